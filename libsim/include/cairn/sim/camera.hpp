// Camera: a pinhole model and its pose in the world.
//
// T_world_camera maps optical-frame points (x right, y down, z forward) into the world
// (z up). Attitude follows od::CameraUpFromPitchRoll: heading turns the optical axis about
// the world vertical (0 = world +x, counter-clockwise), pitch > 0 points it below the
// horizontal, roll > 0 dips the camera's x axis below the horizontal; so UpOptical() equals
// od::CameraUpFromPitchRoll(pitch, roll) whatever the heading.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/geometry.hpp"
#include "cairn/sim/terrain.hpp"

namespace cairn::sim {

struct Camera {
  od::PinholeModel model;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();

  /// Camera at `position` (world) with the given attitude [rad].
  static Camera FromAttitude(const od::PinholeModel& model, const Eigen::Vector3d& position,
                             double heading_rad, double pitch_rad, double roll_rad);
  /// Camera `height_m` above the terrain at (x, y).
  static Camera AboveGround(const od::PinholeModel& model, const Terrain& terrain, double x,
                            double y, double height_m, double heading_rad, double pitch_rad,
                            double roll_rad);

  /// Gravity's up vector in the optical frame (unit).
  Eigen::Vector3d UpOptical() const;
  Eigen::Vector3d Position() const { return T_world_camera.translation(); }

  /// World ray through pixel (col, row); integer coordinates are pixel centres.
  Ray PixelRay(double col, double row) const;
  /// World point seen at pixel (col, row) with z-depth `z_m`.
  Eigen::Vector3d UnprojectWorld(double col, double row, double z_m) const;
  /// Continuous pixel coordinates (col, row) of a world point, or nothing when it is not in
  /// front of the camera (z <= 0 in the optical frame). No image bounds check.
  std::optional<Eigen::Vector2d> ProjectWorld(const Eigen::Vector3d& p_world) const;
};

/// A pinhole model with square pixels and the principal point at the image centre
/// ((width - 1) / 2, (height - 1) / 2), from the horizontal field of view [rad].
od::PinholeModel PinholeFromFov(int width, int height, double horizontal_fov_rad);

}  // namespace cairn::sim
