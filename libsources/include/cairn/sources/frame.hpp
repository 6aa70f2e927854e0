// Frame: one range observation of a recording, decoded for cairn, with what the recording
// says about where the sensor was. The first stage of the data flow (ARCHITECTURE.md):
//
//   source -> Frame { stamp, range data, sensor model, T_body_sensor, odometry, IMU }
//
// Frames and units:
//   - DepthImage and StereoPair live in the camera's optical frame (x right, y down,
//     z forward); PointScan in the LiDAR frame (x forward, y left, z up). T_body_sensor maps
//     that frame into the body (robot) frame, whatever convention the file used.
//   - The body frame is the robot's: x forward, y left, z up (MRPT's).
//   - The odometry frame is the one the recording's odometry starts in; T_odom_body maps body
//     points into it.
//   - Stamps are Unix seconds; NaN where the file gives none. Metres, radians.
// This header needs no MRPT: libraries downstream (mapping, evaluation) take Frames.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/od/stereo.hpp"

namespace cairn::sources {

inline constexpr double kNoStamp = std::numeric_limits<double>::quiet_NaN();

/// R_flu_optical: maps vectors of the optical frame (x right, y down, z forward) into the
/// x-forward, y-left, z-up frame of the same camera (MRPT's range-camera frame). Its
/// transpose maps the other way.
Eigen::Matrix3d RotationFluFromOptical();

/// A pinhole z-depth image (distance along the optical axis, not along the ray).
struct DepthImage {
  od::PinholeModel model;      ///< undistorted pinhole of depth_m's grid
  std::vector<float> depth_m;  ///< row-major, width * height; 0 = no return [m]
  /// For each pixel of the recording's range image (row-major, same size): the index of the
  /// pixel of depth_m it went to, -1 where it went nowhere. Empty when the two grids are the
  /// same (no lens distortion to remove), so labels go back pixel for pixel.
  std::vector<std::int32_t> decoded_of_source;
};

/// LiDAR returns with their place in a spherical range image.
struct PointScan {
  std::vector<Eigen::Vector3f> points;  ///< LiDAR frame [m], in decode order
  std::vector<float> intensity;         ///< per point in sensor units, or empty
  std::vector<std::int32_t> laser_id;   ///< the sensor's laser number per point, or empty
  /// Rings top beam first (elevations from the sensor's calibration where the file or
  /// MRPT knows it, else found from the points), width = azimuth steps per turn.
  od::SphericalModel model;
  /// Each point's row (ring) and column in `model`, from the data (laser ids, firing
  /// azimuths, organised layouts), or empty for od::RangeImage::FromPoints to compute.
  std::vector<std::int32_t> rows, cols;
  std::string layout;  ///< how rows and columns were found, for reports
};

/// A stereo pair, rectified (by the decoder when the file held raw images).
struct StereoPair {
  od::Grid<std::uint8_t> left, right;      ///< grey, same size
  od::PinholeModel left_model;             ///< rectified left camera
  double baseline_m = 0.0;                 ///< right camera's offset along the left's x [m]
  bool rectified_here = false;             ///< the file's images were raw
};

using RangeData = std::variant<DepthImage, PointScan, StereoPair>;

/// A pose of the body in the odometry frame at a time.
struct OdometrySample {
  double stamp_s = kNoStamp;
  Eigen::Isometry3d T_odom_body = Eigen::Isometry3d::Identity();
  /// Where it came from: the sensor label of a CObservationOdometry, or
  /// "CActionRobotMovement2D" / "CActionRobotMovement3D" for integrated actions.
  std::string source;
};

/// The body's attitude from an IMU: MRPT's yaw-pitch-roll (Z-Y-X) convention, R_world_body
/// = Rz(yaw) Ry(pitch) Rx(roll); pitch > 0 nose down, roll > 0 left side up.
struct ImuAttitude {
  double stamp_s = kNoStamp;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  std::optional<double> yaw_rad;  ///< when the IMU gives one
  std::string label;
};

/// One raw inertial sample, in the IMU's own frame (MRPT's IMU_X_ACC.. and IMU_WX..):
/// specific force (gravity included, +9.8 m/s^2 along up at rest) [m/s^2] and angular rate
/// [rad/s]; either may be absent. T_body_imu places the IMU on the body (the
/// observation's sensorPose; identity when the source gives none).
struct ImuSample {
  double stamp_s = kNoStamp;
  std::optional<Eigen::Vector3d> specific_force_mps2;
  std::optional<Eigen::Vector3d> angular_rate_radps;
  Eigen::Isometry3d T_body_imu = Eigen::Isometry3d::Identity();
  std::string label;
};

struct Frame {
  std::string label;       ///< the observation's sensorLabel
  std::string mrpt_class;  ///< e.g. "CObservation3DRangeScan"
  int entry = -1;          ///< top-level object of the file it came from (0-based)
  int index = -1;          ///< its number among the range frames read (0-based)
  double stamp_s = kNoStamp;
  /// The sensor's frame (optical or LiDAR, see the top of this file) in the body frame.
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
  RangeData data;
  /// The last odometry pose and IMU attitude read before this frame, in file order (their
  /// stamps say how old they are); empty when the file has none so far.
  std::optional<OdometrySample> odometry;
  std::optional<ImuAttitude> imu;
  /// The raw IMU samples read since the previous frame of this source (file order).
  std::vector<ImuSample> imu_samples;

  const DepthImage* depth() const { return std::get_if<DepthImage>(&data); }
  const PointScan* points() const { return std::get_if<PointScan>(&data); }
  const StereoPair* stereo() const { return std::get_if<StereoPair>(&data); }
  /// "depth", "points" or "stereo".
  const char* kind() const;
};

/// Gravity's up vector in the sensor frame (unit). The body is taken as level (up = body z)
/// unless frame.imu gives its roll and pitch; the sensor's tilt on the body comes from
/// T_body_sensor. Yaw plays no part.
Eigen::Vector3d UpInSensor(const Frame& frame);

/// R_world_body of an attitude (yaw 0 when absent).
Eigen::Matrix3d RotationFromImu(const ImuAttitude& imu);

/// A frame's range image, levelled with gravity's `up_sensor` (unit, sensor frame).
struct FrameImage {
  od::RangeImage image;
  /// Stereo pairs: the depth matched with the given StereoConfig (od_io's semi-global
  /// matching), which the image was made from.
  std::optional<od::StereoDepth> stereo;
};

/// The one way from any Frame to its range image: depth images and point scans as they
/// are (point scans with their rows and columns when the source found them), stereo pairs
/// matched first. Errors say what failed ("stereo: ...", or the range image's own).
Expected<FrameImage> ToRangeImage(const Frame& frame, const Eigen::Vector3d& up_sensor,
                                  const od::StereoConfig& stereo);

}  // namespace cairn::sources
