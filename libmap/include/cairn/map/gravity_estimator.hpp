// Gravity observed, not assumed: a Ceres estimator over a sliding window of frames that
// recovers each frame's roll, pitch (and height) from cues that see gravity, with the slowly
// varying states they need (accelerometer and gyro biases, the sensor mount's tilt, the
// odometry's scale).
//
// Cues, each a residual weighted by its stated noise (gravity_terms.hpp has the formulas):
//   - accelerometer: the specific force averaged around each frame (with the kernel of the
//     odometry's velocity differences) against gravity plus the motion acceleration the
//     odometry implies (along-track from the change of speed, lateral from speed x yaw rate,
//     vertical from the pitch along the way) or a known velocity gives; Huber-robust
//     (bumps);
//   - gyro: the rotation integrated between consecutive frames;
//   - vertical structure: tall segments' axes are vertical, walls' normals horizontal
//     (measured in the sensor frame; Cauchy-robust, because trees lean);
//   - heights: the height step implied by the pitch over the distance driven (the
//     odometry's, its scale error a slow state), an optional frame-to-map ground height,
//     and the ground a frame sees against the same ground seen by an earlier frame of the
//     window (GroundRise: a rise measured by the sensor, which moves with its tilt);
//     Huber-robust;
//   - priors: the IMU's attitude output (roll, pitch), the measured heading (yaw).
// Frames that leave the window are marginalised into a Gaussian prior on what remains
// (Schur complement), so the biases and the mount learned earlier are kept.
//
// What it cannot see, it says: a straight drive on even ground cannot tell an accelerometer
// bias from a tilt (a turn or a change of attitude separates them, through the gyro); a
// sensor mount's tilt needs vertical structure in view, or ground seen by two frames. Such a state
// keeps (about) its prior uncertainty and is flagged with the reason, rather than corrected from
// nothing.
//
// Frames: world z up; body x forward, y left, z up, defined by the IMU (R_body_imu, known);
// sensor frames as od:: has them, on the body by R_body_sensor_nominal. Attitudes Z-Y-X as
// sim::RotationFromAttitude: pitch > 0 nose down, roll > 0 left side up. Radians, metres,
// seconds. Biases are constant over a run (no random walk modelled).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::map {

struct GravityEstimatorConfig {
  int window_frames = 12;  ///< frames solved together (>= 2 accel_half_span_frames + 2)
  double gravity_mps2 = 9.80665;   ///< local gravity [m/s^2]
  // Noises (the stated sigma of each residual).
  double accel_sigma_mps2 = 0.02;   ///< accelerometer white noise per sample [m/s^2]
  /// Motion the odometry misses, per span average [m/s^2]. 0.03 served the map study's
  /// drives best once the force was averaged as the odometry's velocities imply (0.05 before);
  /// EuRoC's flight, with its true velocity, leaves 0.05 (`cairn eval --euroc` sets that).
  double motion_sigma_mps2 = 0.03;
  /// The accelerometer term spans this many frames on each side of its centre (m): one
  /// term per 2m frames, spans end to end (the forces' kernels reach a frame beyond each
  /// end, so neighbours share it). Longer spans average the odometry's displacement noise
  /// down (its noise enters divided by the span); short ones observe the body's up
  /// (not only the sensor's) sooner and more often. On the 60 m uphill drive with a 2 deg
  /// IMU bias and 1% odometry (seeds 1-3), before the kernel was matched, the fused
  /// ground's height RMS was 0.050-0.066 m with m = 3 and 0.015-0.021 m with m = 1.
  int accel_half_span_frames = 1;
  /// With m > 1: the first spans of a run are this many 2-frame spans (half span 1), then
  /// the long ones follow end to end, so that the body's up is observed after 3 frames
  /// instead of 2m + 1 (before, the first frames knew only the sensor's up from vertical
  /// cues and the height was integrated from a body pitch 1.5 deg off).
  int accel_warmup_spans = 3;
  /// Each frame's odometry position noise, white, per axis [m] (a velocity from a chord of
  /// time T is off by it times sqrt(2) / T).
  double odometry_sigma_m = 0.005;
  /// The odometry's random walk [m/sqrt(m)]: a step of d metres is off by this x sqrt(d) per
  /// axis, on top of odometry_sigma_m (0.01: a 1 m step off by 1 cm; the part that grows in
  /// proportion to the distance is odometry_scale_sigma's). The accelerometer term's
  /// odometry part grows with it; unstated (0), a 3 %
  /// odometry's velocities pass for better than they are and tilt the estimate (in
  /// datasets/maps/REPORT.md, the hill drive's with 3 % odometry went 0.26 / 0.59 -> 0.19 /
  /// 0.39 deg, median / 95th percentile, with it stated).
  double odometry_walk_sigma = 0.0;
  double accel_huber = 3.0;         ///< Huber threshold of the accelerometer term [sigma]
  double gyro_sigma_radps = 0.002;  ///< gyro white noise per sample [rad/s]
  double rotation_floor_rad = 1e-4; ///< added to the integrated gyro noise [rad]
  double attitude_prior_sigma_rad = 0.01;  ///< IMU attitude output, per frame (roll, pitch) [rad]
  /// The IMU attitude output's constant bias, a priori (a slow state) [rad].
  double attitude_bias_sigma_rad = 0.05;
  double yaw_sigma_rad = 0.05;             ///< measured heading [rad]
  double vertical_sigma_rad = 0.035;       ///< a trunk's or pole's lean (2 deg) [rad]
  double vertical_cauchy = 1.0;            ///< Cauchy scale of the vertical term [sigma]
  double wall_sigma_rad = 0.02;            ///< a wall normal's tilt [rad]
  double height_step_sigma_m = 0.01;       ///< height step, per frame [m]
  double height_step_sigma_per_m = 0.01;   ///< plus this per metre driven [m/m]
  double ground_height_huber = 2.0;        ///< Huber threshold of the ground term [sigma]
  // Slow states: prior sigma at the start, and whether they are estimated at all.
  double accel_bias_sigma_mps2 = 0.1;    ///< [m/s^2]
  double gyro_bias_sigma_radps = 0.01;   ///< [rad/s]
  double mount_sigma_rad = 0.05;         ///< the mount's roll and pitch (3 deg) [rad]
  /// The wheel odometry's distance scale error (a wheel radius off), a priori [1]: it adds
  /// as much to every climb the height steps integrate, which the frame-to-map ground
  /// heights then see.
  double odometry_scale_sigma = 0.02;
  bool estimate_accel_bias = true;
  bool estimate_gyro_bias = true;
  bool estimate_mount = true;
  bool estimate_odometry_scale = true;
  /// A slow state whose posterior sigma stays above this fraction of its prior sigma is
  /// flagged as not observable.
  double observable_ratio = 0.5;
  int max_iterations = 20;  ///< Ceres iterations per frame
  bool covariance = true;   ///< compute the per-frame covariance (ceres::Covariance)

