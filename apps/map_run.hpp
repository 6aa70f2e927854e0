// `cairn map`, the parts behind map.cpp's RunMap (parse, load, loop, report): what one run
// keeps per fused frame, its resume state beside the Mapper's checkpoint, the scoring
// against a synthetic world, and the files it writes besides the map's own.
#pragma once

#include <Eigen/Geometry>
#include <chrono>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cairn/eval/map_score.hpp"
#include "cairn/eval/pose_score.hpp"
#include "cairn/map/mapper.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/sources/frame_source.hpp"
#include "cairn/util/format.hpp"

namespace cairn::apps {

using Clock = std::chrono::steady_clock;
using util::SecondsSince;

/// The command line.
struct MapOptions {
  // Inputs (one of three).
  std::string rawlog;
  std::string label;  ///< range sensor of the rawlog; empty: every one
  std::string kitti;
  std::string sequence;  ///< NN: DIR/sequences/NN of a KITTI root
  std::string range;     ///< KITTI scans "A:B"
  std::string lidar = "HDL-64E";
  std::string frames;  ///< folder of depth PNGs
  std::string poses;   ///< TUM file for --frames
  std::string intrinsics;
  std::string stereo_calib;  ///< --frames of stereo pairs: the rig (default DIR/stereo.yaml)
  // Settings.
  std::string config;
  std::string out;
  double window_m = -1.0;  ///< < 0: the config's map.window_size
  bool offline = false;
  bool refine_tilt = false;
  bool no_refine_tilt = false;
  std::string tilt;  ///< --tilt MODE ("" = the config's)
  std::string truth_poses;  ///< --truth-poses FILE.tum
  bool strict = false;  ///< a frame that cannot be used is an error
  int max_frames = 0;
  int progress_every = 10;
  std::string truth;  ///< world YAML to score against
  // Crash safety.
  int checkpoint_every = 20;  ///< frames between checkpoints in DIR/map.checkpoint; 0: none
  bool resume = false;        ///< continue from DIR/map.checkpoint
  bool smooth = false;        ///< tilt.smooth: a second pass at the smoother's poses
};

/// `cairn map` with these options (map.cpp): the process's exit status (0, 1 on bad input,
/// 130 when interrupted), the messages on stdout and stderr.
int RunMap(const MapOptions& options);

/// One fused frame, as the outputs use it.
struct FrameRecord {
  int index = 0;
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< as fused
  int valid_points = 0;
  int segments = 0, kept = 0;
  map::FrameSummary fused;
  bool tilt_from_imu = false;  ///< the prior's roll and pitch came from the IMU
  bool refined = false;        ///< tilt refinement ran and its estimate was fused
  double d_roll_rad = 0.0, d_pitch_rad = 0.0, dz_m = 0.0;  ///< total correction fused
  double rms_before_m = 0.0, rms_after_m = 0.0;
  int refine_points = 0;
  /// tilt.mode gravity: the states the estimator could not observe at this frame (their
  /// names, "; "-separated, "" for none) and the vertical cues the frame brought.
  std::string not_observable;
  int verticals = 0;
  /// tilt.mode gravity: the sensor's tilt sigma as the estimator states it, the square root
  /// of the trace of GravityEstimate::up_sensor_covariance [rad]; NaN when not computed, when
  /// the frame was fused at the prior, and after smoothing.
  double tilt_sigma_rad = std::numeric_limits<double>::quiet_NaN();
  double read_s = 0.0, detect_s = 0.0, refine_s = 0.0, fuse_s = 0.0;
  double rss_mb = 0.0;   ///< the process's resident memory once the frame was fused [MiB]
  double heap_mb = 0.0;  ///< of which malloc'd and not freed (ProcessMemory::heap_mb) [MiB]
};

/// A frame that was not fused.
struct SkippedFrame {
  std::string name, reason, detail;
};

struct StageTimes {
  double read_s = 0.0, detect_s = 0.0, refine_s = 0.0, fuse_s = 0.0, write_s = 0.0;
  double checkpoint_s = 0.0;
};

/// Everything of the run besides the Mapper that a resumed run needs to end as the
/// uninterrupted one would, and what identifies the run (its input, its settings file and
/// the options that change the map), so that a checkpoint is never resumed on other data or
/// other settings. Stored as the app data of the Mapper's checkpoint.
struct RunState {
  nlohmann::json input;     ///< SourceJson(source.Describe())
  std::string config_text;  ///< the --config file's bytes ("" for the defaults)
  nlohmann::json options;   ///< RunOptions()
  double wall_s = 0.0;      ///< wall time of the runs before this one [s]
  int frames_read = 0;      ///< frames taken from the source, skipped ones included
  std::vector<FrameRecord> records;
  /// The first records_saved records are in the records file (kRecordsFileName), one JSON
  /// line each, in its first records_bytes bytes: a checkpoint names how many, so that it
  /// does not carry the run's whole list (which grows with the run) each time.
  std::size_t records_saved = 0;
  std::uint64_t records_bytes = 0;
  std::vector<SkippedFrame> skipped;
  int refined_frames = 0;
  StageTimes times;
};

/// Beside DIR/map.checkpoint: the per-frame records the checkpoint counts.
inline constexpr const char* kRecordsFileName = "map.checkpoint.records";

nlohmann::json SourceJson(const sources::SourceInfo& info);
/// The options besides the input and --config that change what is fused.
nlohmann::json RunOptions(const MapOptions& o, map::TiltMode tilt, double window_size_m,
                          bool smooth);
/// The run's state without its records, which SaveRecords keeps: the resume state of a
/// checkpoint; and back (records_saved and records_bytes set, records empty until LoadRecords).
std::string ResumeStateJson(const RunState& state);
Expected<RunState> ResumeStateFromJson(const std::string& text, const std::string& path);
/// Adds the records not yet saved to `file` (after its first records_bytes bytes, cutting what
/// an interrupted save left beyond them; from the start when none are saved), flushed to disk.
Status SaveRecords(RunState& state, const std::filesystem::path& file);
/// Reads the records_saved records a resumed checkpoint counts from `file`.
Status LoadRecords(RunState& state, const std::filesystem::path& file);
/// Checks a checkpoint's run state against this run: the same input, options and settings
/// (`config`: the --config path, empty for the defaults); the error names what differs.
Status SameRun(const RunState& saved, const RunState& now, const std::string& checkpoint,
               const std::string& config);

/// A source's frames for a Mapper, one read ahead: each frame comes with the one after it
/// already read and told to the Mapper (Mapper::Expect), which levels and detects that one
/// while it fuses this one. The frames, skips and errors are the source's, in its order.
class LookaheadFeed {
 public:
  LookaheadFeed(sources::FrameSource& source, map::Mapper& mapper)
      : source_(source), mapper_(mapper) {}
  /// The next frame, or nullopt at the end. `last`: the run stops after it (--max-frames),
  /// so nothing more is read.
  Expected<std::optional<sources::SequenceFrame>> Next(bool last);

