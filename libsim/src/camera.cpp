#include "cairn/sim/camera.hpp"

#include <cmath>

namespace cairn::sim {

Camera Camera::FromAttitude(const od::PinholeModel& model, const Eigen::Vector3d& position,
                            double heading_rad, double pitch_rad, double roll_rad) {
  // Optical axes of a level camera, in the world: x right, y down, z along the heading.
  const double ch = std::cos(heading_rad), sh = std::sin(heading_rad);
  Eigen::Matrix3d world_from_level;
  world_from_level.col(0) << sh, -ch, 0.0;
  world_from_level.col(1) << 0.0, 0.0, -1.0;
  world_from_level.col(2) << ch, sh, 0.0;
  // Pitch about x (z goes down for pitch > 0), then roll about the new z (x goes down for
  // roll > 0); columns are the camera axes in the level optical frame.
  const double cp = std::cos(pitch_rad), sp = std::sin(pitch_rad);
  const double cr = std::cos(roll_rad), sr = std::sin(roll_rad);
  Eigen::Matrix3d level_from_camera;
  level_from_camera.col(0) << cr, sr * cp, -sr * sp;
  level_from_camera.col(1) << -sr, cr * cp, -cr * sp;
  level_from_camera.col(2) << 0.0, sp, cp;

  Camera camera;
  camera.model = model;
  camera.T_world_camera.linear() = world_from_level * level_from_camera;
  camera.T_world_camera.translation() = position;
  return camera;
}

Camera Camera::AboveGround(const od::PinholeModel& model, const Terrain& terrain, double x,
                           double y, double height_m, double heading_rad, double pitch_rad,
                           double roll_rad) {
  return FromAttitude(model, Eigen::Vector3d(x, y, terrain.Height(x, y) + height_m), heading_rad,
                      pitch_rad, roll_rad);
}

Eigen::Vector3d Camera::UpOptical() const {
  return T_world_camera.linear().transpose() * Eigen::Vector3d::UnitZ();
}

Ray Camera::PixelRay(double col, double row) const {
  const Eigen::Vector3d d((col - model.cx) / model.fx, (row - model.cy) / model.fy, 1.0);
  return Ray{T_world_camera.translation(), (T_world_camera.linear() * d).normalized()};
}

Eigen::Vector3d Camera::UnprojectWorld(double col, double row, double z_m) const {
  return T_world_camera * model.Unproject(col, row, z_m);
}

std::optional<Eigen::Vector2d> Camera::ProjectWorld(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d p = T_world_camera.inverse() * p_world;
  if (!(p.z() > 0.0)) return std::nullopt;
  return model.Project(p);
}

od::PinholeModel PinholeFromFov(int width, int height, double horizontal_fov_rad) {
  od::PinholeModel m;
  m.width = width;
  m.height = height;
  m.fx = m.fy = 0.5 * width / std::tan(0.5 * horizontal_fov_rad);
  m.cx = 0.5 * (width - 1);
  m.cy = 0.5 * (height - 1);
  return m;
}

}  // namespace cairn::sim
