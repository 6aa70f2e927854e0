// cairn detect: one depth frame in, obstacles out (segments.png, classes.png,
// segments.json, overlay.png, segments_color.png).
#include <chrono>
#include <iomanip>
#include <iostream>
#include <memory>
#include <string>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace io = od::io;
using Clock = std::chrono::steady_clock;

struct DetectOptions {
  std::string depth;
  std::string intrinsics;
  std::string config;  ///< empty: built-in defaults
  std::string method = "cone";
  bool no_rules = false;
  std::string out;
};

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

int Fail(const std::string& message) {
  std::cerr << "cairn detect: error: " << message << "\n";
  return kExitFailure;
}

int RunDetect(const DetectOptions& options) {
  const Clock::time_point start = Clock::now();

  Expected<io::CameraIntrinsics> intrinsics = io::LoadIntrinsics(options.intrinsics);
  if (!intrinsics) return Fail(intrinsics.error().message);
  io::DetectSettings settings;
  if (!options.config.empty()) {
    Expected<io::DetectSettings> loaded = io::LoadDetectSettings(options.config);
    if (!loaded) return Fail(loaded.error().message);
    settings = *loaded;
  }
  Expected<io::Grid<float>> depth = io::ReadDepthPng(options.depth, *intrinsics);
  if (!depth) return Fail(depth.error().message);
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(depth->data, intrinsics->model, intrinsics->up);
  if (!image) return Fail(options.depth + ": " + image.error().message);

  const Clock::time_point detect_start = Clock::now();
  Expected<od::Detection> detection = Error{"no method"};
  if (options.method == "column") {
    od::ColumnConfig column = od::ColumnConfig::From(settings.detector);
    column.min_blob_pixels = settings.min_blob_pixels;
    detection = od::DetectColumns(*image, column);
  } else {
    detection = od::Detect(*image, settings.detector);
  }
  if (!detection) return Fail(detection.error().message);
  const double detect_ms = MillisecondsSince(detect_start);

  const Expected<od::Classification> classification =
      options.no_rules ? Expected<od::Classification>(od::KeepAll(*detection))
                       : od::Classify(*detection, settings.rules);
  if (!classification) return Fail(classification.error().message);

  io::RunDescription run;
  run.method = options.method;
  run.rules_applied = !options.no_rules;
  run.settings = settings;
  run.depth_file = options.depth;
  run.intrinsics_file = options.intrinsics;
  run.config_file = options.config;
  Expected<io::DetectionFiles> files =
      io::WriteDetectionFiles(options.out, *depth, *detection, *classification, run);
  if (!files) return Fail(files.error().message);
  const double total_ms = MillisecondsSince(start);

  const od::Detection& d = *detection;
  std::cout << std::fixed << std::setprecision(1) << "cairn detect: " << options.depth << " ("
            << d.width << "x" << d.height << " px, " << image->valid_count() << " valid), method "
            << options.method;
  if (options.method == "cone")
    std::cout << " (" << io::SearchModeName(settings.detector.search) << " search)";
  std::cout << ", rules " << (options.no_rules ? "off" : "on") << "\n"
            << "  segments: " << d.segments.size() << " found, " << classification->kept
            << " kept, " << classification->rejected << " rejected (" << d.stats.obstacle_points
            << " obstacle points, " << d.stats.pairs_compatible << " compatible pairs)\n"
            << "  time: detect " << detect_ms << " ms, total " << total_ms << " ms\n"
            << "  wrote: " << files->segments_png.string() << "\n"
            << "         " << files->classes_png.string() << "\n"
            << "         " << files->segments_json.string() << "\n"
            << "         " << files->overlay_png.string() << "\n"
            << "         " << files->segments_color_png.string() << "\n";
  return kExitOk;
}

}  // namespace

Subcommand AddDetectCommand(CLI::App& parent) {
  auto options = std::make_shared<DetectOptions>();
  CLI::App* app = parent.add_subcommand(
      "detect",
      "Find obstacles in one z-depth frame and write labels, classes, overlays "
      "and per-segment measures");
  app->add_option("--depth", options->depth, "16-bit z-depth PNG (0 = no return)")
      ->required()
      ->type_name("FILE.png");
  app->add_option("--intrinsics", options->intrinsics,
                  "camera YAML: width, height, fx, fy, cx, cy, depth_scale, up or pitch_deg")
      ->required()
      ->type_name("FILE.yaml");
  app->add_option("--config", options->config,
                  "settings YAML (detector, rules, column sections); defaults when absent")
      ->type_name("FILE.yaml");
  app->add_option("--method", options->method,
                  "cone: the cone detector; column: the column-wise baseline")
      ->check(CLI::IsMember({"cone", "column"}))
      ->capture_default_str();
  app->add_flag("--no-rules", options->no_rules, "keep every segment (no rule-based rejection)");
  app->add_option("--out", options->out, "output directory (created when missing)")
      ->required()
      ->type_name("DIR");
  return {app, [options] { return RunDetect(*options); }};
}

}  // namespace cairn::apps
