// Spinning multi-ring LiDAR: presets, ray directions, one revolution by exact ray casting.
#include <cmath>
#include <string>
#include <vector>

#include "cairn/od/parallel.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/world.hpp"
#include "sampling.hpp"

namespace cairn::sim {
namespace {}  // namespace

Expected<LidarSpec> LidarSpec::Preset(const std::string& name) {
  // Ring elevations come from the detector's sensor model, so that rendered scans and the
  // range images made from them agree ring for ring.
  LidarSpec spec;
  spec.preset = name;
  if (name == "HDL-64E") {
    spec.azimuth_steps = 2048;
    spec.range_sigma_m = 0.02;
    spec.max_range_m = 120.0;
  } else if (name == "VLP-16") {
    spec.azimuth_steps = 1024;
    spec.range_sigma_m = 0.03;
    spec.max_range_m = 100.0;
  } else {
    return Error{"unknown LiDAR preset '" + name + "' (expected HDL-64E or VLP-16)"};
  }
  Expected<od::SphericalModel> model = od::SphericalModel::Preset(name, spec.azimuth_steps);
  if (!model) return model.error();
  spec.elevations_rad = model->ring_elevation_rad;
  return spec;
}

Status LidarSpec::Validate() const {
  if (elevations_rad.empty()) return Error{"elevations: needs at least one ring"};
  for (std::size_t r = 0; r < elevations_rad.size(); ++r) {
    const double e = elevations_rad[r];
    const std::string field = "elevations[" + std::to_string(r) + "]";
    if (!(std::isfinite(e) && std::abs(e) < 0.5 * kPi)) {
      return Error{field + ": must be finite and in (-90, 90) deg"};
    }
    if (r > 0 && !(e < elevations_rad[r - 1])) {
      return Error{field + ": must be below the ring before it (ring 0 is the top beam)"};
    }
  }
  if (azimuth_steps < 1 || azimuth_steps > 65536) {
    return Error{"azimuth_steps: must be in 1..65536"};
  }
  if (!(std::isfinite(range_sigma_m) && range_sigma_m >= 0.0)) {
    return Error{"range_sigma: must be a finite number >= 0"};
  }
  if (!(std::isfinite(max_range_m) && max_range_m > 0.0)) {
    return Error{"max_range: must be a finite number > 0"};
  }
  return Status::Ok();
}

double LidarSpec::AzimuthRad(int column) const {
  return kPi * (1.0 - 2.0 * column / static_cast<double>(azimuth_steps));
}

Eigen::Vector3d LidarSpec::RayDirection(int ring, int column) const {
  const double e = elevations_rad[ring], a = AzimuthRad(column);
  return {std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
}

Expected<LidarScan> RenderLidar(const Scene& scene, const LidarSpec& lidar,
                                const Eigen::Isometry3d& T_world_lidar, std::uint64_t seed) {
  if (Status s = lidar.Validate(); !s.ok()) return Error{"lidar: " + s.message()};
  if (Status s = scene.Validate(); !s.ok()) return Error{"scene: " + s.message()};
  if (!T_world_lidar.matrix().allFinite()) return Error{"lidar: pose is not finite"};

  const int rings = lidar.rings(), steps = lidar.azimuth_steps;
  std::vector<double> cos_a(steps), sin_a(steps);
  for (int c = 0; c < steps; ++c) {
    cos_a[c] = std::cos(lidar.AzimuthRad(c));
    sin_a[c] = std::sin(lidar.AzimuthRad(c));
  }
  const RayCaster caster(scene);
  RenderOptions options;
  options.max_range_m = lidar.max_range_m;
  const Eigen::Matrix3d& R = T_world_lidar.linear();
  // Exact ranges first, in parallel (one row per ring); then the noise, in ray order.
  std::vector<double> range(static_cast<std::size_t>(rings) * steps, 0.0);
  std::vector<std::int32_t> id(range.size(), kNoHitId);
  od::ParallelFor(rings, 0, [&](int r) {
    const double ce = std::cos(lidar.elevations_rad[r]), se = std::sin(lidar.elevations_rad[r]);
    Ray ray;
    ray.origin = T_world_lidar.translation();
    for (int c = 0; c < steps; ++c) {
      ray.direction = R * Eigen::Vector3d(ce * cos_a[c], ce * sin_a[c], se);
      if (const auto hit = caster.Cast(ray, options)) {
        range[static_cast<std::size_t>(r) * steps + c] = hit->t;
        id[static_cast<std::size_t>(r) * steps + c] = hit->id;
      }
    }
  });

  LidarScan scan;
  Random rng(seed);
  for (int r = 0; r < rings; ++r) {
    const double ce = std::cos(lidar.elevations_rad[r]), se = std::sin(lidar.elevations_rad[r]);
    for (int c = 0; c < steps; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * steps + c;
      if (id[i] == kNoHitId) continue;
      double measured = range[i];
      if (lidar.range_sigma_m > 0.0) {
        measured += lidar.range_sigma_m * detail::StandardNormal(rng);
      }
      if (!(measured > 0.0)) continue;
      const Eigen::Vector3d d(ce * cos_a[c], ce * sin_a[c], se);
      scan.points.push_back((measured * d).cast<float>());
      scan.ring.push_back(r);
      scan.column.push_back(c);
      scan.object_id.push_back(id[i]);
    }
  }
  return scan;
}

}  // namespace cairn::sim
