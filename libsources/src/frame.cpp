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

Expected<FrameImage> ToRangeImage(const Frame& frame, const Eigen::Vector3d& up_sensor,
                                  const od::StereoConfig& stereo) {
  FrameImage out;
  Expected<od::RangeImage> image = Error{"no range data"};
  if (const DepthImage* depth = frame.depth()) {
    image = od::RangeImage::FromDepth(depth->depth_m, depth->model, up_sensor);
  } else if (const PointScan* scan = frame.points()) {
    image =
        od::RangeImage::FromPoints(scan->points, scan->model, up_sensor, scan->rows, scan->cols);
  } else if (const StereoPair* pair = frame.stereo()) {
    od::StereoPair rectified;
    rectified.left = pair->left;
    rectified.right = pair->right;
    rectified.calibration.model = pair->left_model;
    rectified.calibration.baseline_m = pair->baseline_m;
    Expected<od::StereoDepth> matched = od::ComputeStereoDepth(rectified, stereo);
    if (!matched) return Error{"stereo: " + matched.error().message};
    image = od::RangeImage::FromDepth(matched->depth_m.data, pair->left_model, up_sensor);
    out.stereo = std::move(*matched);
  }
  if (!image) return image.error();
  out.image = std::move(*image);
  return out;
}

}  // namespace cairn::sources
