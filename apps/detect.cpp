// cairn detect: one depth frame or one LiDAR scan in, obstacles out (segments.png,
// classes.png, segments.json, overlay.png, segments_color.png; for a scan also labels.label,
// one SemanticKITTI-layout entry per input point, and birds_eye.png).
#include "detect.hpp"

#include <Eigen/Core>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "cairn/map/mapper_config_file.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/detect_run.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "subcommands.hpp"

namespace cairn::apps {

double MillisecondsSince(DetectClock::time_point start) {
  return std::chrono::duration<double, std::milli>(DetectClock::now() - start).count();
}

int DetectFail(const std::string& message) { return CommandFailure("detect", message); }

Expected<od::io::DetectSettings> LoadDetectSettingsFile(const std::string& path) {
  // One settings file configures every stage; the Mapper's sections are read by its loader.
  return od::io::LoadDetectSettings(path, map::MapperSettingsSections());
}

Expected<od::io::DetectSettings> LoadDetectSettingsOrDefaults(const DetectOptions& options) {
  if (options.config.empty()) return od::io::DetectSettings{};
  return LoadDetectSettingsFile(options.config);
}

Expected<DetectResult> DetectAndClassify(const od::RangeImage& image,
                                         const od::io::DetectSettings& settings,
                                         const DetectOptions& options) {
  od::io::DetectRunOptions run_options;
  run_options.method =
      options.method == "column" ? od::io::DetectMethod::kColumn : od::io::DetectMethod::kCone;
  run_options.apply_rules = !options.no_rules;
  run_options.keep_feet = !options.no_feet;
  Expected<od::io::DetectRun> run = od::io::DetectAndClassify(image, settings, run_options);
  if (!run) return run.error();
  DetectResult result;
  result.detect_ms = run->detect_s * 1000.0;
  result.detection = std::move(run->detection);
  result.classification = std::move(run->classification);
  return result;
}

Expected<Eigen::Vector3d> ParseUpVector(const std::string& text) {
  std::istringstream in(text);
  Eigen::Vector3d up;
  char comma1 = 0, comma2 = 0;
  in >> up.x() >> comma1 >> up.y() >> comma2 >> up.z();
  if (!in || comma1 != ',' || comma2 != ',' || !(in >> std::ws).eof() || !up.allFinite() ||
      up.norm() == 0.0) {
    return Error{"--up: expected three numbers x,y,z, not all zero, got '" + text + "'"};
  }
  return up;
}

namespace {

namespace io = od::io;
using Clock = DetectClock;
using Options = DetectOptions;

}  // namespace

Expected<od::LayoutOptions> ScanLayoutOptions(const DetectOptions& options) {
  od::LayoutOptions layout_options;
  layout_options.columns = options.columns;
  layout_options.organised = options.organised == "yes"  ? od::OrganisedMode::kYes
                             : options.organised == "no" ? od::OrganisedMode::kNo
                                                         : od::OrganisedMode::kAuto;
  if (!options.sensor.empty()) {
    Expected<od::SphericalModel> preset =
        od::SphericalModel::Preset(options.sensor, options.columns);
    if (!preset) return Error{"--sensor: " + preset.error().message};
    layout_options.preset = *preset;
  }
  return layout_options;
}

Expected<sources::FileFrame> ReadScanInput(const DetectOptions& options) {
  Expected<Eigen::Vector3d> up = ParseUpVector(options.up);
  if (!up) return up.error();
  Expected<od::LayoutOptions> layout = ScanLayoutOptions(options);
  if (!layout) return layout.error();
  return sources::ReadScanFrame(options.points, *layout, *up);
}

Expected<sources::FileFrame> ReadDepthInput(const DetectOptions& options) {
  return sources::ReadDepthFrame(options.depth, options.intrinsics);
}

namespace {

int RunDetectPoints(const DetectOptions& options) {
  const Clock::time_point start = Clock::now();
  Expected<io::DetectSettings> settings = LoadDetectSettingsOrDefaults(options);
  if (!settings) return DetectFail(settings.error().message);
  Expected<sources::FileFrame> scan = ReadScanInput(options);
  if (!scan) return DetectFail(scan.error().message);
  const od::PointCloud* cloud = &scan->cloud;
  const od::FoundLayout* layout = &scan->layout;
  const od::RangeImage* image = &scan->image;

  Expected<DetectResult> result = DetectAndClassify(*image, *settings, options);
  if (!result) return DetectFail(result.error().message);
  const od::Detection& d = result->detection;

  const std::string rings = std::to_string(image->height()) + " rings (" +
                            od::RingSourceName(layout->source) + ") x " +
                            std::to_string(image->width()) + " columns";
  io::RunDescription run;
  run.method = options.method;
  run.rules_applied = !options.no_rules;
  run.settings = *settings;
  run.depth_file = options.points;
  run.intrinsics_file =
      (options.sensor.empty() ? "rings from the data" : "sensor " + options.sensor) + ", " + rings;
  run.config_file = options.config;
  Expected<io::ScanOutputs> files =
      io::WriteScanOutputs(options.out, *image, cloud->points, d, result->classification, run);
  if (!files) return DetectFail(files.error().message);
  const double total_ms = MillisecondsSince(start);

  if (!layout->note.empty()) std::cerr << "cairn detect: note: " << layout->note << "\n";
  std::cout << std::fixed << std::setprecision(1) << "cairn detect: " << options.points << " ("
            << cloud->points.size() << " points, "
            << (options.sensor.empty() ? "no preset" : options.sensor) << ", " << rings << ", "
            << image->valid_count() << " valid cells), method " << options.method;
  if (options.method == "cone")
    std::cout << " (" << io::SearchModeName(settings->detector.search) << " search)";
  std::cout << ", rules " << (options.no_rules ? "off" : "on") << "\n"
            << "  segments: " << d.segments.size() << " found, " << result->classification.kept
            << " kept, " << result->classification.rejected << " rejected ("
            << d.stats.obstacle_points << " obstacle cells)\n"
            << "  time: detect " << result->detect_ms << " ms, total " << total_ms << " ms\n"
            << "  wrote: " << files->labels.string() << "\n"
            << "         " << files->birds_eye.string()
            << " (5 m per 100 px, sensor at the centre)\n"
            << "         " << files->images.segments_png.string() << "\n"
            << "         " << files->images.classes_png.string() << "\n"
            << "         " << files->images.segments_json.string() << "\n"
            << "         " << files->images.overlay_png.string() << "\n"
            << "         " << files->images.segments_color_png.string() << "\n";
  return kExitOk;
}

int RunDetect(const DetectOptions& options) {
  if (options.points.empty() && options.kitti.empty() &&
      (!options.sensor.empty() || options.organised != "auto" || options.columns != 0 ||
       options.up != "0,0,1")) {
    return DetectFail("--sensor, --organised, --columns and --up go with --points or --kitti");
  }
  if (!options.points.empty()) return RunDetectPoints(options);
#ifdef CAIRN_HAVE_SOURCES
  if (!options.rawlog.empty()) return RunDetectRawlog(options);
#endif
#ifdef CAIRN_HAVE_STEREO
  if (!options.left.empty()) return RunDetectStereo(options);
#endif
#ifdef CAIRN_HAVE_KITTI
  if (!options.kitti.empty()) return RunDetectKitti(options);
#endif
  if (options.depth.empty() || options.intrinsics.empty()) {
    return DetectFail(
        "give --depth FILE.png with --intrinsics FILE.yaml, or --points FILE "
        "(with --sensor PRESET or rings found from the data)");
  }
  const Clock::time_point start = Clock::now();

  Expected<io::DetectSettings> loaded_settings = LoadDetectSettingsOrDefaults(options);
  if (!loaded_settings) return DetectFail(loaded_settings.error().message);
  const io::DetectSettings settings = *loaded_settings;
  Expected<sources::FileFrame> loaded = ReadDepthInput(options);
  if (!loaded) return DetectFail(loaded.error().message);
  const od::Grid<float>* depth = &loaded->depth_m;
  const od::RangeImage* image = &loaded->image;

  Expected<DetectResult> result = DetectAndClassify(*image, settings, options);
  if (!result) return DetectFail(result.error().message);
  const double detect_ms = result->detect_ms;
  const od::Detection* detection = &result->detection;
  const od::Classification* classification = &result->classification;

  io::RunDescription run;
  run.method = options.method;
  run.rules_applied = !options.no_rules;
  run.settings = settings;
  run.depth_file = options.depth;
  run.intrinsics_file = options.intrinsics;
  run.config_file = options.config;
  Expected<io::DetectionFiles> files =
      io::WriteDetectionFiles(options.out, *depth, *detection, *classification, run);
  if (!files) return DetectFail(files.error().message);
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
            << " obstacle points)\n"
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
      "Find obstacles in one z-depth frame or LiDAR scan and write labels, classes, overlays "
      "and per-segment measures");
  CLI::Option* depth =
      app->add_option("--depth", options->depth,
                      "z-depth: 16-bit PNG (value * depth_scale) or 32-bit float TIFF "
                      "(metres); 0 = no return")
          ->type_name("FILE");
  CLI::Option* intrinsics =
      app->add_option("--intrinsics", options->intrinsics,
                      "camera YAML: width, height, fx, fy, cx, cy, depth_scale, up or pitch_deg")
          ->type_name("FILE.yaml");
  depth->needs(intrinsics);
  intrinsics->needs(depth);
  CLI::Option* points =
      app->add_option("--points", options->points,
                      "LiDAR scan (instead of --depth): KITTI .bin (float32 x, y, z, intensity "
                      "per point), PLY (x, y, z, optional intensity and ring), or text "
                      "\"x y z [intensity]\" per line (.txt .xyz .dat .pts .asc .csv, optionally "
                      ".bz2)")
          ->type_name("FILE")
          ->excludes(depth);
  app->add_option("--sensor", options->sensor,
                  "sensor preset of the scan (or of every scan of --kitti); default: rings "
                  "found from the data (ring field, organised order, ring breaks, elevation "
                  "clusters, else uniform elevation bins)")
      ->transform(CLI::IsMember(SensorPresets(), CLI::ignore_case))
      ->type_name("PRESET");
  app->add_option("--organised", options->organised,
                  "auto: organised (index = col * rings + ring, Ouster) when the data says so; "
                  "yes / no to force")
      ->check(CLI::IsMember({"auto", "yes", "no"}))
      ->capture_default_str();
  app->add_option("--columns", options->columns,
                  "azimuth steps of a scan that is not organised (default: the preset's, 1800 "
                  "for VLP-16/VLP-32C and 2048 otherwise, or measured on the data)")
      ->check(CLI::PositiveNumber);
  app->add_option("--up", options->up, "gravity's up vector in the LiDAR frame, x,y,z")
      ->capture_default_str()
      ->type_name("X,Y,Z");
#ifdef CAIRN_HAVE_SOURCES
  CLI::Option* rawlog =
      app->add_option("--rawlog", options->rawlog,
                      "MRPT rawlog (observations or sensory-frame format): every range "
                      "observation of --label is detected, one output folder per frame")
          ->type_name("FILE.rawlog")
          ->excludes(depth)
          ->excludes(points);
  app->add_option("--label", options->label,
                  "sensor label to take from the rawlog (default: every range sensor)")
      ->needs(rawlog);
  app->add_option("--annotated", options->annotated,
                  "write a copy of the rawlog whose range observations carry their obstacle "
                  "segments as MRPT pixel labels")
      ->type_name("FILE.rawlog")
      ->needs(rawlog);
  app->add_option("--max-frames", options->max_frames, "stop after this many range frames")
      ->check(CLI::PositiveNumber)
      ->needs(rawlog);
#endif
#ifdef CAIRN_HAVE_STEREO
  CLI::Option* left = app->add_option("--left", options->left, "rectified left image")
                          ->type_name("FILE.png")
                          ->excludes(depth)
                          ->excludes(points);
  CLI::Option* right =
      app->add_option("--right", options->right, "rectified right image")->type_name("FILE.png");
  CLI::Option* stereo_calib =
      app->add_option("--stereo-calib", options->stereo_calib,
                      "stereo calibration: YAML with fx, cx, cy, baseline (and up or "
                      "pitch_deg), or an OpenCV stereo calibration (M1, D1, M2, D2, R, T)")
          ->type_name("FILE");
  left->needs(right)->needs(stereo_calib);
  right->needs(left);
  stereo_calib->needs(left);
#endif
#ifdef CAIRN_HAVE_KITTI
  CLI::Option* kitti =
      app->add_option("--kitti", options->kitti,
                      "KITTI odometry sequence folder (velodyne/*.bin, calib.txt, poses.txt, "
                      "times.txt): every scan, one output folder per frame")
          ->type_name("DIR")
          ->excludes(depth)
          ->excludes(points);
  app->add_option("--frames", options->frames, "frames A:B of the sequence (inclusive)")
      ->type_name("A:B")
      ->needs(kitti);
#endif
  app->add_option("--config", options->config,
                  "settings YAML (detector, rules, column sections); defaults when absent")
      ->type_name("FILE.yaml");
  app->add_option("--method", options->method,
                  "cone: the cone detector; column: the column-wise baseline")
      ->check(CLI::IsMember({"cone", "column"}))
      ->capture_default_str();
  app->add_flag("--no-rules", options->no_rules, "keep every segment (no rule-based rejection)");
  app->add_flag("--no-feet", options->no_feet,
                "count each obstacle's foot as ground: points that are only ever the lower point "
                "of their pairs (the terrain at its base and its lowest HT), which the paper's "
                "definition joins to it; the overlay shows them light blue otherwise");
  app->add_option("--out", options->out, "output directory (created when missing)")
      ->required()
      ->type_name("DIR");
  return {app, [options] { return RunDetect(*options); }};
}

}  // namespace cairn::apps
