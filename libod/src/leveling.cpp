#include "cairn/od/leveling.hpp"

#include <cmath>

namespace cairn::od {

Eigen::Vector3d CameraUpFromPitchRoll(double pitch_rad, double roll_rad) {
  const double cp = std::cos(pitch_rad);
  return {-cp * std::sin(roll_rad), -cp * std::cos(roll_rad), -std::sin(pitch_rad)};
}

Expected<Eigen::Matrix3d> LevelRotation(const Eigen::Vector3d& up_sensor,
                                        const Eigen::Vector3d& forward_sensor) {
  const double n = up_sensor.norm();
  if (!std::isfinite(n) || n < 1e-9) {
    return Error{"up vector must be finite and non-zero"};
  }
  const Eigen::Vector3d z = up_sensor / n;
  // Heading: forward projected on the horizontal plane; the sensor's x axis when forward is
  // (nearly) vertical, then its y axis, so that a basis always exists.
  Eigen::Vector3d x = forward_sensor - forward_sensor.dot(z) * z;
  const Eigen::Vector3d fallbacks[] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()};
  for (const Eigen::Vector3d& fallback : fallbacks) {
    if (x.norm() > 1e-6) break;
    x = fallback - fallback.dot(z) * z;
  }
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R_level_sensor;
  R_level_sensor.row(0) = x.transpose();
  R_level_sensor.row(1) = y.transpose();
  R_level_sensor.row(2) = z.transpose();
  return R_level_sensor;
}

}  // namespace cairn::od
