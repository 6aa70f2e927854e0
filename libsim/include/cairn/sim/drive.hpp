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

/// Standard gravity [m/s^2]; world gravity is (0, 0, -kGravity).
inline constexpr double kGravityMps2 = 9.80665;

/// The raw inertial sensor: an accelerometer and a gyro in the IMU frame, sampled at
/// rate_hz from the body's true motion, and the errors of each source, separately. The
/// attitude the IMU's filter reports (DriveSample::imu) keeps DriveSpec::imu_bias_rad and
/// imu_sigma_rad as its error.
struct ImuSpec {
  double rate_hz = 100.0;  ///< raw samples per second [Hz], > 0
  /// Constant accelerometer bias, IMU frame [m/s^2].
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  double accel_sigma_mps2 = 0.02;  ///< white noise per sample and axis [m/s^2]
  /// Constant gyro bias (drift), IMU frame [rad/s].
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  double gyro_sigma_radps = 0.002;  ///< white noise per sample and axis [rad/s]
  /// The IMU frame on the body: R_body_imu = Rz(yaw) Ry(pitch) Rx(roll) of these (roll,
  /// pitch, yaw) [rad]. Its readings are in the IMU frame and the attitude it reports is the
  /// IMU frame's, so a misalignment looks like a tilt to whoever assumes IMU = body.
  Eigen::Vector3d misalignment_rad = Eigen::Vector3d::Zero();

  /// Names the first bad field ("imu.rate_hz", ...).
  Status Validate() const;
};

/// One raw IMU sample, in the IMU frame. Sample j stands for the interval
/// [stamp_s - dt/2, stamp_s + dt/2] (dt = 1 / rate_hz): its angular rate is the rotation over
/// that interval divided by dt, so that the product of Exp(omega_j dt) is the true rotation
/// exactly; its specific force f = R_world_imu^T (a + kGravity e_z) is the mean acceleration
/// a over the two intervals around it (a second difference of the position, so that
/// sum_j a_j dt telescopes to the velocity change), plus bias and noise.
struct ImuReading {
  double stamp_s = 0.0;                                          ///< same clock as the frames [s]
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();  ///< accelerometer [m/s^2]
  Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();   ///< gyro [rad/s]
};

/// The ideal (error-free) reading of an IMU whose frame follows T_world_imu(t), for the
/// interval of half-width dt/2 around t, as ImuReading defines it.
template <typename PoseAt>
ImuReading IdealImuReading(const PoseAt& T_world_imu, double t, double dt);

/// The drifts drawn for one drive: the systematic parts of its errors.
struct DriveErrors {
  double odom_scale_error = 0.0;          ///< odometry distance = (1 + this) * true distance
  double odom_yaw_drift_rad_per_m = 0.0;  ///< heading error added per metre driven [rad/m]
  double imu_roll_bias_rad = 0.0;         ///< constant, = DriveSpec::imu_bias_rad
  double imu_pitch_bias_rad = 0.0;        ///< constant, = DriveSpec::imu_bias_rad
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();  ///< = ImuSpec's
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();  ///< = ImuSpec's
};

struct Drive {
  SensorFrame sensor = SensorFrame::kCameraOptical;
  /// The nominal mount (what a mapper is told); samples' T_world_sensor use the true one.
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
  /// The true mount: T_body_sensor with DriveSpec::sensor_misalignment_rad.
  Eigen::Isometry3d T_body_sensor_true = Eigen::Isometry3d::Identity();
  /// The IMU frame on the body (rotation only, the IMU sits at the body origin).
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  double path_length_m = 0.0;  ///< planar length of the waypoint polyline [m]
  DriveErrors errors;
  std::vector<DriveSample> samples;  ///< in time order, one per frame
  /// Raw IMU samples at ImuSpec::rate_hz, stamps (j + 1/2) / rate_hz from the first frame's
  /// time to the last one's, so that frame times fall on interval boundaries.
  std::vector<ImuReading> imu;
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
///
/// Raw IMU (`imu`): the body's pose as a function of time (the same one the frames sample,
/// at the speed DriveSpec gives, speed waves included), read as IdealImuReading says, plus
/// the ImuSpec's biases and noise (a noise stream of its own: the frames, odometry and
/// attitude output are those of a drive without raw IMU). The body origin follows the
/// waypoint polyline, so at a waypoint its velocity turns within one sample: the
/// accelerometer sees that as an impulse (the velocity change stays right over an interval);
/// drives meant for inertial estimation use finely sampled curves.
Expected<Drive> SimulateDrive(const Terrain& terrain, const DriveSpec& spec, SensorFrame sensor,
                              std::uint64_t seed, int max_frames = 0,
                              const ImuSpec& imu = ImuSpec{});

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

/// Z-Y-X rotation from (roll, pitch, yaw) [rad]: Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Matrix3d RotationFromRollPitchYaw(const Eigen::Vector3d& roll_pitch_yaw);

/// A 64-bit mix of a seed and an index (splitmix64), for per-frame noise seeds.
std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t index);

template <typename PoseAt>
ImuReading IdealImuReading(const PoseAt& T_world_imu, double t, double dt) {
  const Eigen::Isometry3d before = T_world_imu(t - dt), now = T_world_imu(t),
                          after = T_world_imu(t + dt);
  const Eigen::Matrix3d R_lo = T_world_imu(t - 0.5 * dt).linear();
  const Eigen::Matrix3d R_hi = T_world_imu(t + 0.5 * dt).linear();
  const Eigen::Vector3d a =
      (after.translation() - 2.0 * now.translation() + before.translation()) / (dt * dt);
  ImuReading reading;
  reading.stamp_s = t;
  reading.specific_force_mps2 =
      now.linear().transpose() * (a + Eigen::Vector3d(0.0, 0.0, kGravityMps2));
  const Eigen::AngleAxisd turn(R_lo.transpose() * R_hi);
  reading.angular_rate_radps = turn.angle() / dt * turn.axis();
  return reading;
}

}  // namespace cairn::sim