  /// Fails naming the first field out of range ("gravity.window_frames: ...").
  Status Validate() const;
};

/// One raw IMU sample in the IMU frame (sources::ImuSample without the optionals).
struct GravityImuSample {
  double stamp_s = 0.0;
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();  ///< gravity included
  Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();
};

/// A vertical cue seen by the sensor: a tall segment's axis, or a wall's horizontal normal.
struct VerticalCue {
  Eigen::Vector3d direction_sensor = Eigen::Vector3d::UnitZ();  ///< unit, sensor frame
  bool wall_normal = false;
};

/// The ground this frame sees where an earlier frame saw it too: how much higher this
/// frame's body stands than the earlier one's, measured by the sensor looking at the terrain
/// ahead (not by the wheels or the IMU), at the tilts at which both frames' ground points
/// were placed. A tilt of either sensor moves its points' heights by its rotation of their
/// offset, which the estimator applies as it re-estimates the tilts (GroundRiseTerm in
/// gravity_terms.hpp): against the climb the wheels' plane gives (the body's pitch over the
/// distance), this tells the sensor's tilt from the body's, the mount, without structure in
/// view; with the sensor's tilt anchored by vertical structure it holds the height to the
/// terrain's true rise.
struct GroundRise {
  /// The earlier frame's stamp: one of the window's frames that stay in it with this one.
  double earlier_stamp_s = 0.0;
  double rise_m = 0.0;           ///< body height here minus there, at the placements [m]
  /// The sensors' world rotations at which this frame's and the earlier frame's ground
  /// points were placed.
  Eigen::Matrix3d R_world_sensor = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_world_sensor_earlier = Eigen::Matrix3d::Identity();
  /// The bodies' world rotations at the placements, and the sensor's position on the body
  /// [m]: a tilt of the body moves the sensor with it.
  Eigen::Matrix3d R_world_body = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_world_body_earlier = Eigen::Matrix3d::Identity();
  Eigen::Vector3d sensor_on_body_m = Eigen::Vector3d::Zero();
  /// The matched ground's mean offset from each sensor, world axes [m].
  Eigen::Vector3d offset_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_earlier_m = Eigen::Vector3d::Zero();
  /// Where the frames were placed from the odometry: the displacement between them (world
  /// x, y [m]) and the ground's gradient at the matched places (dz/dx, dz/dy). With the
  /// odometry's distances 1 + s of the true ones, the later frame stood s / (1 + s) of the
  /// displacement short of where it was placed, on ground lower by the gradient times that.
  Eigen::Vector2d odometry_step_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
  double sigma_m = 0.05;  ///< [m]
};

