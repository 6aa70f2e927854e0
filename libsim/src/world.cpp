// World: validation of the sensor and drive specs, view cameras, rendering of views.
// The file reader is world_file.cpp, the noise noise.cpp, the LiDAR lidar.cpp.
#include "cairn/sim/world.hpp"

#include <cassert>
#include <cmath>
#include <string>

#include "sampling.hpp"

namespace cairn::sim {
namespace {

Status WorldError(const std::string& field, const std::string& what) {
  return Error{field + ": " + what};
}

bool Finite(double v) { return std::isfinite(v); }

}  // namespace

Status StereoNoise::Validate() const {
  if (!(Finite(depth_sigma_per_m2) && depth_sigma_per_m2 >= 0.0)) {
    return WorldError("depth_sigma_per_m2", "must be a finite number >= 0");
  }
  if (!(Finite(dropout_probability) && dropout_probability >= 0.0 && dropout_probability < 1.0)) {
    return WorldError("dropout_probability", "must be in [0, 1)");
  }
  if (edge_smear_px < 0 || edge_smear_px > 32) {
    return WorldError("edge_smear_px", "must be in 0..32");
  }
  if (!(Finite(edge_jump_m) && edge_jump_m > 0.0)) {
    return WorldError("edge_jump", "must be a finite number > 0");
  }
  return Status::Ok();
}

Status RangeCameraSpec::Validate() const {
  if (Status s = model.Validate(); !s.ok()) return s;
  if (Status s = noise.Validate(); !s.ok()) return Error{"noise." + s.message()};
  if (!(Finite(max_range_m) && max_range_m > 0.0)) {
    return WorldError("max_range", "must be a finite number > 0");
  }
  return Status::Ok();
}

RangeCameraSpec RangeCameraSpec::Default() {
  RangeCameraSpec spec;
  spec.model.width = 320;
  spec.model.height = 240;
  spec.model.fx = spec.model.fy = 260.0;
  spec.model.cx = 0.5 * (spec.model.width - 1);
  spec.model.cy = 0.5 * (spec.model.height - 1);
  return spec;
}

RangeCameraSpec RangeCameraSpec::Scaled(int width) const {
  RangeCameraSpec out = *this;
  const double scale = static_cast<double>(width) / model.width;
  out.model.width = width;
  out.model.height = static_cast<int>(std::lround(model.height * scale));
  out.model.fx *= scale;
  out.model.fy *= scale;
  out.model.cx = (out.model.width - 1) / 2.0;
  out.model.cy = (out.model.height - 1) / 2.0;
  return out;
}

Status DriveSpec::Validate() const {
  if (waypoints.size() < 2) return WorldError("waypoints", "needs at least two points");
  bool moves = false;
  for (std::size_t i = 0; i < waypoints.size(); ++i) {
    if (!waypoints[i].allFinite()) {
      return WorldError("waypoints[" + std::to_string(i) + "]", "must be finite");
    }
    moves = moves || (waypoints[i] - waypoints[0]).norm() > 0.0;
  }
  if (!moves) return WorldError("waypoints", "are all the same point");
  const struct {
    const char* key;
    double value;
  } positive[] = {{"speed", speed_mps},
                  {"frame_rate", frame_rate_hz},
                  {"wheelbase", wheelbase_m},
                  {"track", track_m}};
  for (const auto& p : positive) {
    if (!(Finite(p.value) && p.value > 0.0)) {
      return WorldError(p.key, "must be a finite number > 0");
    }
  }
  const struct {
    const char* key;
    double value;
  } non_negative[] = {{"odom_sigma_per_m", odom_sigma_per_m},
                      {"odom_yaw_sigma_per_m", odom_yaw_sigma_rad_per_m},
                      {"imu_sigma", imu_sigma_rad},
                      {"turn_radius", turn_radius_m}};
  for (const auto& p : non_negative) {
    if (!(Finite(p.value) && p.value >= 0.0)) {
      return WorldError(p.key, "must be a finite number >= 0");
    }
  }
  if (!Finite(imu_bias_rad)) return WorldError("imu_bias", "must be finite");
  if (!(Finite(speed_wave_mps) && speed_wave_mps >= 0.0 && speed_wave_mps < speed_mps)) {
    return WorldError("speed_wave", "must be in [0, speed)");
  }
  if (!(Finite(speed_wave_period_s) && speed_wave_period_s > 0.0)) {
    return WorldError("speed_wave_period", "must be a finite number > 0");
  }
  if (!sensor_misalignment_rad.allFinite()) {
    return WorldError("sensor_misalignment", "must be finite");
  }
  if (!T_body_sensor_xyz.allFinite()) return WorldError("sensor_xyz", "must be finite");
  if (!(Finite(sensor_pitch_rad) && std::abs(sensor_pitch_rad) < 1.5707963267948966)) {
    return WorldError("sensor_pitch", "must be in (-90, 90) deg");
  }
  return Status::Ok();
}

Camera ViewCamera(const World& world, int index) {
  assert(index >= 0 && index < static_cast<int>(world.views.size()));
  const Viewpoint& v = world.views[index];
  const Terrain& terrain = world.scene.terrain();
  if (!v.follow_terrain) {
    return Camera::AboveGround(world.camera.model, terrain, v.x_m, v.y_m, v.height_m, v.heading_rad,
                               v.pitch_rad, v.roll_rad);
  }
  // Body frame on the ground's tangent plane: z along the normal, x the heading projected.
  const Eigen::Vector3d n = terrain.Normal(v.x_m, v.y_m);
  const Eigen::Vector3d heading(std::cos(v.heading_rad), std::sin(v.heading_rad), 0.0);
  const Eigen::Vector3d x_body = (heading - heading.dot(n) * n).normalized();
  Eigen::Matrix3d R_world_body;
  R_world_body.col(0) = x_body;
  R_world_body.col(1) = n.cross(x_body);
  R_world_body.col(2) = n;
  // The camera's attitude on the body is FromAttitude's with the body as the level frame.
  const Camera on_body = Camera::FromAttitude(world.camera.model, Eigen::Vector3d::Zero(), 0.0,
                                              v.pitch_rad, v.roll_rad);
  Camera camera;
  camera.model = world.camera.model;
  camera.T_world_camera.linear() = R_world_body * on_body.T_world_camera.linear();
  camera.T_world_camera.translation() =
      Eigen::Vector3d(v.x_m, v.y_m, terrain.Height(v.x_m, v.y_m) + v.height_m);
  return camera;
}

std::uint64_t ViewNoiseSeed(std::uint64_t world_seed, int index) {
  return detail::Mix(world_seed, 0x76696577ULL + static_cast<std::uint64_t>(index));  // "view"
}

Expected<DepthFrame> RenderRangeCamera(const Scene& scene, const RangeCameraSpec& spec,
                                       const Camera& camera, std::uint64_t seed) {
  if (Status s = spec.Validate(); !s.ok()) return Error{"camera: " + s.message()};
  if (!camera.T_world_camera.matrix().allFinite()) {
    return Error{"camera: pose is not finite"};
  }
  Camera placed = camera;
  placed.model = spec.model;
  RenderOptions options;
  options.max_range_m = spec.max_range_m;
  Expected<DepthFrame> frame = RenderDepth(scene, placed, options);
  if (!frame.ok() || spec.noise.IsZero()) return frame;
  return ApplyStereoNoise(std::move(frame).value(), spec.noise, seed);
}

Expected<DepthFrame> RenderView(const World& world, int index) {
  if (index < 0 || index >= static_cast<int>(world.views.size())) {
    return Error{"world '" + world.name + "': view " + std::to_string(index) +
                 " does not exist (it has " + std::to_string(world.views.size()) + ")"};
  }
  return RenderRangeCamera(world.scene, world.camera, ViewCamera(world, index),
                           ViewNoiseSeed(world.seed, index));
}

}  // namespace cairn::sim
