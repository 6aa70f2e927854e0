// Leveling: gravity's up vector in the sensor frame, and the level frame built from it.
//
// Heights are measured along `up`, never along an image axis. This is the one replaceable
// step that takes the tilt: a prior from config or IMU now, a per-frame refinement from
// Ceres later, all entering as an up vector.
//
// Level frame: sensor-centred, z along `up`, x the sensor's heading (its forward axis,
// +z for a camera) projected on the horizontal plane, y = z cross x.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "cairn/od/expected.hpp"

namespace cairn::od {

/// Up vector in the camera optical frame (x right, y down, z forward) for a camera pitched
/// by `pitch_rad` (optical axis below the horizontal is positive) and then rolled by
/// `roll_rad` about its optical axis (positive when the camera's x axis dips below the
/// horizontal): up = (-cos(pitch) sin(roll), -cos(pitch) cos(roll), -sin(pitch)).
Eigen::Vector3d CameraUpFromPitchRoll(double pitch_rad, double roll_rad);

/// Rotation R_level_sensor for a unit-normalisable `up` and the sensor's forward axis.
/// Fails when `up` is zero or not finite. When forward is parallel to up, the level x axis
/// is taken from the sensor x axis instead.
Expected<Eigen::Matrix3d> LevelRotation(const Eigen::Vector3d& up_sensor,
                                        const Eigen::Vector3d& forward_sensor);

}  // namespace cairn::od
