// cairn synth: renders a world file into single frames (what `cairn detect` and `cairn eval`
// read) or into a driven sequence (an MRPT rawlog with its ground truth, what `cairn map`
// reads).
//
//   cairn synth --world W.yaml --out DIR                 every view, DIR/view_NN/
//   cairn synth --world W.yaml --out DIR --view N        view N, into DIR
//   cairn synth --world W.yaml --out DIR --drive [--frames N]
//   ... [--sensor camera|lidar] [--exact]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "cairn/sim/drive.hpp"
#include "cairn/sim/mrpt/frame_files.hpp"
#include "cairn/sim/mrpt/sequence.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/util/format.hpp"
#include "progress.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct SynthOptions {
  std::string world;
  std::string out;
  int view = -1;  ///< -1: every view
  bool drive = false;
  int frames = 0;  ///< 0: the whole drive
  std::string sensor = "camera";
  bool exact = false;
  bool raw_imu = false;
};

int SynthFail(const std::string& message) { return CommandFailure("synth", message); }

std::string ViewDirName(int index) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "view_%02d", index);
  return buf;
}

// One view, camera or LiDAR, into `dir`; returns the line that reports it.
Expected<std::string> WriteView(const sim::World& world, int index, bool lidar, bool exact,
                                const fs::path& dir) {
  const sim::Camera camera = sim::ViewCamera(world, index);
  if (!lidar) {
    Expected<sim::DepthFrame> frame = Error{"not rendered"};
    if (exact) {
      sim::RangeCameraSpec spec = world.camera;
      spec.noise = sim::StereoNoise{};
      frame = sim::RenderRangeCamera(world.scene, spec, camera, 0);
    } else {
      frame = sim::RenderView(world, index);
    }
    if (!frame) return frame.error();
    Expected<sim::CameraFrameFiles> files = sim::WriteCameraFrame(dir, *frame, world.scene);
    if (!files) return files.error();
    int valid = 0;
    for (float d : frame->depth_m) valid += d > 0.0f;
    std::ostringstream line;
    line << "view " << index << ": " << frame->width() << "x" << frame->height() << " px, " << valid
         << " returns -> " << files->depth_png.string() << ", "
         << files->intrinsics_yaml.filename().string() << ", "
         << files->truth_png.filename().string() << ", " << files->truth_yaml.filename().string();
    return line.str();
  }
  // The LiDAR at the view's place, looking along the camera's axis (x forward, y left, z up).
  sim::LidarSpec spec = *world.lidar;
  if (exact) spec.range_sigma_m = 0.0;
  Eigen::Isometry3d T_world_lidar = camera.T_world_camera;
  T_world_lidar.linear() = camera.T_world_camera.linear() * sim::RotationOpticalFromFlu();
  Expected<sim::LidarScan> scan =
      sim::RenderLidar(world.scene, spec, T_world_lidar, sim::ViewNoiseSeed(world.seed, index));
  if (!scan) return scan.error();
  const Eigen::Vector3d up = T_world_lidar.linear().transpose() * Eigen::Vector3d::UnitZ();
  Expected<sim::LidarFrameFiles> files = sim::WriteLidarFrame(dir, *scan, spec, up, world.scene);
  if (!files) return files.error();
  std::ostringstream line;
  line << "view " << index << ": " << spec.preset << ", " << scan->points.size() << " points -> "
       << files->points_bin.string() << ", " << files->labels.filename().string() << ", "
       << files->rowcol_bin.filename().string() << ", " << files->lidar_yaml.filename().string()
       << ", " << files->truth_yaml.filename().string();
  return line.str();
}

