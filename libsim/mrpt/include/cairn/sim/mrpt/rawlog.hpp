// The observations a synthetic drive is made of, as MRPT objects for a rawlog in the
// observations format (written with cairn::sources::RawlogWriter, read back with
// cairn::sources::RawlogSource, which decodes them into frames).
//
// What cairn writes, per frame, all with the frame's timestamp:
//   "ODOMETRY"  CObservationOdometry: odometry = T_odom_body as (x, y, yaw) [m, rad],
//               velocityLocal = (vx, vy, omega) of the body [m/s, rad/s].
//   "IMU"       CObservationIMU: IMU_YAW, IMU_PITCH, IMU_ROLL present [rad], MRPT's Z-Y-X
//               convention (as CPose3D: pitch > 0 nose down, roll > 0 left side up).
//               With raw samples (SequenceOptions::raw_imu), more "IMU" observations at the
//               IMU rate carry IMU_X_ACC, IMU_Y_ACC, IMU_Z_ACC (specific force, gravity
//               included: +9.8 m/s^2 up at rest) [m/s^2] and IMU_WX, IMU_WY, IMU_WZ [rad/s]
//               in the IMU frame, whose pose on the body is sensorPose (rotation only).
//   "CAMERA"    CObservation3DRangeScan: rangeImage = z-depth in units of rangeUnits [m]
//               (range_is_depth = true), 0 = no return; cameraParams (= cameraParamsIntensity)
//               the pinhole, no distortion; maxRange; no point cloud, no intensity image.
//               sensorPose = T_body_sensor of MRPT's range-camera frame: x forward (along the
//               optical axis), y left, z up, i.e. the optical frame (x right, y down, z
//               forward) turned by RotationOpticalFromFlu (drive.hpp). MRPT unprojects pixel
//               (r, c) of depth d to x = d, y = (cx - c) d / fx, z = (cy - r) d / fy.
//   "LIDAR"     CObservationPointCloud with a CSimplePointsMap: the returns in the LiDAR frame
//               (x forward, y left, z up) [m]; sensorPose = T_body_lidar.
// Timestamps are mrpt::Clock time points (100 ns ticks); cairn's are Unix seconds.
#pragma once

#include <mrpt/core/Clock.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>

#include <Eigen/Geometry>

#include "cairn/od/expected.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {

inline constexpr const char* kCameraLabel = "CAMERA";
inline constexpr const char* kLidarLabel = "LIDAR";
inline constexpr const char* kOdometryLabel = "ODOMETRY";
inline constexpr const char* kImuLabel = "IMU";

// The observations of a synthetic drive (see the top of this file for their conventions).

/// `frame` as a range scan; `T_body_camera` places the optical frame on the body. Depths
/// are quantised to `range_units_m` (rounded); a depth beyond 65535 units is an error.
Expected<::mrpt::obs::CObservation3DRangeScan::Ptr> MakeRangeScan(
    const DepthFrame& frame, const Eigen::Isometry3d& T_body_camera, double range_units_m,
    double max_range_m, ::mrpt::Clock::time_point stamp);
::mrpt::obs::CObservationPointCloud::Ptr MakePointCloud(const LidarScan& scan,
                                                        const Eigen::Isometry3d& T_body_lidar,
                                                        ::mrpt::Clock::time_point stamp);
/// `velocity_local` = (vx, vy, omega) in the body frame [m/s, rad/s].
::mrpt::obs::CObservationOdometry::Ptr MakeOdometry(const Pose2D& odometry,
                                                    const Eigen::Vector3d& velocity_local,
                                                    ::mrpt::Clock::time_point stamp);
::mrpt::obs::CObservationIMU::Ptr MakeImu(const Attitude& attitude,
                                          ::mrpt::Clock::time_point stamp);
/// One raw sample (accelerometer and gyro, IMU frame); `R_body_imu` becomes sensorPose.
::mrpt::obs::CObservationIMU::Ptr MakeRawImu(const ImuReading& reading,
                                             const Eigen::Matrix3d& R_body_imu,
                                             ::mrpt::Clock::time_point stamp);

}  // namespace cairn::sim
