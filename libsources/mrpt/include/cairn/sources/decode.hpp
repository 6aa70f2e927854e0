// MRPT observations decoded into cairn frames (frame.hpp), one function per class, and the
// odometry and IMU observations that give a frame its context.
//
// What each class becomes, and the conventions it follows:
//
//   CObservation3DRangeScan -> DepthImage. rangeImage * rangeUnits is z-depth when
//     range_is_depth, else the distance along the pixel's ray (converted to z-depth through
//     the undistorted ray). cameraParams is the pinhole; lens distortion, when present, is
//     removed by resampling the image (nearest pixel, so no depth is ever interpolated across
//     an edge) onto the undistorted pinhole with the same fx, fy, cx, cy. sensorPose is the
//     pose of MRPT's range-camera frame (x forward along the optical axis, y left, z up),
//     which MRPT unprojects as x = d, y = (cx - c) d / fx, z = (cy - r) d / fy; T_body_sensor
//     is the optical frame's, sensorPose * RotationFluFromOptical(). Externally stored range
//     and intensity images are loaded first.
//   CObservationVelodyneScan -> PointScan. Points from MRPT's generatePointCloud on the raw
//     packets, with the calibration stored in the observation, else MRPT's default for the
//     model byte of the packets (0x22 VLP-16, 0x21 HDL-32E); each point keeps its laser id.
//     Rows: the lasers ordered by their calibrated elevation, top first. Columns: one per
//     firing, as many per turn as the mean firing step over the sweep gives (measured from
//     the packets). Returns nearer than DecodeOptions::velodyne_min_range_m are dropped
//     (MRPT's default, the vehicle itself).
//   CObservationRotatingScan -> PointScan. Rows are lasers (MRPT fills row = laser id from
//     Velodyne packets); elevations from MRPT's default calibration of lidarModel ("VLP-16",
//     "HDL-32E") when its laser count matches, else the scan cannot be placed and is an
//     error. Column c looks at azimuth startAzimuth + azimuthSpan * c / n, n the columns the
//     sweep covers (see decode.cpp for MRPT 2.5's Velodyne conversion, which sizes the matrix
//     16x too wide and fills every other column); azimuths grow clockwise for Velodyne-made
//     scans, as the packets count them.
//   CObservationPointCloud -> PointScan. Any CPointsMap, points in input order (intensity
//     from a CPointsMapXYZI). Rows and columns found from the data by
//     od::FindLayout (point_cloud.hpp), as for point files: organised or ring-after-ring
//     storage, elevation clusters, else even elevation bins.
//   CObservationStereoImages -> StereoPair. Grey left and right images; when the left
//     camera has distortion (MRPT's mark of raw images) the pair is rectified with MRPT's
//     CStereoRectifyMap (alpha 0: only valid pixels) and the rectified poses are used.
//     cameraPose is the left camera's optical frame (x right, y down, z forward) on the body;
//     the baseline is the norm of rightCameraPose's translation.
//
// Every error begins "<class> '<label>'" and says what is wrong; callers add file and entry.
#pragma once

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationStereoImages.h>
#include <mrpt/obs/CObservationVelodyneScan.h>

#include <optional>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/sources/frame.hpp"

namespace cairn::sources {

struct DecodeOptions {
  /// Velodyne returns nearer than this are dropped [m] (MRPT's generatePointCloud default).
  double velodyne_min_range_m = 1.0;
  /// How rows and columns are found in point clouds that carry no laser ids.
  od::LayoutOptions layout;
};

/// True for the classes that decode into frames (the five above).
bool IsRangeObservation(const ::mrpt::obs::CObservation& observation);

/// Why a range observation holds no range data (a 3-D scan without a range image, stereo
/// without a right image, an empty cloud), or nullopt when it holds some. Such observations
/// are skipped, not errors.
std::optional<std::string> WhyNoRangeData(const ::mrpt::obs::CObservation& observation);

Expected<Frame> DecodeRangeScan(const ::mrpt::obs::CObservation3DRangeScan& scan);
Expected<Frame> DecodeVelodyneScan(const ::mrpt::obs::CObservationVelodyneScan& scan,
                                   const DecodeOptions& options = {});
Expected<Frame> DecodeRotatingScan(const ::mrpt::obs::CObservationRotatingScan& scan);
Expected<Frame> DecodePointCloud(const ::mrpt::obs::CObservationPointCloud& cloud,
                                 const DecodeOptions& options = {});
Expected<Frame> DecodeStereoImages(const ::mrpt::obs::CObservationStereoImages& stereo);

/// Any of the five; an error for other classes.
Expected<Frame> DecodeRangeObservation(const ::mrpt::obs::CObservation& observation,
                                       const DecodeOptions& options = {});

/// The odometry pose (x, y, yaw as a planar T_odom_body) at the observation's stamp.
OdometrySample DecodeOdometry(const ::mrpt::obs::CObservationOdometry& odometry);

/// Roll and pitch (and yaw) from IMU_ROLL/IMU_PITCH/IMU_YAW, else from the orientation
/// quaternion IMU_ORI_QUAT_*; nullopt when the IMU gives neither (rates only).
std::optional<ImuAttitude> DecodeImu(const ::mrpt::obs::CObservationIMU& imu);

/// The raw accelerometer (IMU_X_ACC, IMU_Y_ACC, IMU_Z_ACC, all three present and finite) and
/// gyro (IMU_WX, IMU_WY, IMU_WZ) readings; nullopt when it has neither (attitude only).
std::optional<ImuSample> DecodeImuSample(const ::mrpt::obs::CObservationIMU& imu);

/// The elevations [rad] of a Velodyne calibration's lasers, indexed by laser id.
std::vector<double> LaserElevations(const ::mrpt::obs::VelodyneCalibration& calibration);

}  // namespace cairn::sources
