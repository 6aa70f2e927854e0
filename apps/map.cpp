// cairn map: a whole sequence fused into an OctoMap and a 2.5-D cost grid.
//
//   parse   the settings file (map::LoadMapperSettings) and the command line's overrides
//           (the options: map_command.cpp)
//   load    a FrameSource (cairn/sources/frame_source.hpp): an MRPT rawlog, a KITTI
//           sequence or a folder of depth PNGs with a TUM pose file
//   loop    each frame through the Mapper (cairn/map/mapper.hpp): detect, tilt, fuse; frames
//           that cannot be used are named on stderr and counted (--strict: an error)
//   report  the map files (map_files.hpp), an overlay, per-frame poses and a summary
//           (map_summary.cpp, map_truth.cpp)
//
// Outputs are written into a staging folder inside --out and renamed into place at the end,
// so a failed or interrupted run leaves nothing half-written behind; the Mapper's
// checkpoints (with the run's own state, map_state.cpp) let an interrupted run resume.
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

#include "cairn/map/checkpoint.hpp"
#include "cairn/map/frame_imu.hpp"
#include "cairn/map/map_files.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/util/yaml.hpp"
#include "map_run.hpp"
#include "process_memory.hpp"
#include "progress.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

int MapFail(const std::string& message) { return CommandFailure("map", message); }

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void OnInterrupt(int) { g_interrupted = 1; }

/// Removes what this run created, on failure or interruption.
struct Cleanup {
  fs::path staging;
  fs::path out;
  bool created_out = false;
  bool armed = true;
  ~Cleanup() {
    if (!armed) return;
    std::error_code ec;
    if (!staging.empty()) fs::remove_all(staging, ec);
    if (created_out && fs::is_empty(out, ec)) fs::remove(out, ec);
  }
};

}  // namespace

