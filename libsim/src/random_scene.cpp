#include "cairn/sim/random_scene.hpp"

#include <cmath>

#include "cairn/od/units.hpp"

namespace cairn::sim {
namespace {

Terrain RandomTerrain(Random& rng, const RandomSceneOptions& options) {
  const double base = rng.Uniform(-1.0, 1.0);
  switch (rng.UniformInt(0, 3)) {
    case 0:
      return Terrain::Flat(base);
    case 1: {
      const double slope = rng.Uniform(0.0, options.max_terrain_slope_rad);
      return Terrain::Slope(base, slope, rng.Uniform(-kPi, kPi));
    }
    case 2: {
      std::vector<SineWave> waves(rng.UniformInt(1, 3));
      for (SineWave& w : waves) {
        w.amplitude_m = rng.Uniform(0.05, 0.6);
        w.wavelength_m = rng.Uniform(3.0, 20.0);
        w.direction_rad = rng.Uniform(-kPi, kPi);
        w.phase_rad = rng.Uniform(-kPi, kPi);
      }
      return Terrain::Hills(base, std::move(waves));
    }
    default: {
      HeightGrid grid;
      grid.cols = grid.rows = 24;
      grid.resolution_m = rng.Uniform(1.0, 3.0);
      grid.origin = Eigen::Vector2d::Constant(-0.5 * (grid.cols - 1) * grid.resolution_m);
      const double roughness = rng.Uniform(0.0, 0.8);
      grid.heights.resize(grid.cols * grid.rows);
      for (double& h : grid.heights) h = base + rng.Uniform(-roughness, roughness);
      return std::move(*Terrain::FromGrid(std::move(grid)));
    }
  }
}

Shape RandomShape(Random& rng, Scene& scene, double x, double y, bool& is_obstacle) {
  const Terrain& terrain = scene.terrain();
  const double ground = terrain.Height(x, y);
  switch (rng.UniformInt(0, 3)) {
    case 0: {
      const double radius = rng.Uniform(0.03, 0.3), height = rng.Uniform(0.1, 2.5);
      is_obstacle = height >= 0.3;
      const double base = terrain.MinHeightOver({x, y}, radius);
      return Cylinder{{x, y, base}, radius, ground + height - base};
    }
    case 1: {
      Eigen::Vector3d radii;  // one draw per statement: argument order is unspecified
      for (int k = 0; k < 3; ++k) radii[k] = rng.Uniform(0.1, 0.8);
      const double height = rng.Uniform(0.3, 2.0) * radii.z();
      is_obstacle = height >= 0.3;
      return Ellipsoid{{x, y, ground + height - radii.z()}, radii, rng.Uniform(-kPi, kPi)};
    }
    case 2: {
      Eigen::Vector3d size;
      size.x() = rng.Uniform(0.2, 2.0);
      size.y() = rng.Uniform(0.2, 2.0);
      size.z() = rng.Uniform(0.1, 1.5);
      is_obstacle = size.z() >= 0.3;
      const double base = terrain.MinHeightOver({x, y}, 0.5 * size.head<2>().norm());
      const double height = ground + size.z() - base;
      return Box{{x, y, base + 0.5 * height}, {size.x(), size.y(), height}, rng.Uniform(-kPi, kPi)};
    }
    default: {
      Ridge ridge;
      ridge.yaw_rad = rng.Uniform(-kPi, kPi);
      ridge.top_length_m = rng.Uniform(0.5, 6.0);
      ridge.top_width_m = rng.Uniform(0.1, 1.0);
      ridge.height_m = rng.Uniform(0.2, 1.2);
      ridge.left_slope_rad = rng.Uniform(15.0, 90.0) * kDegToRad;
      ridge.right_slope_rad = rng.Uniform(15.0, 90.0) * kDegToRad;
      ridge.end_slope_rad = rng.Uniform(15.0, 90.0) * kDegToRad;
      is_obstacle = ridge.height_m >= 0.3;
      const double base = terrain.MinHeightOver({x, y}, Bound(ridge).radius_m);
      ridge.height_m += ground - base;
      ridge.base_centre = {x, y, base};
      return ridge;
    }
  }
}

}  // namespace

double Random::Uniform(double lo, double hi) {
  // 53 random bits -> [0, 1), the same on every platform.
  const double unit = static_cast<double>(engine_() >> 11) * (1.0 / 9007199254740992.0);
  return lo + (hi - lo) * unit;
}

int Random::UniformInt(int lo, int hi) {
  const auto span = static_cast<std::uint64_t>(static_cast<std::int64_t>(hi) - lo + 1);
  return lo + static_cast<int>(engine_() % span);
}

RandomView MakeRandomView(std::uint64_t seed, const RandomSceneOptions& options) {
  Random rng(seed);
  Scene scene(RandomTerrain(rng, options));
  const double fov = rng.Uniform(options.min_fov_rad, options.max_fov_rad);
  const od::PinholeModel model = PinholeFromFov(options.width, options.height, fov);
  const double heading = rng.Uniform(-kPi, kPi);
  const double height = rng.Uniform(options.min_camera_height_m, options.max_camera_height_m);
  const double pitch = rng.Uniform(-0.1, options.max_pitch_rad);
  const double roll = rng.Uniform(-options.max_roll_rad, options.max_roll_rad);
  const Camera camera =
      Camera::AboveGround(model, scene.terrain(), 0.0, 0.0, height, heading, pitch, roll);

  const int count = rng.UniformInt(options.min_objects, options.max_objects);
  for (int k = 0; k < count; ++k) {
    const double distance = rng.Uniform(options.min_distance_m, options.max_distance_m);
    const double bearing = heading + rng.Uniform(-0.45, 0.45) * fov;
    const double x = distance * std::cos(bearing), y = distance * std::sin(bearing);
    bool is_obstacle = true;
    const Shape shape = RandomShape(rng, scene, x, y, is_obstacle);
    // The camera must stay outside every solid.
    const BoundingSphere b = Bound(shape);
    if ((b.centre - camera.Position()).norm() <= b.radius_m) continue;
    scene.Add(shape, is_obstacle, "random");
  }
  return RandomView{std::move(scene), camera};
}

}  // namespace cairn::sim
