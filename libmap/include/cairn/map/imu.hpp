// One IMU reading as the Mapper hands it to its tilt step: what a gravity-observing estimator
// needs from the IMU between two frames. Body frame (x forward, y left, z up), SI units.
//
// A reading carries what its device gives: raw specific force and angular rate (an IMU),
// an attitude (an IMU's own filter, or an AHRS), or both; the flags say which.
#pragma once

#include <Eigen/Core>

namespace cairn::map {

struct ImuSample {
  double stamp_s = 0.0;  ///< same clock as the frames' stamps [s]
  /// Accelerometer: specific force f = a - g in the body frame (at rest, level: +9.81 z)
  /// [m/s^2], when has_raw.
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();
  /// Gyro: angular rate of the body in the body frame [rad/s], when has_raw.
  Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();
  bool has_raw = false;
  /// The device's attitude, R_world_body = Rz(yaw) Ry(pitch) Rx(roll) (MRPT's convention:
  /// pitch > 0 nose down, roll > 0 left side up) [rad], when has_attitude.
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  bool has_attitude = false;
};

}  // namespace cairn::map