int RunSynth(const SynthOptions& options) {
  const Clock::time_point start = Clock::now();
  const bool lidar = options.sensor == "lidar";
  if (options.sensor != "camera" && !lidar) {
    return SynthFail("--sensor: unknown sensor '" + options.sensor +
                     "' (expected camera or lidar)");
  }
  Expected<sim::World> loaded = sim::LoadWorld(options.world);
  if (!loaded) return SynthFail(loaded.error().message);
  const sim::World& world = *loaded;
  if (lidar && !world.lidar) {
    return SynthFail(options.world +
                     ": lidar: missing (--sensor lidar needs the world's lidar section)");
  }
  const fs::path out = options.out;

  if (options.drive) {
    if (!world.drive) {
      return SynthFail(options.world +
                       ": drive: missing (--drive needs the world's drive section)");
    }
    sim::SequenceOptions sequence;
    sequence.sensor = lidar ? sim::SensorFrame::kLidar : sim::SensorFrame::kCameraOptical;
    sequence.max_frames = options.frames;
    sequence.noise = !options.exact;
    sequence.raw_imu = options.raw_imu;
    std::optional<Progress> progress;  // a line per tenth of the drive off a terminal
    Expected<sim::SequenceSummary> summary =
        sim::WriteDriveSequence(world, out, sequence, [&](int done, int total) {
          if (!progress) {
            progress.emplace("cairn synth", total, std::max(1, total / 10), 0, "frames", start);
          }
          progress->Update(done);
        });
    if (progress) progress->Finish();
    if (!summary) return SynthFail(options.world + ": " + summary.error().message);
    const double seconds = util::SecondsSince(start);
    std::cout << std::fixed << std::setprecision(1) << "cairn synth: " << world.name
              << ", drive of " << summary->frames << " frames (" << summary->distance_m << " m, "
              << summary->duration_s << " s), " << (lidar ? "lidar" : "camera")
              << (options.exact ? ", exact ranges" : "") << "\n"
              << "  time: " << seconds << " s, " << summary->frames / std::max(seconds, 1e-9)
              << " frames/s\n"
              << "  wrote: " << summary->rawlog.string() << "\n"
              << "         " << summary->poses_body.string() << "\n"
              << "         " << summary->poses_sensor.string() << "\n"
              << "         " << (out / "truth").string() << "/ (per-frame truth)\n"
              << "         " << summary->truth_yaml.string() << "\n"
              << "         " << summary->sequence_yaml.string() << "\n";
    return kExitOk;
  }

  const int views = static_cast<int>(world.views.size());
  if (options.view >= views) {
    return SynthFail(options.world + ": views: no view " + std::to_string(options.view) +
                     " (the world has " + std::to_string(views) + ")");
  }
  std::cout << "cairn synth: " << world.name << ", " << (lidar ? "lidar" : "camera")
            << (options.exact ? ", exact ranges" : "") << "\n";
  for (int index = 0; index < views; ++index) {
    if (options.view >= 0 && index != options.view) continue;
    const fs::path dir = options.view >= 0 ? out : out / ViewDirName(index);
    Expected<std::string> line = WriteView(world, index, lidar, options.exact, dir);
    if (!line) {
      return SynthFail(options.world + ": view " + std::to_string(index) + ": " +
                       line.error().message);
    }
    std::cout << "  " << *line << "\n";
  }
  std::cout << std::fixed << std::setprecision(2) << "  time: " << util::SecondsSince(start)
            << " s\n";
  return kExitOk;
}

}  // namespace

Subcommand AddSynthCommand(CLI::App& parent) {
  auto options = std::make_shared<SynthOptions>();
  CLI::App* app = parent.add_subcommand(
      "synth",
      "Render a synthetic world into frames (depth PNG + intrinsics + truth) or a driven "
      "sequence (MRPT rawlog + true poses + truth)");
  app->add_option("--world", options->world, "world file (datasets/worlds/*.yaml)")
      ->required()
      ->type_name("FILE.yaml");
  app->add_option("--out", options->out, "output directory (created when missing)")
      ->required()
      ->type_name("DIR");
  CLI::Option* view =
      app->add_option("--view", options->view,
                      "render only view N, into DIR (default: every view, into DIR/view_NN)")
          ->check(CLI::NonNegativeNumber)
          ->type_name("N");
  CLI::Option* drive = app->add_flag(
      "--drive", options->drive,
      "drive the world's drive section and write DIR/sequence.rawlog with ground truth");
  view->excludes(drive);
  app->add_option("--frames", options->frames, "with --drive: stop after N frames")
      ->check(CLI::PositiveNumber)
      ->needs(drive)
      ->type_name("N");
  app->add_option("--sensor", options->sensor,
                  "camera (depth images) or lidar (point clouds; needs the world's lidar)")
      ->capture_default_str()
      ->type_name("camera|lidar");
  app->add_flag("--exact", options->exact, "no sensor noise: exact ranges");
  app->add_flag("--raw-imu", options->raw_imu,
                "with --drive: also write the raw accelerometer and gyro samples (100 Hz, "
                "white noise 0.02 m/s^2 and 0.002 rad/s) as CObservationIMU, for "
                "`cairn map --tilt gravity`")
      ->needs(drive);
  return {app, [options] { return RunSynth(*options); }};
}

}  // namespace cairn::apps
