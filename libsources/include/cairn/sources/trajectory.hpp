// Trajectory: where the robot was at any time of a recording, for placing each range frame
// in the world: T_world_sensor(frame) = T_world_body(frame.stamp_s) * frame.T_body_sensor.
//
// Three kinds of pose source:
//  - Odometry (FromOdometry): the OdometrySamples of a rawlog (CObservationOdometry, and the
//    composed CActionRobotMovement2D/3D of sensory-frame files), with IMU attitudes.
//    The world frame is the odometry frame (z up, equal to the body at the first sample
//    when the odometry starts at the identity).
//  - KITTI (FromKitti): poses.txt and calib.txt's Tr give the velodyne's pose in the z-up
//    map frame (the velodyne of frame 0), stamped by times.txt; the "body" is the velodyne.
//  - TUM pose files (ReadTumTrajectory): "stamp tx ty tz qx qy qz qw", the pose of the
//    sensor (or body) in the file's world frame.
//
// Interpolation: linear in position, spherical-linear in rotation (along the geodesic)
// between the two samples around the stamp, as MRPT's CPose3DInterpolator with imLinearSlerp
// (the tests compare it with MRPT's slerp). Linear and not a spline because (1) odometry and
// ground-truth files are sampled at or above the frame rate, so the chord error is small and
// bounded (a circle of radius r sampled every dtheta rad: at most r (1 - cos(dtheta / 2))); (2) it
// never overshoots between samples, where a spline does on the step changes of real odometry; (3)
// MRPT's splines need two samples on each side and give nothing in the first and last interval.
//
// Attitude: 2-D odometry knows no tilt. Where an IMU attitude lies within
// TrajectoryOptions::max_imu_age_s of the stamp, its roll and pitch (interpolated linearly
// between the IMU samples around the stamp) replace the odometry's; the heading (yaw) always
// comes from the odometry, whose frame the map is in (an IMU's yaw is magnetic or drifting).
// For planar odometry the height is integrated from the IMU pitch along the way (each step
// of horizontal length d along the heading climbs -d tan(pitch), pitch > 0 nose down),
// so a drive up a hill climbs in the map as it did in the world.
//
// Outside the time span of the samples, poses are extrapolated at the constant velocity of
// the two nearest samples for at most max_extrapolation_s; farther is an error naming the
// frame, as is a stamp between two samples more than max_gap_s apart (the odometry stopped).
//
// Frames: world z up; body x forward, y left, z up (frame.hpp). Metres, radians, seconds
// (Unix seconds for rawlogs, the file's own clock for KITTI and TUM).
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/io/kitti.hpp"
#include "cairn/sources/frame.hpp"

namespace cairn::sources {

struct TrajectoryOptions {
  /// Stamps up to this long before the first sample or after the last get a pose
  /// extrapolated at constant velocity; farther is an error [s].
  double max_extrapolation_s = 0.2;
  /// A stamp between two samples farther apart than this is an error (no pose known there);
  /// 0 = no limit [s].
  double max_gap_s = 2.0;
  /// An IMU attitude this close to the stamp replaces the odometry's roll and pitch [s].
  double max_imu_age_s = 0.25;
  /// Planar odometry: integrate the height from the IMU pitch (see above).
  bool height_from_imu = true;

  /// Names the first bad field: all >= 0 and finite.
  Status Validate() const;
};

/// A pose at a time, for files of poses.
struct StampedPose {
  double stamp_s = kNoStamp;
  Eigen::Isometry3d T_world_x = Eigen::Isometry3d::Identity();
};

/// The body's pose at a stamp, and how it was found.
struct BodyPose {
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  bool tilt_from_imu = false;   ///< roll and pitch came from the IMU
  double extrapolated_s = 0.0;  ///< how far beyond the samples' span (0 inside) [s]
};

class Trajectory {
 public:
  /// From odometry samples (any order; a later sample with the same stamp replaces an
  /// earlier one) and IMU attitudes (may be empty). Fails, naming the sample, on a
  /// non-finite stamp or pose, and on no samples.
  static Expected<Trajectory> FromOdometry(const std::vector<OdometrySample>& odometry,
                                           const std::vector<ImuAttitude>& imu,
                                           const TrajectoryOptions& options = {});
  /// From poses of the body in the world (no IMU). `source` names them in errors.
  static Expected<Trajectory> FromPoses(const std::vector<StampedPose>& poses,
                                        const std::string& source,
                                        const TrajectoryOptions& options = {});
  /// A KITTI sequence's velodyne poses in the z-up map frame, stamped by times.txt. Fails
  /// when the sequence has no poses.txt.
  static Expected<Trajectory> FromKitti(const od::io::KittiSequence& sequence,
                                        const TrajectoryOptions& options = {});

  /// The body's pose at `stamp_s`. Fails, saying how far the stamp lies from the samples,
  /// outside the span plus the extrapolation limit, or inside a gap longer than max_gap_s.
  Expected<BodyPose> PoseAt(double stamp_s) const;
  /// T_world_body(frame.stamp_s) * frame.T_body_sensor. Errors name the frame (index,
  /// label, entry, stamp).
  Expected<Eigen::Isometry3d> T_world_sensor(const Frame& frame) const;

  double start_s() const { return samples_.front().stamp_s; }
  double end_s() const { return samples_.back().stamp_s; }
  /// The samples, by stamp, as the trajectory holds them: the odometry's poses with the
  /// height integrated from the IMU (planar odometry), before the IMU tilt is applied.
  const std::vector<StampedPose>& samples() const { return samples_; }
  /// Length of the polyline through the samples, in 3-D [m].
  double PathLength() const;
  /// Where the poses came from, for reports ("odometry ODOMETRY + IMU", a file name, ...).
  const std::string& source() const { return source_; }

 private:
  Trajectory() = default;
  /// IMU roll and pitch at `stamp_s` when a sample is near enough.
  bool ImuTiltAt(double stamp_s, double* roll_rad, double* pitch_rad) const;

  TrajectoryOptions options_;
  std::string source_;
  std::vector<StampedPose> samples_;  // by stamp, strictly increasing
  std::vector<ImuAttitude> imu_;      // by stamp, strictly increasing
};

/// Reads a TUM pose file: '#' comment lines and blank lines skipped, else per line
/// "stamp tx ty tz qx qy qz qw" (metres, unit quaternion, seconds). Fails, naming the file
/// and the line, on a line without 8 numbers, a quaternion whose norm is not 1 (to 1e-3),
/// a stamp not after the one before it, or no pose.
Expected<std::vector<StampedPose>> ReadTumPoses(const std::filesystem::path& path);

/// One TUM line, without the newline: the stamp and the position with 6 decimals, the
/// quaternion with 9 (qw >= 0).
std::string TumLine(const StampedPose& pose);

/// Writes a TUM pose file atomically: `comment` (one or more lines) as '#' lines, the
/// column names, then one line per pose. ReadTumPoses reads it back.
Status WriteTumPoses(const std::filesystem::path& path, const std::vector<StampedPose>& poses,
                     const std::string& comment);

/// ReadTumPoses, then Trajectory::FromPoses.
Expected<Trajectory> ReadTumTrajectory(const std::filesystem::path& path,
                                       const TrajectoryOptions& options = {});

}  // namespace cairn::sources