/// What one frame brings.
struct GravityFrame {
  double stamp_s = 0.0;  ///< strictly after the previous frame's [s]
  /// Raw IMU samples since the previous frame (stamps in (previous stamp, stamp]).
  std::vector<GravityImuSample> imu;
  /// Odometry: the planar pose T_odom_body (x, y [m], yaw [rad]). Its displacements give
  /// the velocities (along the nose, for a ground vehicle) and its yaw the heading prior.
  Eigen::Vector3d odometry_xy_yaw = Eigen::Vector3d::Zero();
  /// A known world velocity (z up) [m/s] instead of the odometry's displacements (a
  /// reference, VIO): the accelerometer term then uses it, vertical part included.
  std::optional<Eigen::Vector3d> velocity_world_mps;
  /// The IMU's attitude output for the body (roll, pitch) [rad]; none: no prior.
  std::optional<Eigen::Vector2d> attitude_prior_rad;
  std::vector<VerticalCue> verticals;
  /// A frame-to-map ground height of the body [m] and its sigma [m].
  std::optional<double> ground_height_m;
  double ground_height_sigma_m = 0.05;
  /// This frame's ground against earlier frames' (Huber-robust, ground_height_huber).
  std::vector<GroundRise> ground_rises;
};

/// A state that the data in the window do not determine.
struct GravityDegeneracy {
  enum class State { kAccelBias, kGyroBias, kMount, kCovariance };
  State state = State::kAccelBias;
  std::string reason;  ///< starts with the state's name (StateName), then the figures
};

/// "accelerometer bias", "gyro bias", "sensor mount tilt", "covariance".
const char* StateName(GravityDegeneracy::State state);

/// Which cues the window used (the newest frame's own in the last fields).
struct GravityCues {
  int accel_terms = 0;         ///< frames with an accelerometer term (all but the ends)
  int accel_outliers = 0;      ///< beyond the Huber threshold at the solution
  int gyro_terms = 0;          ///< frame-to-frame gyro rotations
  int attitude_priors = 0;
  int verticals = 0;           ///< vertical cues in the window
  int vertical_outliers = 0;   ///< beyond 3 sigma at the solution (leaning, wrong)
  int ground_heights = 0;
  int ground_rises = 0;        ///< frame-to-frame ground rises in the window
  int frame_imu_samples = 0;   ///< raw samples the newest frame brought
  int frame_verticals = 0;     ///< vertical cues the newest frame brought
  double heading_change_rad = 0.0;  ///< largest heading change seen so far from the start
};

/// The estimate for the newest frame, with diagnostics (in the manner of
/// ceres::Solver::Summary).
struct GravityEstimate {
  double stamp_s = 0.0;
  double roll_rad = 0.0, pitch_rad = 0.0, yaw_rad = 0.0;  ///< body attitude
  double height_m = 0.0;                                  ///< body height [m]
  /// Covariance of (roll, pitch, yaw) [rad^2] and of the height [m^2]; NaN when not computed.
  Eigen::Matrix3d attitude_covariance = Eigen::Matrix3d::Constant(NAN);
  double height_variance = NAN;
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d accel_bias_covariance = Eigen::Matrix3d::Constant(NAN);
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Matrix3d gyro_bias_covariance = Eigen::Matrix3d::Constant(NAN);
  Eigen::Vector2d attitude_bias_rad = Eigen::Vector2d::Zero();  ///< the IMU output's bias
  Eigen::Vector2d mount_rad = Eigen::Vector2d::Zero();  ///< roll, pitch of the mount's tilt
  double odometry_scale = 0.0;                          ///< odometry distance / true distance - 1
  Eigen::Matrix2d mount_covariance = Eigen::Matrix2d::Constant(NAN);
  Eigen::Vector3d up_body = Eigen::Vector3d::UnitZ();    ///< gravity's up in the body frame
  Eigen::Vector3d up_sensor = Eigen::Vector3d::UnitZ();  ///< and in the sensor frame
  /// Covariance of up_sensor [rad^2] (first order, rank 2: across it), from the newest frame's
  /// roll and pitch and the mount's tilt and their cross terms: the sensor's tilt as the
  /// estimator knows it. Its trace is the expected squared tilt error. NaN when not computed.
  Eigen::Matrix3d up_sensor_covariance = Eigen::Matrix3d::Constant(NAN);
  GravityCues cues;
  std::vector<GravityDegeneracy> degeneracies;  ///< empty: every state observed
  // Solver.
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  bool converged = false;
  std::string solver_report;  ///< Ceres' BriefReport

