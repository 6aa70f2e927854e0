// cairn map: a whole sequence fused into an OctoMap and a 2.5-D cost grid.
//
//   parse   the command line and the settings file (map::LoadMapperSettings)
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

#include <CLI/CLI.hpp>
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

}  // namespace

Subcommand AddMapCommand(CLI::App& parent) {
  auto options = std::make_shared<MapOptions>();
  CLI::App* app = parent.add_subcommand(
      "map",
      "Fuse a whole sequence into an OctoMap and a 2.5-D cost grid: detect obstacles in every "
      "frame, place it by odometry (or given poses), write the map files and a summary");
  // One input, with the options that go with it.
  CLI::Option_group* input = app->add_option_group(
      "input", "one of --rawlog FILE, --kitti DIR, --frames DIR (with --poses FILE.tum)");
  input->add_option("--rawlog", options->rawlog,
                    "MRPT rawlog with range frames and odometry (IMU used when present)")
      ->type_name("FILE");
  app->add_option("--label", options->label, "with --rawlog: the range sensor's label")
      ->type_name("L");
  input->add_option("--kitti", options->kitti,
                  "KITTI odometry sequence folder (velodyne/, calib.txt, times.txt, poses.txt), "
                  "or the data set's root with --sequence")
      ->type_name("DIR");
  app->add_option("--sequence", options->sequence, "with --kitti: DIR/sequences/NN")
      ->type_name("NN");
  app->add_option("--range", options->range, "with --kitti: scans A:B (inclusive)")
      ->type_name("A:B");
  app->add_option("--lidar", options->lidar,
                  "with --kitti: sensor preset (HDL-64E, VLP-16, VLP-32C, OS1-64; any case)")
      ->capture_default_str();
  CLI::Option* frames =
      input
          ->add_option(
              "--frames", options->frames,
              "folder of 16-bit depth PNGs, or of stereo pairs in left/ and right/ (named by "
              "stamp, or in pose order)")
          ->type_name("DIR");
  input->require_option(1);
  CLI::Option* poses =
      app->add_option("--poses", options->poses,
                      "with --frames: TUM file of the camera's (the left camera's) poses (optical "
                      "frame, z-up world)")
          ->type_name("FILE.tum");
  frames->needs(poses);
  app->add_option("--intrinsics", options->intrinsics,
                  "with --frames: camera YAML (default DIR/intrinsics.yaml)")
      ->type_name("FILE");
  app->add_option("--stereo-calib", options->stereo_calib,
                  "with --frames of stereo pairs (DIR/left/, DIR/right/): the rig's "
                  "calibration, any format of cairn detect --stereo-calib (default "
                  "DIR/stereo.yaml)")
      ->type_name("FILE");
  app->add_option("--config", options->config,
                  "settings YAML: detector, rules, stereo, map, tilt and frames sections "
                  "(config/default.yaml documents them)")
      ->type_name("FILE");
  app->add_option("--out", options->out, "output folder (created when missing)")
      ->required()
      ->type_name("DIR");
  CLI::Option* window =
      app->add_option("--window", options->window_m,
                      "online: a rolling window this wide follows the robot (map.window_size)")
          ->check(CLI::NonNegativeNumber)
          ->type_name("METRES");
  app->add_flag("--offline", options->offline, "unbounded map of the whole sequence")
      ->excludes(window);
  CLI::Option* refine = app->add_flag("--refine-tilt", options->refine_tilt,
                                      "refine each frame's roll, pitch and height with Ceres "
                                      "against the terrain fused so far (tilt.refine)");
  CLI::Option* no_refine =
      app->add_flag("--no-refine-tilt", options->no_refine_tilt, "do not (overrides the config)")
          ->excludes(refine);
  app->add_option("--tilt", options->tilt,
                  "how each frame's roll, pitch and height are found (tilt.mode): prior (the "
                  "odometry pose), refine_to_map (Ceres against the terrain fused so far), "
                  "gravity (Ceres over a window: accelerometer, gyro, trunks, poles and walls)")
      ->check(CLI::IsMember({"prior", "refine_to_map", "gravity"}))
      ->excludes(refine)
      ->excludes(no_refine)
      ->type_name("MODE");
  app->add_flag("--smooth", options->smooth,
                "with --tilt gravity (or tilt.mode gravity): once the input is read, every frame "
                "posed again by the smoother (the whole run solved together: the mount and biases "
                "learned at the first trunks or turn apply from the first frame on) and the map "
                "fused again at those poses, reading the input twice (offline map building; "
                "tilt.smooth in --config)");
  app->add_flag("--strict", options->strict,
                "a frame that cannot be used (missing, truncated, no valid points, a pose that "
                "jumps) is an error, not a frame skipped and counted");
  app->add_option("--max-frames", options->max_frames, "stop after N frames")
      ->check(CLI::PositiveNumber)
      ->type_name("N");
  app->add_option("--checkpoint-every", options->checkpoint_every,
                  "save the map and the run's state to DIR/map.checkpoint every N frames (and "
                  "when interrupted), for --resume; 0: only when interrupted")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app->add_flag("--resume", options->resume,
                "continue an interrupted run from DIR/map.checkpoint (same input, same --config)");
  app->add_option("--progress-every", options->progress_every,
                  "when stderr is not a terminal: a progress line every N frames")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app->add_option("--truth-poses", options->truth_poses,
                  "TUM file of the sensor's true poses (e.g. poses_sensor.tum of `cairn synth "
                  "--drive`): the fused poses' tilt and height errors in the summary")
      ->type_name("FILE.tum");
#ifdef CAIRN_HAVE_SYNTH
  app->add_option("--truth", options->truth,
                  "world YAML of a synthetic sequence: score the obstacles and the elevation")
      ->type_name("WORLD.yaml");
#endif
  app->footer(
      "Writes into DIR: map.bt, map.ot, obstacles.ot (OctoMap), cost.yaml + cost.pgm "
      "(map_server), cost.png, overlay.png, elevation.tiff + elevation.yaml, obstacles.json, "
      "poses.tum, frames.csv, summary.json, summary.txt. Frames that cannot be used are named "
      "on stderr and counted in the summary by reason. Exit 1 on bad input (nothing written; a "
      "checkpoint of an earlier interruption stays), 130 when interrupted (the map so far kept "
      "in DIR/map.checkpoint: run again with --resume).");
  return {app, [options] { return RunMap(*options); }};
}

}  // namespace cairn::apps
