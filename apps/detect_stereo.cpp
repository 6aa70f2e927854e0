// cairn detect --left L --right R --stereo-calib FILE: a stereo pair in, obstacles out.
// Semi-global matching gives the left view's z-depth (holes where the matcher cannot vouch
// for a match), which then goes the depth-image way: RangeImage, detector, rules, the same
// files as --depth, plus the depth (float TIFF, metres), its uncertainty, the disparity and
// the rectified left camera's intrinsics (so the depth can be re-run with --depth).
#include <Eigen/Core>
#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "cairn/od/range_image.hpp"
#include "detect.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace io = od::io;
namespace fs = std::filesystem;

/// Depth quantiles of the valid pixels [m], for the report.
struct DepthSummary {
  int valid = 0;
  double min_m = 0.0, median_m = 0.0, max_m = 0.0;
};

DepthSummary Summarise(const od::Grid<float>& depth_m) {
  std::vector<float> valid;
  for (float z : depth_m.data) {
    if (z > 0.0f) valid.push_back(z);
  }
  DepthSummary s;
  s.valid = static_cast<int>(valid.size());
  if (valid.empty()) return s;
  const auto middle = valid.begin() + static_cast<std::ptrdiff_t>(valid.size() / 2);
  std::nth_element(valid.begin(), middle, valid.end());
  s.median_m = *middle;
  const auto [lo, hi] = std::minmax_element(valid.begin(), valid.end());
  s.min_m = *lo;
  s.max_m = *hi;
  return s;
}

double Percent(int part, std::size_t whole) {
  return whole == 0 ? 0.0 : 100.0 * part / static_cast<double>(whole);
}

}  // namespace

