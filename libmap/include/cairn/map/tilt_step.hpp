// The Mapper's tilt step: the roll, pitch and height at which a frame is fused, from its
// odometry pose and what the step observes, behind one small interface so that estimators
// can be swapped without touching the per-frame pipeline.
//
// Per frame the Mapper asks the step twice:
//   1. Prior(T_world_sensor_odometry): the pose before this frame's own evidence (the
//      odometry pose with what the step carries from earlier frames). The range image is
//      levelled with its up vector, so the detector measures heights along it.
//   2. Estimate(frame, map): after detection, with the frame's evidence (TiltFrame: stamp,
//      odometry pose, prior, IMU samples since the previous frame, range image, detection,
//      classification, ground points) and the terrain fused so far (before this frame):
//      the pose to fuse the frame at, with diagnostics. It may update what it carries.
// What a step carries from frame to frame is its resume state (SaveState / RestoreState):
// a Mapper restored from a checkpoint continues exactly as the uninterrupted one.
//
// Three steps exist (MakeTiltStep):
//   kPrior     the odometry pose is fused as it is; nothing is carried.
//   kRefineToMap  map::RefineTilt (tilt_refiner.hpp) matches the frame's ground points to the
//              fused elevation around the prior; a usable estimate that lowers the ground
//              RMS is fused and its correction is carried to the next frame's prior (IMU
//              biases and the height integrated from them persist from frame to frame).
//   kGravity   map::GravityEstimator (gravity_estimator.hpp) over a sliding window: the
//              frame's raw IMU samples, its odometry (planar pose, velocity), the IMU
//              attitude in the odometry pose as a prior, the vertical structure the
//              detector found (gravity_cues.hpp), and, once vertical cues anchor the tilt,
//              the body height at which its ground fits the terrain fused so far
//              (RefineHeight: RefineTilt's height with the tilt held). The
//              frame is fused at the estimated roll, pitch, height and mount tilt, the
//              odometry's x, y and heading. With TiltConfig::smooth it also keeps every
//              frame's evidence for a GravitySmoother: once the run is over, Smooth() poses
//              every frame again with what the whole run observed, for a second pass that
//              fuses the map at those poses (offline map building).
// Mapper::Create also takes a step of the caller's.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cairn/map/gravity_cues.hpp"
#include "cairn/map/gravity_estimator.hpp"
#include "cairn/map/imu.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/map/tilt_refiner.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::map {

enum class TiltMode {
  kPrior,        ///< fuse the odometry pose as it is
  kRefineToMap,  ///< RefineTilt against the fused terrain, correction carried
  kGravity,      ///< GravityEstimator: IMU, odometry and vertical structure
};

/// "prior" | "refine_to_map" | "gravity".
const char* TiltModeName(TiltMode mode);
/// The mode of a TiltModeName; fails naming the three.
Expected<TiltMode> ParseTiltMode(const std::string& name);

/// The `tilt:` section of a settings file (mapper_config_file.hpp).
struct TiltConfig {
  TiltMode mode = TiltMode::kPrior;
  TiltRefinerConfig refiner;  ///< kRefineToMap
  GravityEstimatorConfig gravity;  ///< kGravity
  VerticalCueConfig verticals;     ///< kGravity: which segments are vertical cues
  /// kGravity: sigma of the frame-to-map ground height (the refiner's dz with the tilt
  /// held) given to the estimator [m]; refiner.* sets the ground matching. The window's
  /// frames all measure their height against one map, fused at the earlier frames' tilts:
  /// its error is common to them, not independent from frame to frame, so the sigma is the
  /// scatter of one measurement (0.3 m, the value before) times about the square root of the
  /// window's 12 frames; at 0.3 m the twelve held the height where the first frames, before
  /// the mount or the biases were learned, had put the map. In datasets/maps/REPORT.md (with
  /// its camera at 160 x 120, as it was until 2026-12-05), 1.0 against 0.3 m, ground RMS in
  /// the window: the weaving climb 0.043-0.061 -> 0.035-0.044 m
  /// with the attitude and gyro errors and 0.081 -> 0.055 m with a 2.5 deg mount error
  /// (smoothed: 0.057 -> 0.041 m); the straight climb 0.009-0.033 -> 0.017-0.026 m, the hill
  /// 0.020-0.034 -> 0.023-0.030 m and the side slope 0.007-0.032 -> 0.013-0.024 m; with 1 %
  /// odometry 0.018-0.040 -> 0.024-0.037 m, with 3 % 0.056-0.073 -> 0.055-0.080 m (the hill
  /// 0.060 -> 0.079). A scratch sweep on the weave's mount drives (three seeds), mean ground
  /// RMS: 0.3 m 0.081, 1.0 m 0.056, 3.0 m 0.053 m.
  double gravity_ground_sigma_m = 1.0;
  /// kGravity: the ground height is used once this many vertical cues have been seen (the
  /// tilt anchored by structure, not only by the accelerometer).
  int gravity_ground_min_verticals = 5;
  /// kGravity: each frame's ground against the ground of the frame this many before it (a
  /// GroundRise to the estimator; 0: none), from the frame after the one that fills the
  /// estimator's window; under gravity.window_frames.
  int gravity_rise_frames_back = 2;
  /// kGravity: sigma of a ground rise [m].
  double gravity_rise_sigma_m = 0.05;
  /// kGravity: keep every frame's evidence, so that the run can be smoothed once it is over
  /// (TiltStep::Smooth; offline map building). Its state, and every checkpoint, then grows
  /// with the run: every frame's IMU samples, cues and ground rises.
  bool smooth = false;
  /// With `smooth`: the sigma of the frame-to-map ground height given to the smoother [m]
  /// (tilt.gravity.smooth_ground_sigma_m; 0: left out). It was measured against the map fused
  /// at the window's estimates, and pulls the smoother back to them; without it the smoother
  /// has only the pitch over the distance driven and the ground rises for the height, which
  /// a straight drive or a drifting odometry scale leaves loose. In datasets/maps/REPORT.md
  /// (`smoothed`, with 0.9, against `smoothed_free`), the straight climb's ground RMS is
  /// 0.021-0.027 m with it and 0.044-0.048 m without (0.024-0.038 m in the window; attitude,
  /// gyro and mount errors), and with 3 % odometry 0.048 against 0.158 m (0.056). With the
  /// report's camera at 160 x 120 (until 2026-12-05), where the window's first frames were far
  /// off, the weaving climb with a misaligned mount, its map held them back: 0.029-0.051 m with
  /// it, 0.023-0.039 m without (three drives; at 320 x 240, 0.024 m either way). 0.9 was
  /// chosen over 0.3 and 3 on 13 drives of the same worlds, with the window's
  /// gravity_ground_sigma_m at 0.3 (a scratch sweep, not kept: the mean ground RMS 0.047 m,
  /// against 0.049 and 0.052, and 0.060 without it). Swept again with the window's at 1.0
  /// (22 drives: the weave with three errors and three seeds, the straight climb, the hill
  /// and the side slope with two, each world with 1 % odometry): mean ground RMS 0.0269 m at
  /// 0.5, 0.0268 at 0.9 and 1.5, 0.0271 at 3, 0.0275 without; the worst drive 0.059, 0.071,
  /// 0.079, 0.084 and 0.087 m.
  double smooth_ground_sigma_m = 0.9;
  /// Fails naming the first bad field ("tilt.max_points: ...").
  Status Validate() const;
};

