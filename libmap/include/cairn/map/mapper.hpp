// Mapper: the per-frame pipeline of a mapping run, in the manner of kiss-icp's KissICP
// pipeline: one config, one call per frame, the state owned inside, nothing printed.
//
//   Process(image | points, T_world_sensor (odometry), stamp, IMU samples since the last frame)
//     check    a frame with too few valid returns, or whose odometry pose jumps from the
//              previous frame's, is not fused: its record says why (FrameSkip)
//     level    the range image's up vector from the tilt step's prior (tilt_step.hpp)
//     detect   od::Detect + od::Classify (the cone detector and the rules)
//     tilt     the tilt step's estimate: the pose the frame is fused at
//     fuse     TerrainMap::Integrate
//   -> MapperRecord: counts, kept / rejected, the tilt estimate with its diagnostics, the
//      fusion summary, per-stage times.
//
// The Mapper owns the TerrainMap, the tilt step and what it carries from frame to frame, and
// the previous frame's pose (for the jump check). SaveCheckpoint / FromCheckpoint save and
// restore all of it through TerrainMap's checkpoints (checkpoint.hpp): a Mapper restored
// after N frames and fed the rest ends exactly like the one that was never interrupted.
//
// World frame z up; sensor frames as od::RangeImage has them; metres, radians, seconds.
// Not thread-safe (it runs threads of its own: the detector's, and Expect's look-ahead).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cairn/map/imu.hpp"
#include "cairn/map/map_config.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/map/tilt_step.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::map {

/// When a frame is not fused (the `frames:` section of a settings file).
struct FrameCheckConfig {
  /// Fewer valid returns than this (after detector.min_range): skipped, kNoValidPoints.
  int min_valid_points = 1;
  /// The odometry pose moved farther than max_speed_mps * dt, or turned by more than
  /// max_turn_rate_radps * dt, since the previous frame given to Process (dt its stamp
  /// difference, at least 10 ms): skipped, kPoseJump [m/s], [rad/s].
  double max_speed_mps = 50.0;
  double max_turn_rate_radps = 6.283185307179586;  ///< 360 deg/s
  /// Names the first bad field ("frames.max_speed: ..."): min_valid_points >= 1, the
  /// rates > 0 and finite.
  Status Validate() const;
};

/// Everything the Mapper does, stage by stage.
struct MapperConfig {
  od::DetectorConfig detector;  ///< detector.min_range also drops returns from the map
  od::RuleConfig rules;
  MapConfig map;
  TiltConfig tilt;
  FrameCheckConfig frames;
  /// Names the first bad field, prefixed by its section ("detector: ...", "map config: ...").
  Status Validate() const;
};

/// Why a frame was not fused.
enum class FrameSkip {
  kNone,           ///< fused
  kNoValidPoints,  ///< fewer valid returns than frames.min_valid_points
  kPoseJump,       ///< the odometry pose jumped (FrameCheckConfig)
};

/// "none" | "no valid points" | "pose jump".
const char* FrameSkipName(FrameSkip skip);

/// What one Process() call did.
struct MapperRecord {
  std::int64_t index = 0;  ///< frames fused before it (TerrainMap's frame id)
  double stamp_s = 0.0;
  FrameSkip skip = FrameSkip::kNone;
  std::string skip_detail;  ///< the figures behind a skip ("moved 12.3 m in 0.10 s")
  Eigen::Isometry3d T_world_sensor_odometry = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< as fused
  int valid_points = 0;  ///< after detector.min_range
  int segments = 0, kept = 0, rejected = 0;
  TiltOutcome tilt;
  FrameSummary fused;
  /// Per-stage wall time [s].
  double detect_s = 0.0, tilt_s = 0.0, fuse_s = 0.0;

  bool used() const { return skip == FrameSkip::kNone; }
};

/// The settings of the Mapper that fuses a run again at its smoothed poses
/// (Mapper::SmoothTilt): `first`'s, with tilt mode prior (the poses as given), no smoothing
/// and no jump check (the first pass vetted the frames: one it skipped for a jump would
/// otherwise be a jump from the frame before it again).
MapperConfig SmoothedPassConfig(const MapperConfig& first);