  bool IsSolutionUsable() const { return converged && std::isfinite(roll_rad); }
  bool Degenerate(GravityDegeneracy::State state) const;
  /// One line: attitude, biases, mount, cues, flags.
  std::string BriefReport() const;
};

class GravityEstimator {
 public:
  /// Fails on an invalid config.
  static Expected<GravityEstimator> Create(const GravityEstimatorConfig& config,
                                           const Eigen::Matrix3d& R_body_imu,
                                           const Eigen::Matrix3d& R_body_sensor_nominal);
  GravityEstimator(GravityEstimator&&) noexcept;
  GravityEstimator& operator=(GravityEstimator&&) noexcept;
  ~GravityEstimator();

  /// Adds a frame, solves the window and returns the newest frame's estimate. Fails on a
  /// stamp not after the previous frame's or non-finite input, naming the field.
  Expected<GravityEstimate> AddFrame(const GravityFrame& frame);

  int frames_added() const;

  /// What the estimator carries from frame to frame, as text (JSON): the window's frames
  /// with their states and IMU samples, the marginalised priors, the slow states and the
  /// counters. Its size is bounded by the window, not by the length of the drive.
  std::string SaveState() const;
  /// Restores a SaveState() on an estimator made with the same config and mounts (its own
  /// frames are dropped): the frames added next give the estimates (attitude, height,
  /// biases, mount) to the last bit that the saving estimator would have given; their
  /// covariance, and the flags drawn from it, may differ in the last digits (ceres orders the
  /// parameter blocks by address), as between any two runs. Fails, leaving the estimator as
  /// it was, on text that is not such a state or was saved under other settings, naming what
  /// is wrong.
  Status RestoreState(const std::string& state);

 private:
  friend class GravitySmoother;
  struct State;
  explicit GravityEstimator(std::unique_ptr<State> state);
  // AddFrame's checks and bookkeeping, without the solve.
  Status Push(const GravityFrame& frame);
  std::unique_ptr<State> state_;
};

/// Offline: every frame of a run solved together, with GravityEstimator's terms (a batch
/// smoother). The sliding window answers each frame from the frames up to it: a frame early
/// in a run is answered before the slow states are learned (the accelerometer bias at the
/// first turn, the mount at the first trunks), and a map fused at that answer keeps its
/// error. Over the whole run, what was learned anywhere applies everywhere. Nothing is
/// marginalised, so memory and time grow with the run (sparse Cholesky).
class GravitySmoother {
 public:
  /// As GravityEstimator::Create; config.window_frames is not used.
  static Expected<GravitySmoother> Create(const GravityEstimatorConfig& config,
                                          const Eigen::Matrix3d& R_body_imu,
                                          const Eigen::Matrix3d& R_body_sensor_nominal);
  /// Adds a frame with GravityEstimator::AddFrame's checks (a ground rise may name any earlier
  /// frame); nothing is solved. `start`, when given (a sliding window's estimate of the
  /// frame), is where the solve starts from for its roll, pitch and height; otherwise the
  /// frame before turned by the gyro, which drifts over a long run.
  Status Add(const GravityFrame& frame, const GravityEstimate* start = nullptr);
  int frames() const;
  /// Frame `index` (0 <= index < frames()) as added, its IMU samples left out.
  const GravityFrame& frame(int index) const;
  /// Every frame's estimate, in the order added: attitude, height, and the slow states (the
  /// same in each); the solver's figures; no covariance, cues or flags (the sliding window's
  /// estimates carry those). Solved twice, the IMU terms pre-integrated again at the gyro bias
  /// the first solve found, from the states as they stand, which it leaves as they were (a
  /// second call, or a smoother saved and restored, gives the same). Fails when no frame was
  /// added or the solve does not converge (Ceres' CONVERGENCE) within max(max_iterations,
  /// 100) iterations.
  Expected<std::vector<GravityEstimate>> Solve();

  /// Every frame added, as text (GravityEstimator::SaveState's form), and back: a smoother
  /// restored and given the rest of the run solves as the uninterrupted one. RestoreState
  /// fails, leaving the smoother as it was, on text that is not a smoother's state under the
  /// same settings, or that is a sliding window's (which let frames go).
  std::string SaveState() const;
  Status RestoreState(const std::string& state);

 private:
  explicit GravitySmoother(GravityEstimator estimator) : estimator_(std::move(estimator)) {}
  GravityEstimator estimator_;
};

}  // namespace cairn::map