int RunDetectStereo(const DetectOptions& options) {
  const DetectClock::time_point start = DetectClock::now();
  Expected<io::DetectSettings> settings = LoadDetectSettingsOrDefaults(options);
  if (!settings) return DetectFail(settings.error().message);
  Expected<sources::FileFrame> frame = sources::ReadStereoFrame(
      options.left, options.right, options.stereo_calib, settings->stereo,
      options.config.empty() ? "built-in stereo settings" : options.config);
  if (!frame) return DetectFail(frame.error().message);
  const od::RangeImage* image = &frame->image;
  const od::StereoPair* pair = &*frame->pair;
  const od::StereoDepth* stereo = &*frame->stereo;
  const od::PinholeModel& model = frame->model;
  const bool rectified_here = frame->rectified_here;
  const bool up_given = frame->up_given;
  const Eigen::Vector3d up = frame->up;
  const double stereo_ms = 1e3 * frame->matching_s;

  Expected<DetectResult> result = DetectAndClassify(*image, *settings, options);
  if (!result) return DetectFail(result.error().message);
  const od::Detection& d = result->detection;

  io::RunDescription run;
  run.method = options.method;
  run.rules_applied = !options.no_rules;
  run.settings = *settings;
  run.depth_file = options.left + " + " + options.right + " (stereo)";
  run.intrinsics_file = options.stereo_calib;
  run.config_file = options.config;
  Expected<io::DetectionFiles> files =
      io::WriteDetectionFiles(options.out, stereo->depth_m, d, result->classification, run);
  if (!files) return DetectFail(files.error().message);

  const fs::path out(options.out);
  const fs::path depth_path = out / "depth.tiff";
  const fs::path sigma_path = out / "depth_sigma.tiff";
  const fs::path disparity_path = out / "disparity.png";
  const fs::path disparity_color_path = out / "disparity_color.png";
  const fs::path intrinsics_path = out / "intrinsics.yaml";
  if (Status s = io::WriteDepthTiff(depth_path, stereo->depth_m); !s)
    return DetectFail(s.message());
  if (Status s = io::WriteDepthTiff(sigma_path, stereo->sigma_m); !s)
    return DetectFail(s.message());
  const od::Grid<float>& disparity = stereo->disparity.disparity_px;
  if (Status s = io::WriteDisparityPng(disparity_path, disparity); !s) {
    return DetectFail(s.message());
  }
  if (Status s = io::WriteDisparityColorPng(disparity_color_path, disparity,
                                            stereo->disparity.num_disparities);
      !s) {
    return DetectFail(s.message());
  }
  io::CameraIntrinsics intrinsics;
  intrinsics.model = model;
  intrinsics.depth_scale_m = 0.001;  // for a 16-bit PNG; depth.tiff holds metres
  intrinsics.up = up;
  if (Status s = io::WriteIntrinsics(
          intrinsics_path, intrinsics,
          "rectified left camera of " + options.stereo_calib + " (depth.tiff holds metres" +
              (up_given ? ")" : "; up assumed level: the calibration gives none)"));
      !s) {
    return DetectFail(s.message());
  }
  std::vector<fs::path> rectified_paths;
  if (rectified_here) {
    rectified_paths = {out / "left_rectified.png", out / "right_rectified.png"};
    if (Status s = io::WriteGreyPng(rectified_paths[0], pair->left); !s) {
      return DetectFail(s.message());
    }
    if (Status s = io::WriteGreyPng(rectified_paths[1], pair->right); !s) {
      return DetectFail(s.message());
    }
  }
  const double total_ms = MillisecondsSince(start);
  if (stereo->disparity.range_too_short()) {
    std::cerr << "cairn detect: warning: " << std::fixed << std::setprecision(0)
              << 100.0 * stereo->disparity.range_end_fraction
              << "% of the matched pixels lie at the end of the disparity search (0.."
              << stereo->disparity.num_disparities - 1 << " px, depth from "
              << std::setprecision(2)
              << pair->calibration.fx_baseline() / stereo->disparity.num_disparities
              << " m): the scene is likely nearer than the range allows, and those depths "
                 "wrong; lower stereo.min_depth (or raise stereo.num_disparities) in "
              << (options.config.empty() ? std::string("a --config file") : options.config)
              << "\n";
  }

  const std::size_t n = stereo->depth_m.data.size();
  const od::StereoHoleCounts& holes = stereo->disparity.holes;
  const DepthSummary depth = Summarise(stereo->depth_m);
  const od::StereoConfig& sc = settings->stereo;
  std::cout << std::fixed << std::setprecision(1) << "cairn detect: stereo " << options.left
            << " + " << options.right << " (" << model.width << "x" << model.height << " px, fx "
            << model.fx << " px, baseline " << std::setprecision(4) << pair->calibration.baseline_m
            << " m" << (rectified_here ? ", rectified here" : "") << ")\n"
            << std::setprecision(1) << "  stereo: " << od::StereoModeName(sc.mode) << ", block "
            << sc.block_size << " px, disparities 0.." << stereo->disparity.num_disparities - 1
            << " px (depth from " << std::setprecision(2)
            << pair->calibration.fx_baseline() / stereo->disparity.num_disparities << " m)\n"
            << "  depth: " << depth.valid << " valid (" << std::setprecision(1)
            << Percent(depth.valid, n) << "%), " << std::setprecision(2) << depth.min_m << " .. "
            << depth.median_m << " (median) .. " << depth.max_m << " m\n"
            << std::setprecision(1) << "  holes: " << holes.total() << " ("
            << Percent(holes.total(), n) << "%): " << holes.no_match << " no match, "
            << holes.low_texture << " low texture, " << holes.out_of_range << " out of range\n"
            << "  at the end of the search range: " << std::setprecision(1)
            << 100.0 * stereo->disparity.range_end_fraction << "% of the matched pixels\n"
            << "  up: "
            << (up_given ? "from the calibration" : "not in the calibration, camera assumed level")
            << "\n"
            << "  method " << options.method;
  if (options.method == "cone") {
    std::cout << " (" << io::SearchModeName(settings->detector.search) << " search)";
  }
  std::cout << ", rules " << (options.no_rules ? "off" : "on") << "\n"
            << "  segments: " << d.segments.size() << " found, " << result->classification.kept
            << " kept, " << result->classification.rejected << " rejected ("
            << d.stats.obstacle_points << " obstacle points)\n"
            << "  time: stereo " << stereo_ms << " ms, detect " << result->detect_ms
            << " ms, total " << total_ms << " ms\n"
            << "  wrote: " << depth_path.string() << " (z-depth [m], 0 = hole)\n"
            << "         " << sigma_path.string() << " (depth sigma [m])\n"
            << "         " << disparity_path.string() << " (disparity * 256, 0 = hole)\n"
            << "         " << disparity_color_path.string() << "\n"
            << "         " << intrinsics_path.string() << "\n";
  for (const fs::path& p : rectified_paths) std::cout << "         " << p.string() << "\n";
  std::cout << "         " << files->segments_png.string() << "\n"
            << "         " << files->classes_png.string() << "\n"
            << "         " << files->segments_json.string() << "\n"
            << "         " << files->overlay_png.string() << "\n"
            << "         " << files->segments_color_png.string() << "\n";
  return kExitOk;
}

}  // namespace cairn::apps
