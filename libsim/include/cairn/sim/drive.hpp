// A vehicle driving a DriveSpec over a terrain: true poses, drifting odometry and a noisy,
// biased IMU attitude, one sample per sensor frame. Pure Eigen; file formats (MRPT rawlogs,
// TUM pose files) live in cairn::sim_mrpt.
//
// Frames (world z up, metres, radians, seconds):
//   body    x forward, y left, z up. Its origin is on the ground: the mean height of the four
//           wheel contacts, midway between the axles and between the wheels.
//   sensor  the camera's optical frame (x right, y down, z forward) or the LiDAR frame
//           (x forward, y left, z up), mounted at DriveSpec::T_body_sensor_xyz and pitched
//           down by DriveSpec::sensor_pitch_rad about the body's y axis.
//   odom    the odometry frame: equal to the world at the first frame (odometry starts at the
//           true planar pose), so that a map built from odometry is compared with the world
//           directly; it drifts from there.
// Attitudes are Z-Y-X Euler angles as MRPT's CPose3D has them:
// R_world_body = Rz(yaw) * Ry(pitch) * Rx(roll). Pitch > 0 puts the nose below the
// horizontal and roll > 0 lifts the left side (dips the right), as od::CameraUpFromPitchRoll.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sim/terrain.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {

/// Which axes convention the sensor frame has.
enum class SensorFrame {
  kCameraOptical,  ///< x right, y down, z forward
  kLidar,          ///< x forward, y left, z up
};

/// Roll, pitch, yaw [rad] (Z-Y-X, see above).
struct Attitude {
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rad = 0.0;
};

/// A planar pose, as 2-D odometry has it: position [m] and heading [rad] in (-pi, pi].
struct Pose2D {
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;
};

/// One sample of the drive, taken when a sensor frame is.
struct DriveSample {
  int index = 0;
  double stamp_s = 0.0;     ///< since the first frame: index / frame_rate_hz [s]
  double distance_m = 0.0;  ///< path length driven so far (planar) [m]
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  Attitude attitude;   ///< true attitude of the body
  Pose2D odometry;     ///< T_odom_body as measured by the wheels (drifts)
  Attitude imu;        ///< body attitude as the IMU reports it (noise, roll/pitch bias)
  Pose2D true_planar;  ///< the true (x, y, yaw) of the body, for comparison with odometry
};

/// The drifts drawn for one drive: the systematic parts of its errors.
struct DriveErrors {
  double odom_scale_error = 0.0;          ///< odometry distance = (1 + this) * true distance
  double odom_yaw_drift_rad_per_m = 0.0;  ///< heading error added per metre driven [rad/m]
  double imu_roll_bias_rad = 0.0;         ///< constant, = DriveSpec::imu_bias_rad
  double imu_pitch_bias_rad = 0.0;        ///< constant, = DriveSpec::imu_bias_rad
};

struct Drive {
  SensorFrame sensor = SensorFrame::kCameraOptical;
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
  double path_length_m = 0.0;  ///< planar length of the waypoint polyline [m]
  DriveErrors errors;
  std::vector<DriveSample> samples;  ///< in time order, one per frame
};

/// Drives `spec` over `terrain`. The body moves at spec.speed_mps along the waypoint
/// polyline and is sampled at spec.frame_rate_hz from the first waypoint to the last (or
/// for `max_frames` frames when > 0). Its heading is that of the chord from its rear axle to
/// its front axle, both on the path (so corners are cut smoothly); its height, pitch and
/// roll are those of the plane fitted to the terrain under its four wheels, exact on planar
/// terrain.
///
/// Odometry (2-D, like wheel odometry): each frame-to-frame increment, in the body frame,
/// is scaled by (1 + s) and turned by d * b, where d is the step's length and s ~
/// N(0, odom_sigma_per_m), b ~ N(0, odom_yaw_sigma_rad_per_m) are drawn once per drive
/// (wheel-radius error, heading drift); on top, a random walk adds per step N(0, sigma^2 d)
/// to each translation component (sigma = odom_sigma_per_m, variance per metre driven) and
/// N(0, yaw_sigma^2 d) to the heading. All zero gives odometry equal to the true planar pose.
/// IMU: roll and pitch get +imu_bias_rad and N(0, imu_sigma_rad) each sample, yaw the noise.
///
/// Deterministic: the same terrain, spec and seed give the same drive on every platform.
/// Fails, naming the field ("drive.speed_mps", ...), on a spec it cannot drive: fewer than
/// two distinct waypoints, a non-positive speed, rate, wheelbase or track, a negative or
/// non-finite sigma.
Expected<Drive> SimulateDrive(const Terrain& terrain, const DriveSpec& spec, SensorFrame sensor,
                              std::uint64_t seed, int max_frames = 0);

/// Number of frames a whole drive gives (0 when the spec cannot be driven).
int DriveFrameCount(const DriveSpec& spec);

/// The sensor's pose on the body, for `spec`'s mount.
Eigen::Isometry3d BodyToSensor(const DriveSpec& spec, SensorFrame sensor);

/// R such that p_optical = R * p_flu: the optical frame (x right, y down, z forward) against
/// a frame at the same place with x forward, y left, z up (LiDAR, MRPT, ROS body axes).
Eigen::Matrix3d RotationOpticalFromFlu();

/// R_world_body from an attitude, and back (yaw and roll in (-pi, pi], pitch in
/// [-pi/2, pi/2]).
Eigen::Matrix3d RotationFromAttitude(const Attitude& attitude);
Attitude AttitudeFromRotation(const Eigen::Matrix3d& R_world_body);

/// A 64-bit mix of a seed and an index (splitmix64), for per-frame noise seeds.
std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t index);

}  // namespace cairn::sim
