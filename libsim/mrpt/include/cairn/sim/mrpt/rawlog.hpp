// MRPT rawlogs in the observations format (a flat list of CObservation objects): writing
// them crash-safely, reading them back in file order, and the observations a synthetic
// drive is made of.
//
// What cairn writes, per frame, all with the frame's timestamp:
//   "ODOMETRY"  CObservationOdometry: odometry = T_odom_body as (x, y, yaw) [m, rad],
//               velocityLocal = (vx, vy, omega) of the body [m/s, rad/s].
//   "IMU"       CObservationIMU: IMU_YAW, IMU_PITCH, IMU_ROLL present [rad], MRPT's Z-Y-X
//               convention (as CPose3D: pitch > 0 nose down, roll > 0 left side up).
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
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CSerializable.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {

inline constexpr const char* kCameraLabel = "CAMERA";
inline constexpr const char* kLidarLabel = "LIDAR";
inline constexpr const char* kOdometryLabel = "ODOMETRY";
inline constexpr const char* kImuLabel = "IMU";

/// Frame conversions between Eigen and MRPT poses (exact up to rounding).
::mrpt::poses::CPose3D ToCPose3D(const Eigen::Isometry3d& T);
Eigen::Isometry3d FromCPose3D(const ::mrpt::poses::CPose3D& pose);

/// Unix seconds <-> mrpt::Clock, to the 100 ns tick (rounded to nearest).
::mrpt::Clock::time_point ToMrptTime(double unix_s);
double FromMrptTime(::mrpt::Clock::time_point t);

/// Writes a rawlog into a temporary file beside `path`, renamed over `path` by Commit(): a
/// reader never sees a half-written rawlog. Abandoned (destroyed without Commit), the
/// temporary is removed. gzip level 0 writes a plain file, 1..9 a gzip-compressed one (MRPT
/// reads both). Move-only.
class RawlogWriter {
 public:
  static Expected<RawlogWriter> Create(const std::filesystem::path& path, int gzip_level = 1);
  RawlogWriter(RawlogWriter&&) noexcept = default;
  RawlogWriter& operator=(RawlogWriter&&) noexcept = default;
  ~RawlogWriter();

  /// Appends one object (an observation). Fails, naming the file, when writing fails.
  Status Write(const ::mrpt::serialization::CSerializable& object);
  /// Closes and renames into place. Nothing can be written afterwards.
  Status Commit();

  int objects_written() const { return written_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  RawlogWriter() = default;
  std::filesystem::path path_, temp_path_;
  std::unique_ptr<::mrpt::io::CFileGZOutputStream> out_;
  int written_ = 0;
};

/// Reads a rawlog (plain or gzip) object by object. Observations-format files give their
/// observations; sensory-frame files give the observations of each CSensoryFrame in turn
/// and skip the actions (CActionCollection). Move-only.
class RawlogReader {
 public:
  static Expected<RawlogReader> Open(const std::filesystem::path& path);
  RawlogReader(RawlogReader&&) noexcept;
  RawlogReader& operator=(RawlogReader&&) noexcept;
  ~RawlogReader();

  /// The next observation, or nullptr at the end of the file. Fails on a truncated or
  /// corrupt file or an unknown class, naming the file and the entry.
  Expected<::mrpt::obs::CObservation::Ptr> Next();

  /// Entries (top-level objects) read so far.
  int entries_read() const { return entries_; }

 private:
  class Stream;  // the file with one byte of look-ahead, to tell its end from truncation
  RawlogReader() = default;
  std::filesystem::path path_;
  std::unique_ptr<::mrpt::io::CFileGZInputStream> file_;
  std::unique_ptr<Stream> stream_;
  std::deque<::mrpt::obs::CObservation::Ptr> pending_;
  int entries_ = 0;
};

/// Every observation of a rawlog, in file order (see RawlogReader).
Expected<std::vector<::mrpt::obs::CObservation::Ptr>> ReadRawlogObservations(
    const std::filesystem::path& path);

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

/// A range scan decoded for cairn: z-depth per pixel (row-major) with the pinhole and the
/// optical frame's pose on the body.
struct RangeScanFrame {
  od::PinholeModel model;
  std::vector<float> depth_m;                                       ///< z-depth [m], 0 = no return
  Eigen::Isometry3d T_body_camera = Eigen::Isometry3d::Identity();  ///< optical frame
  double stamp_s = 0.0;                                             ///< Unix seconds
  std::string label;
};

/// Decodes a range scan (range_is_depth true, or false: ranges along the ray converted to
/// z-depth), loading externally stored images first. Fails when it holds no range image or
/// its cameraParams do not match the image size.
Expected<RangeScanFrame> DecodeRangeScan(const ::mrpt::obs::CObservation3DRangeScan& scan);

}  // namespace cairn::sim