class Mapper {
 public:
  /// With the tilt step of config.tilt. Fails when the config does not validate.
  static Expected<Mapper> Create(const MapperConfig& config);
  /// With a tilt step of the caller's (config.tilt is then not used). Fails on a null step.
  static Expected<Mapper> Create(const MapperConfig& config, std::unique_ptr<TiltStep> tilt);

  Mapper(Mapper&&) noexcept;
  Mapper& operator=(Mapper&&) noexcept;
  ~Mapper();

  /// One frame: `image` holds its points in the sensor frame (its up vector is replaced by
  /// the tilt step's prior), `T_world_sensor` is the odometry pose, `imu` the samples since
  /// the previous frame. A frame that fails a check comes back as a record with its skip
  /// reason and changes nothing but the jump check's reference. Fails (changing nothing) on
  /// a non-finite pose or stamp, or when a stage fails.
  Expected<MapperRecord> Process(od::RangeImage image, const Eigen::Isometry3d& T_world_sensor,
                                 double stamp_s, const std::vector<ImuSample>& imu = {});
  /// The same from LiDAR points (sensor frame) and their model; `rows` and `cols` as
  /// od::RangeImage::FromPoints takes them.
  Expected<MapperRecord> Process(const std::vector<Eigen::Vector3f>& points,
                                 const od::SphericalModel& model,
                                 const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                 const std::vector<ImuSample>& imu = {},
                                 const std::vector<std::int32_t>& rows = {},
                                 const std::vector<std::int32_t>& cols = {});

  /// The frame the next Process call after this one will be given (the same image, pose
  /// and stamp), told ahead: the next Process call levels and detects it on a thread of its
  /// own while it fuses its own frame, and Process for that frame takes the result instead
  /// of detecting again. Levelling needs only the tilt step's prior, which this frame's tilt
  /// estimate settles before fusion starts, so the records and the map are those of one
  /// Process call after the other; a frame that turns out otherwise (another pose or stamp)
  /// is detected afresh. Its detect_s is then the wait for that result.
  void Expect(od::RangeImage image, const Eigen::Isometry3d& T_world_sensor, double stamp_s);

  /// Saves the map, the tilt step's state and the jump check's reference to
  /// CheckpointPath(dir_or_file), atomically, with `app_data` (the caller's own resume state)
  /// stored as is.
  Status SaveCheckpoint(const std::filesystem::path& dir_or_file,
                        std::string_view app_data = {}) const;
  /// A Mapper restored from a checkpoint SaveCheckpoint wrote. Fails, naming the file, on
  /// what LoadCheckpoint refuses, and when the checkpoint was made with another tilt mode
  /// than `config.tilt.mode` (or `tilt`'s, when given). `app_data` receives the caller's data.
  static Expected<Mapper> FromCheckpoint(const std::filesystem::path& dir_or_file,
                                         const MapperConfig& config,
                                         std::string* app_data = nullptr,
                                         std::unique_ptr<TiltStep> tilt = nullptr);

  /// The sensor's pose on the body (x forward, y left, z up; the IMU's frame) that the
  /// odometry poses assume: the tilt step needs it to tell the body's attitude from the
  /// sensor's (TiltFrame::T_body_sensor). Identity unless set. Fails on a non-rigid pose.
  Status SetSensorMount(const Eigen::Isometry3d& T_body_sensor);
  const Eigen::Isometry3d& sensor_mount() const;

  const TerrainMap& map() const;
  const MapperConfig& config() const;
  const TiltStep& tilt() const;
  /// Once the run is over: every fused frame posed again by the tilt step's smoother
  /// (TiltStep::Smooth; tilt.mode gravity with tilt.smooth), in order. Fusing the frames
  /// again at these poses (a Mapper of SmoothedPassConfig(), given them as its odometry
  /// poses) builds the map a smoother gives. Fails when the step keeps no record.
  Expected<std::vector<SmoothedFrame>> SmoothTilt();
  std::int64_t frames_processed() const;  ///< Process() calls that succeeded
  std::int64_t frames_fused() const;

 private:
  struct State;
  explicit Mapper(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace cairn::map