int RunMap(const MapOptions& options) {
  const Clock::time_point run_start = Clock::now();
  // --- parse ---
  Expected<map::MapperSettings> settings = map::LoadMapperSettings(options.config);
  if (!settings) return MapFail(settings.error().message);
  map::MapperConfig& config = settings->mapper;
  if (options.offline) config.map.window_size_m = 0.0;
  if (options.window_m >= 0.0) config.map.window_size_m = options.window_m;
  if (options.refine_tilt) config.tilt.mode = map::TiltMode::kRefineToMap;
  if (options.no_refine_tilt) config.tilt.mode = map::TiltMode::kPrior;
  if (!options.tilt.empty()) {
    Expected<map::TiltMode> mode = map::ParseTiltMode(options.tilt);
    if (!mode) return MapFail("--tilt: " + mode.error().message);
    config.tilt.mode = *mode;
  }
  if (options.smooth) {
    if (config.tilt.mode != map::TiltMode::kGravity) {
      return MapFail(std::string("--smooth: smooths the gravity tilt's run; the tilt mode is ") +
                     map::TiltModeName(config.tilt.mode) + " (--tilt gravity)");
    }
    config.tilt.smooth = true;
  }
  if (Status s = config.map.Validate(); !s) return MapFail("--window: " + s.message());
  Expected<map::Mapper> created = map::Mapper::Create(config);
  if (!created) return MapFail(created.error().message);
  map::Mapper mapper = std::move(*created);

  // --- load ---
  const Clock::time_point open_start = Clock::now();
  Expected<std::unique_ptr<sources::FrameSource>> opened =
      OpenFrameSource(options, settings->stereo);
  if (!opened) return MapFail(opened.error().message);
  sources::FrameSource& source = **opened;
  StageTimes times;
  times.read_s += SecondsSince(open_start);  // the rawlog's pose pass reads the whole file

  // The output folder and a staging folder inside it.
  Cleanup cleanup;
  cleanup.out = options.out;
  std::error_code ec;
  if (!fs::exists(options.out)) {
    fs::create_directories(options.out, ec);
    if (ec) return MapFail(options.out + ": cannot create: " + ec.message());
    cleanup.created_out = true;
  } else if (!fs::is_directory(options.out)) {
    return MapFail(options.out + ": exists and is not a folder (--out)");
  }
  cleanup.staging = fs::path(options.out) / (".cairn-map-partial-" + std::to_string(getpid()));
  fs::create_directories(cleanup.staging, ec);
  if (ec) return MapFail(cleanup.staging.string() + ": cannot create: " + ec.message());

  // From here an interruption is handled (at the next frame): nothing half-written is left.
  g_interrupted = 0;
  std::signal(SIGINT, OnInterrupt);
  std::signal(SIGTERM, OnInterrupt);

  // Checkpoints: the Mapper and the run's state, every --checkpoint-every frames and when
  // interrupted, in DIR/map.checkpoint (atomically), the per-frame records it counts in
  // DIR/map.checkpoint.records (added to at each); removed once the map files are written.
  Expected<std::string> config_text =
      options.config.empty() ? Expected<std::string>(std::string()) : util::ReadTextFile(options.config);
  if (!config_text) return MapFail(config_text.error().message);
  const fs::path checkpoint = fs::path(options.out) / map::kCheckpointFileName;
  const fs::path records_file = fs::path(options.out) / kRecordsFileName;
  RunState state;
  state.input = SourceJson(source.Describe());
  state.config_text = *config_text;
  state.options =
      RunOptions(options, config.tilt.mode, config.map.window_size_m, config.tilt.smooth);
  double earlier_wall_s = 0.0;
  if (!options.resume && fs::exists(checkpoint)) {
    return MapFail(checkpoint.string() +
                   ": an interrupted run's checkpoint is here: continue it with --resume, or "
                   "remove it and map.checkpoint.records (or choose another --out) to start "
                   "afresh");
  }
  if (options.resume) {
    if (!fs::exists(checkpoint)) {
      return MapFail(checkpoint.string() +
                     ": no checkpoint to resume from (--resume continues a run interrupted with "
                     "the same --out)");
    }
    std::string app_data;
    Expected<map::Mapper> loaded = map::Mapper::FromCheckpoint(checkpoint, config, &app_data);
    if (!loaded) {
      return MapFail(loaded.error().message +
                     " (--resume needs the same input, --config, --tilt and --window)");
    }
    Expected<RunState> saved = ResumeStateFromJson(app_data, checkpoint.string());
    if (!saved) return MapFail(saved.error().message);
    if (Status s = SameRun(*saved, state, checkpoint.string(), options.config); !s) {
      return MapFail(s.message());
    }
    if (Status s = LoadRecords(*saved, records_file); !s) return MapFail(s.message());
    const Clock::time_point skip_start = Clock::now();
    if (Status s = source.Skip(saved->frames_read); !s) return MapFail(s.message());
    const double open_s = times.read_s + SecondsSince(skip_start);
    mapper = std::move(*loaded);
    state = std::move(*saved);
    times = state.times;
    times.read_s += open_s;
    earlier_wall_s = state.wall_s;
    std::cerr << "cairn map: resuming from " << checkpoint.string() << " after "
              << state.frames_read << " frames\n";
  }
  auto save_checkpoint = [&]() -> Status {
    const Clock::time_point t0 = Clock::now();
    state.wall_s = earlier_wall_s + SecondsSince(run_start);
    state.times = times;
    // The records first: the checkpoint counts them, and until it is in place the one before
    // counts fewer (what lies beyond is cut when saved again or resumed).
    if (Status s = SaveRecords(state, records_file); !s) return s;
    Status saved = mapper.SaveCheckpoint(checkpoint, ResumeStateJson(state));
    times.checkpoint_s += SecondsSince(t0);
    return saved;
  };

  // --- loop ---
  const int total =
      options.max_frames > 0 ? std::min(options.max_frames, source.total()) : source.total();
  Progress progress("cairn map", total, options.progress_every, state.frames_read);
  LookaheadFeed feed(source, mapper);  // each frame detected while the one before is fused
  while (options.max_frames <= 0 || state.frames_read < options.max_frames) {
    if (g_interrupted) {
      progress.Finish();
      if (state.frames_read == 0) {
        std::cerr << "cairn map: interrupted before the first frame was fused; nothing written\n";
        return 130;
      }
      if (Status s = save_checkpoint(); !s) return MapFail("interrupted, and " + s.message());
      std::cerr << "cairn map: interrupted after " << state.frames_read << " frames; the map so "
                << "far is in " << checkpoint.string()
                << ": run the same command with --resume to continue\n";
      return 130;
    }
    const Clock::time_point t = Clock::now();
    Expected<std::optional<sources::SequenceFrame>> next =
        feed.Next(options.max_frames > 0 && state.frames_read + 1 >= options.max_frames);
    if (!next) {
      progress.Finish();
      return MapFail(next.error().message);
    }
    if (!*next) break;
    sources::SequenceFrame& frame = **next;
    ++state.frames_read;
    const double read_s = SecondsSince(t);
    times.read_s += read_s;
    std::string reason = frame.used() ? "" : sources::SourceSkipName(frame.skip);
    std::string detail = frame.skip_detail;
    if (frame.used()) {
      if (Status st = mapper.SetSensorMount(frame.T_body_sensor()); !st) {
        return MapFail(frame.name + ": " + st.message());
      }
      Expected<map::MapperRecord> r = mapper.Process(std::move(frame.image), frame.T_world_sensor,
                                                     frame.stamp_s, map::ImuSamplesOf(frame));
      if (!r) return MapFail(frame.name + ": " + r.error().message);
      if (r->used()) {
        const FrameRecord record = RecordOf(frame, *r, read_s);
        times.detect_s += record.detect_s;
        times.refine_s += record.refine_s;
        times.fuse_s += record.fuse_s;
        state.refined_frames += record.refined ? 1 : 0;
        state.records.push_back(record);
      } else {
        reason = map::FrameSkipName(r->skip);
        detail = r->skip_detail;
      }
    }
    if (!reason.empty()) {  // nothing is skipped in silence
      if (options.strict) {
        progress.Finish();
        return MapFail(frame.name + ": " + reason + " (" + detail +
                       "); --strict makes a frame that cannot be used an error");
      }
      progress.Note("skipped " + frame.name + ": " + reason + " (" + detail + ")");
      state.skipped.push_back({frame.name, reason, detail});
    }
    progress.Update(state.frames_read);
    ReleaseFreeMemoryEvery(state.frames_read);  // level memory on long runs
    if (options.checkpoint_every > 0 && state.frames_read % options.checkpoint_every == 0 &&
        state.frames_read < total) {
      if (Status s = save_checkpoint(); !s) return MapFail(s.message());
    }
  }
  progress.Finish();
  if (state.records.empty()) {
    return MapFail("no frames to fuse" +
                   (state.skipped.empty()
                        ? std::string()
                        : " (" + std::to_string(state.skipped.size()) + " skipped)"));
  }

  // --- smooth: the second pass (tilt.smooth) ---
  std::optional<SmoothedRun> smoothed;
  if (config.tilt.smooth) {
    Expected<SmoothedRun> again =
        SmoothedPass(options, *settings, mapper, state, [] { return g_interrupted != 0; });
    if (!again) {
      if (g_interrupted) {
        // The first pass is whole: a resumed run goes straight to the second.
        if (Status s = save_checkpoint(); !s) return MapFail("interrupted, and " + s.message());
        std::cerr << "cairn map: interrupted in the smoothed pass; the first pass is in "
                  << checkpoint.string() << ": run the same command with --resume to smooth it\n";
        return 130;
      }
      return MapFail(again.error().message);
    }
    smoothed.emplace(std::move(*again));
  }
  const map::Mapper& fused = smoothed ? smoothed->mapper : mapper;

  // --- report ---
  const Clock::time_point write_start = Clock::now();
  const fs::path& staging = cleanup.staging;
  if (Status s = map::WriteMapFiles(fused.map(), staging); !s) return MapFail(s.message());
  std::optional<TruthScore> truth;
  if (!options.truth.empty()) {
    Expected<TruthScore> score = ScoreAgainstWorld(options.truth, fused.map());
    if (!score) return MapFail(score.error().message);
    truth = std::move(*score);
  }
  if (Status s = WriteOverlay(staging / "cost.png", staging / "overlay.png", fused.map(),
                              state.records, truth ? &*truth : nullptr);
      !s) {
    return MapFail(s.message());
  }
  std::optional<PoseTruth> poses;
  if (!options.truth_poses.empty()) {
    Expected<PoseTruth> scored = ScorePoses(options.truth_poses, state.records);
    if (!scored) return MapFail(scored.error().message);
    poses = std::move(*scored);
  }
  RunReport report{source, mapper, state, truth, earlier_wall_s + SecondsSince(run_start),
                   write_start};
  report.poses = poses ? &*poses : nullptr;
  report.smoothed = smoothed ? &*smoothed : nullptr;
  Expected<std::string> text = WriteRunFiles(report, staging, times);
  if (!text) return MapFail(text.error().message);

  // Everything is written: move it into place.
  std::vector<fs::path> written;
  for (const fs::directory_entry& e : fs::directory_iterator(staging)) written.push_back(e.path());
  std::sort(written.begin(), written.end());
  for (const fs::path& p : written) {
    fs::rename(p, fs::path(options.out) / p.filename(), ec);
    if (ec) return MapFail((fs::path(options.out) / p.filename()).string() + ": " + ec.message());
  }
  fs::remove(staging, ec);
  fs::remove(checkpoint, ec);  // the map files hold it all now
  fs::remove(records_file, ec);
  cleanup.armed = false;
  std::cout << *text << "  files in " << options.out << ":";
  for (const fs::path& p : written) std::cout << " " << p.filename().string();
  std::cout << "\n";
  return kExitOk;
}

}  // namespace cairn::apps
