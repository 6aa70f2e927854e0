#include "cairn/sources/frame.hpp"

namespace cairn::sources {

Eigen::Matrix3d RotationFluFromOptical() {
  Eigen::Matrix3d R;
  R << 0.0, 0.0, 1.0,  // x forward = z forward
      -1.0, 0.0, 0.0,  // y left = -x right
      0.0, -1.0, 0.0;  // z up = -y down
  return R;
}

const char* Frame::kind() const {
  if (depth() != nullptr) return "depth";
  if (points() != nullptr) return "points";
  return "stereo";
}

Eigen::Matrix3d RotationFromImu(const ImuAttitude& imu) {
  using Eigen::AngleAxisd;
  using Eigen::Vector3d;
  return (AngleAxisd(imu.yaw_rad.value_or(0.0), Vector3d::UnitZ()) *
          AngleAxisd(imu.pitch_rad, Vector3d::UnitY()) *
          AngleAxisd(imu.roll_rad, Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Vector3d UpInSensor(const Frame& frame) {
  Eigen::Vector3d up_body = Eigen::Vector3d::UnitZ();
  // up_body = R_body_world * up_world; yaw turns about up and leaves it alone.
  if (frame.imu) up_body = RotationFromImu(*frame.imu).transpose() * Eigen::Vector3d::UnitZ();
  return (frame.T_body_sensor.linear().transpose() * up_body).normalized();
}

}  // namespace cairn::sources