 private:
  sources::FrameSource& source_;
  map::Mapper& mapper_;
  std::optional<Expected<std::optional<sources::SequenceFrame>>> ahead_;  // read, not given
};

/// tilt.smooth (--smooth): every frame the first pass fused, posed again by the gravity step's
/// smoother (Mapper::SmoothTilt), and fused again at that pose by a Mapper of
/// map::SmoothedPassConfig, reading the input a second time. Each record takes its frame's
/// new pose, fusion figures and correction (SmoothedFrame's roll and pitch, the sensor's
/// height against the odometry's); the tilt diagnostics (flags, cues) stay the first pass's.
/// Fails, naming the frame, when the input does not give the same frames again, and with
/// "interrupted" once `interrupted()` is true (checked before each frame).
struct SmoothedRun {
  map::Mapper mapper;                  ///< the second pass's: its map is the run's
  double solve_s = 0.0, pass_s = 0.0;  ///< the smoother's and the second pass's wall time
};
Expected<SmoothedRun> SmoothedPass(const MapOptions& options, const map::MapperSettings& settings,
                                   map::Mapper& first, RunState& state,
                                   const std::function<bool()>& interrupted);

/// The frames of the input `o` names (--rawlog, --kitti or --frames), stereo pairs matched
/// with `stereo`, each read while the one before is mapped (sources::ReadAhead).
Expected<std::unique_ptr<sources::FrameSource>> OpenFrameSource(const MapOptions& o,
                                                                const od::StereoConfig& stereo);

/// The record of a fused frame.
FrameRecord RecordOf(const sources::SequenceFrame& frame, const map::MapperRecord& r,
                     double read_s);

// --- scoring against a synthetic world (--truth) ---

/// The map against a synthetic world's truth (--truth).
struct TruthScore {
  std::string world;  ///< the world file
  cairn::eval::MapScore score;
};

/// cairn::eval::ScoreMap against the world file; an obstacle is found with a lethal cell within
/// 0.5 m and a cell of it (some drift). Fails naming the world file.
Expected<TruthScore> ScoreAgainstWorld(const std::string& world_path,
                                       const map::TerrainMap& terrain);

/// The overlay: cost.png enlarged, the live obstacles outlined with their ids, the path
/// driven, and the true objects when scored.
Status WriteOverlay(const std::filesystem::path& cost_png, const std::filesystem::path& path,
                    const map::TerrainMap& terrain, const std::vector<FrameRecord>& records,
                    const TruthScore* truth);

/// poses.tum, frames.csv, summary.json and summary.txt into `dir` (setting times.write_s);
/// returns summary.txt's text.
/// The fused poses against true sensor poses (--truth-poses FILE.tum).
struct PoseTruth : cairn::eval::PoseScore {
  std::string source;  ///< the TUM file
};

/// cairn::eval::ScorePoses of every record's fused T_world_sensor against the TUM file's
/// pose at its stamp. Fails naming the file when it cannot be read or does not span a stamp.
Expected<PoseTruth> ScorePoses(const std::string& tum_path, const std::vector<FrameRecord>& records);

struct RunReport {
  const sources::FrameSource& source;
  const map::Mapper& mapper;
  const RunState& state;
  const std::optional<TruthScore>& truth;
  double wall_s = 0.0;                 ///< of every run of this map [s]
  Clock::time_point write_start = {};  ///< times.write_s runs from here
  const PoseTruth* poses = nullptr;    ///< --truth-poses
  /// --smooth: the second pass, whose map is the run's (`mapper` is the first pass's: its
  /// settings and tilt diagnostics).
  const SmoothedRun* smoothed = nullptr;
};
Expected<std::string> WriteRunFiles(const RunReport& run, const std::filesystem::path& dir,
                                    StageTimes& times);

}  // namespace cairn::apps
