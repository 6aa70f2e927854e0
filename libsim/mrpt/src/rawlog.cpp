#include "cairn/sim/mrpt/rawlog.hpp"

#include <mrpt/maps/CSimplePointsMap.h>

#include <cmath>
#include <string>

#include "cairn/sources/mrpt_convert.hpp"

namespace cairn::sim {

// ---------------------------------------------------------------------------------------
// Observations

Expected<::mrpt::obs::CObservation3DRangeScan::Ptr> MakeRangeScan(
    const DepthFrame& frame, const Eigen::Isometry3d& T_body_camera, double range_units_m,
    double max_range_m, ::mrpt::Clock::time_point stamp) {
  if (!(range_units_m > 0.0)) {
    return Error{"range scan: range units must be > 0, got " + std::to_string(range_units_m)};
  }
  auto scan = std::make_shared<::mrpt::obs::CObservation3DRangeScan>();
  scan->sensorLabel = kCameraLabel;
  scan->timestamp = stamp;
  scan->hasRangeImage = true;
  scan->range_is_depth = true;
  scan->rangeUnits = static_cast<float>(range_units_m);
  scan->rangeImage_setSize(frame.height(), frame.width());
  for (int r = 0; r < frame.height(); ++r) {
    for (int c = 0; c < frame.width(); ++c) {
      const float d = frame.depth_m[static_cast<std::size_t>(r) * frame.width() + c];
      long units = 0;
      if (std::isfinite(d) && d > 0.0f) units = std::lround(d / range_units_m);
      if (units > 65535) {
        return Error{"range scan: depth " + std::to_string(d) + " m at row " + std::to_string(r) +
                     ", col " + std::to_string(c) + " exceeds 65535 x " +
                     std::to_string(range_units_m) + " m"};
      }
      scan->rangeImage(r, c) = static_cast<std::uint16_t>(units);
    }
  }
  ::mrpt::img::TCamera camera;
  camera.ncols = static_cast<std::uint32_t>(frame.model.width);
  camera.nrows = static_cast<std::uint32_t>(frame.model.height);
  camera.setIntrinsicParamsFromValues(frame.model.fx, frame.model.fy, frame.model.cx,
                                      frame.model.cy);
  camera.cameraName = kCameraLabel;
  scan->cameraParams = camera;
  scan->cameraParamsIntensity = camera;
  scan->maxRange = static_cast<float>(max_range_m);
  scan->stdError = static_cast<float>(range_units_m);
  Eigen::Isometry3d T_body_flu = T_body_camera;
  T_body_flu.linear() = T_body_camera.linear() * RotationOpticalFromFlu();
  scan->sensorPose = sources::ToCPose3D(T_body_flu);
  return scan;
}

::mrpt::obs::CObservationPointCloud::Ptr MakePointCloud(const LidarScan& scan,
                                                        const Eigen::Isometry3d& T_body_lidar,
                                                        ::mrpt::Clock::time_point stamp) {
  auto cloud = std::make_shared<::mrpt::obs::CObservationPointCloud>();
  cloud->sensorLabel = kLidarLabel;
  cloud->timestamp = stamp;
  auto points = ::mrpt::maps::CSimplePointsMap::Create();
  points->reserve(scan.points.size());
  for (const Eigen::Vector3f& p : scan.points) points->insertPointFast(p.x(), p.y(), p.z());
  cloud->pointcloud = points;
  cloud->sensorPose = sources::ToCPose3D(T_body_lidar);
  return cloud;
}

::mrpt::obs::CObservationOdometry::Ptr MakeOdometry(const Pose2D& odometry,
                                                    const Eigen::Vector3d& velocity_local,
                                                    ::mrpt::Clock::time_point stamp) {
  auto obs = std::make_shared<::mrpt::obs::CObservationOdometry>();
  obs->sensorLabel = kOdometryLabel;
  obs->timestamp = stamp;
  obs->odometry = ::mrpt::poses::CPose2D(odometry.x_m, odometry.y_m, odometry.yaw_rad);
  obs->hasVelocities = true;
  obs->velocityLocal =
      ::mrpt::math::TTwist2D(velocity_local.x(), velocity_local.y(), velocity_local.z());
  return obs;
}

::mrpt::obs::CObservationIMU::Ptr MakeImu(const Attitude& attitude,
                                          ::mrpt::Clock::time_point stamp) {
  auto obs = std::make_shared<::mrpt::obs::CObservationIMU>();
  obs->sensorLabel = kImuLabel;
  obs->timestamp = stamp;
  obs->set(::mrpt::obs::IMU_YAW, attitude.yaw_rad);
  obs->set(::mrpt::obs::IMU_PITCH, attitude.pitch_rad);
  obs->set(::mrpt::obs::IMU_ROLL, attitude.roll_rad);
  return obs;
}

::mrpt::obs::CObservationIMU::Ptr MakeRawImu(const ImuReading& reading,
                                             const Eigen::Matrix3d& R_body_imu,
                                             ::mrpt::Clock::time_point stamp) {
  using namespace ::mrpt::obs;
  auto obs = std::make_shared<CObservationIMU>();
  obs->sensorLabel = kImuLabel;
  obs->timestamp = stamp;
  obs->set(IMU_X_ACC, reading.specific_force_mps2.x());
  obs->set(IMU_Y_ACC, reading.specific_force_mps2.y());
  obs->set(IMU_Z_ACC, reading.specific_force_mps2.z());
  obs->set(IMU_WX, reading.angular_rate_radps.x());
  obs->set(IMU_WY, reading.angular_rate_radps.y());
  obs->set(IMU_WZ, reading.angular_rate_radps.z());
  Eigen::Isometry3d T_body_imu = Eigen::Isometry3d::Identity();
  T_body_imu.linear() = R_body_imu;
  obs->sensorPose = sources::ToCPose3D(T_body_imu);
  return obs;
}

}  // namespace cairn::sim
