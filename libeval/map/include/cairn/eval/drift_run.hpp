// Mapping a world from the poses a robot would believe, scored against the world's truth:
// libsim's drive with drifting 2-D odometry and a biased IMU, every frame through the
// map::Mapper (prior tilt, the frame-to-map refiner or the gravity estimator). Shared by the
// map study (`cairn eval --maps`, datasets/maps/REPORT.md) and the claims of map_drift_test.
//
// The believed pose of the body: x, y, yaw from odometry; roll and pitch from the IMU; height
// dead-reckoned from the odometry steps and the IMU pitch (dz = -d tan(pitch), trapezoid),
// starting at the true height (odometry starts at the true pose). The sensor renders from
// the TRUE pose; the range image is levelled with the believed up vector and the frame is
// fused at the believed pose, as on a real robot.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cairn/eval/map_score.hpp"
#include "cairn/map/imu.hpp"
#include "cairn/map/mapper.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/sim/drive.hpp"

namespace cairn::eval {

/// One mapping run.
struct DriftRunSpec {
  std::string world;                       ///< world file (libsim's YAML)
  od::io::DetectSettings settings;         ///< the detector and the rules
  std::vector<Eigen::Vector2d> waypoints;  ///< world xy [m]
  double turn_radius_m = 0.0;              ///< libsim DriveSpec::turn_radius_m
  bool true_poses = false;                 ///< fuse at the true poses (no odometry, no IMU)
  double odom_sigma_per_m = 0.0;           ///< libsim DriveSpec::odom_sigma_per_m
  double odom_yaw_sigma_rad_per_m = 0.0;   ///< libsim DriveSpec::odom_yaw_sigma_rad_per_m
  double imu_bias_rad = 0.0;               ///< constant roll and pitch bias
  double imu_sigma_rad = 0.0;              ///< the IMU attitude output's noise
  bool refine_tilt = false;                ///< Ceres tilt refiner on the believed pose
  bool gravity = false;                    ///< the gravity estimator (takes over refine_tilt)
  /// With `gravity`: once the drive is over, its frames posed again by the smoother
  /// (Mapper::SmoothTilt) and fused again at those poses into a new map. The result's map,
  /// ground_height_rms_m, pose errors and on_frame calls are the second pass's; its flags,
  /// height sigma and refined_frames the first's.
  bool smooth = false;
  /// The floor of every tilt mode: roll, pitch and height true, x, y and heading from the
  /// odometry (what is left is the odometry's horizontal drift).
  bool truth_tilt_height = false;
  /// Raw IMU errors (accelerometer and gyro bias and noise, misalignment) and the sensor's
  /// mount misalignment; the raw samples reach the Mapper in every mode.
  sim::ImuSpec imu;
  Eigen::Vector3d sensor_misalignment_rad = Eigen::Vector3d::Zero();  ///< roll, pitch, yaw
  bool measure_cues = false;     ///< score the vertical cues (gravity_cues.hpp) of every frame
  std::uint64_t drive_seed = 1;  ///< draws the drift of the drive and the sensor's noise
  double rate_hz = 2.0;
  double speed_mps = 2.0;
  int camera_width = 320;  ///< the world's camera scaled to this width (its own: 320 x 240)
  /// Changes the Mapper's settings before it is made (studies); may be empty.
  std::function<void(map::MapperConfig&)> configure;
  /// Called with every frame's record and its true sample (diagnostics); may be empty.
  std::function<void(const map::MapperRecord&, const sim::DriveSample&)> on_frame;
};

/// Odometry that drifts by `fraction` of the distance (sigma of the scale error) and, in
/// proportion, 0.5 deg of heading per 10 m at 1 %.
void DriftOdometryBy(DriftRunSpec& spec, double fraction);

/// An obstacle is seen well in a frame where it covers this many pixels of a 160 x 120 image,
/// or the same part of the view at another size (120 pixels of 320 x 240).
constexpr double kSeenWellPixels160 = 30.0;

/// One obstacle seen well (kSeenWellPixels160) against the map.
struct ObstacleScore {
  std::string name;
  double first_seen_distance_m = 0.0;  ///< distance driven at the first frame seeing it well
  double nearest_lethal_m = 0.0;       ///< from its obstacle cells to the nearest lethal cell [m]
};

/// Believed pose against the truth, per frame.
struct PoseError {
  double distance_m = 0.0;  ///< driven so far
  double position_m = 0.0;  ///< horizontal error of the believed sensor position [m]
  double yaw_rad = 0.0;     ///< |heading error|
  double tilt_rad = 0.0;    ///< angle between the believed and true up vectors
  /// Gravity mode: d^T P^+ d, d the fused up vector less the true one (sensor frame) and P the
  /// estimator's covariance of it (GravityEstimate::up_sensor_covariance): chi-square with two
  /// degrees of freedom where the estimator's covariance is right. NaN without one.
  double tilt_nees = NAN;
  double tilt_sigma_rad = NAN;  ///< and sqrt(trace P): the tilt error it expects (RMS) [rad]
  double z_m = 0.0;         ///< |height error| of the sensor [m]
};

struct DriftRunResult {
  explicit DriftRunResult(map::Mapper m) : mapper(std::move(m)) {}
  map::Mapper mapper;  ///< the run's Mapper, its map fused
  const map::TerrainMap& map() const { return mapper.map(); }
  int frames = 0;
  double distance_m = 0.0;
  int refined_frames = 0;
  /// The map against the world (ScoreMap with its default options).
  MapScore score;
  /// The obstacles seen well (kSeenWellPixels160) in some frame, by id, and over them the largest
  /// and mean distance to the nearest lethal cell and how many are within found_within_m.
  std::vector<ObstacleScore> obstacles;
  double max_distance_m = 0.0, mean_distance_m = 0.0;
  int found_0_3 = 0;
  /// Every fused frame's terrain returns within map.max_range (every 4th pixel): the height
  /// they were fused at against the true terrain under their true position [m]. Unlike
  /// score.elevation_rms_m, which compares the grid with the terrain at the same x, y, it
  /// leaves out the odometry's horizontal drift: it is the error the fused pose's tilt and
  /// height put into the map.
  double ground_height_rms_m = 0.0;
  std::vector<PoseError> pose_errors;
  /// measure_cues: each vertical cue's angle from the true vertical (a wall normal's from
  /// the horizontal) [rad].
  std::vector<double> cue_errors_rad;
  /// Gravity mode: frames whose estimate flagged a state as not observable, and the last
  /// frame's flags (state and reason).
  int degenerate_frames = 0;
  int accel_bias_flagged_frames = 0;  ///< of them, those with the accelerometer bias flagged
  std::vector<map::GravityDegeneracy> last_degeneracies;
  /// Gravity mode: the estimator's own height sigma for the last frame [m] (NaN when it
  /// computed no covariance): what it says it knows of the height, against the truth's
  /// ground_height_rms_m.
  double final_height_sigma_m = NAN;
};

/// Angle between the up vectors of two world-from-sensor rotations [rad].
double TiltBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b);

/// The drive's raw IMU readings from drive.imu[*next] up to the stamp `up_to_s`, rotated into
/// the body frame as the Mapper takes them; *next moves past them (start it at 0 and call
/// once per frame for the samples since the previous frame).
std::vector<map::ImuSample> BodyImuUpTo(const sim::Drive& drive, double up_to_s, std::size_t* next);

/// Drives, maps and scores one run. Fails on a world that does not load, a frame that does
/// not render, is skipped or does not fuse, or a map that observed nothing.
Expected<DriftRunResult> RunDrift(const DriftRunSpec& spec);

}  // namespace cairn::eval