/// What a tilt step sees of one frame (every reference lives for the Estimate() call).
struct TiltFrame {
  std::int64_t index = 0;  ///< frames fused before this one
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_sensor_odometry = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor_prior = Eigen::Isometry3d::Identity();  ///< Prior()
  /// The sensor's nominal mount on the body (Mapper::SetSensorMount; identity unless set).
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
  const std::vector<ImuSample>& imu;  ///< since the previous frame, by stamp
  const od::RangeImage& image;        ///< levelled with the prior's up vector
  const od::Detection& detection;
  const od::Classification& classification;
  /// Valid returns outside every kept segment, sensor frame [m]; empty unless
  /// TiltStep::UsesGroundPoints().
  const std::vector<Eigen::Vector3f>& ground_points_sensor;
};

/// The step's answer for one frame.
struct TiltOutcome {
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< to fuse at
  bool estimated = false;  ///< the step ran an estimator on this frame (not kPrior)
  bool applied = false;    ///< its estimate replaced the prior
  /// The estimator's diagnostics (kRefineToMap: RefineTilt's), when estimated.
  TiltEstimate estimate;
  /// kGravity: the estimator's answer for this frame (covariance, cues, degeneracies).
  std::optional<GravityEstimate> gravity;
  /// Total correction of the fused pose relative to the odometry pose, as carried after this
  /// frame (ApplyTiltCorrection's roll, pitch, dz) [rad, rad, m].
  double roll_rad = 0.0, pitch_rad = 0.0, dz_m = 0.0;
};

/// One frame posed again once the run is over (TiltStep::Smooth).
struct SmoothedFrame {
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< to fuse at
  /// Roll and pitch of the fused pose relative to the odometry pose's, as
  /// TiltOutcome::roll_rad and pitch_rad [rad].
  double roll_rad = 0.0, pitch_rad = 0.0;
  GravityEstimate estimate;  ///< kGravity: the smoother's (no covariance, cues or flags)
};

class TiltStep {
 public:
  virtual ~TiltStep() = default;
  virtual TiltMode mode() const = 0;
  /// Whether Estimate() reads TiltFrame::ground_points_sensor (the Mapper extracts them
  /// only then).
  virtual bool UsesGroundPoints() const = 0;
  /// The pose to level and detect the frame with (see the top of this file).
  virtual Eigen::Isometry3d Prior(const Eigen::Isometry3d& T_world_sensor_odometry) const = 0;
  /// The pose to fuse the frame at. Fails only on an invalid config or a broken frame.
  virtual Expected<TiltOutcome> Estimate(const TiltFrame& frame, const TerrainMap& map) = 0;
  /// What is carried from frame to frame, as bytes, and back (exactly: doubles round-trip).
  virtual std::string SaveState() const = 0;
  virtual Status RestoreState(const std::string& state) = 0;
  /// Once the run is over: every frame Estimate() was given, posed again with the whole
  /// run's evidence, in order (kGravity with TiltConfig::smooth: GravitySmoother, the
  /// odometry's x, y and heading as Estimate() has them). Fails for a step that keeps no
  /// record, or none yet.
  virtual Expected<std::vector<SmoothedFrame>> Smooth();
};

/// The step of `config.mode`. Fails when the config does not validate.
Expected<std::unique_ptr<TiltStep>> MakeTiltStep(const TiltConfig& config);

}  // namespace cairn::map
