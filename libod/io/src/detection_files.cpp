#include "cairn/od/io/detection_files.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <system_error>

#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"
#include "png.hpp"

namespace cairn::od::io {
namespace {

using Json = nlohmann::ordered_json;

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

/// `where` starts each message: the file being written, or what is being rendered.
Status CheckDetection(const std::string& where, const Detection& detection) {
  if (detection.width <= 0 || detection.height <= 0 ||
      detection.labels.size() != static_cast<std::size_t>(detection.width) * detection.height) {
    return Error{where + ": detection has " + std::to_string(detection.labels.size()) +
                 " labels for a " + SizeText(detection.width, detection.height) + " image"};
  }
  return Status::Ok();
}

Status CheckClassification(const std::string& where, const Detection& detection,
                           const Classification& classification) {
  if (classification.verdicts.size() != detection.segments.size()) {
    return Error{where + ": classification has " + std::to_string(classification.verdicts.size()) +
                 " verdicts for " + std::to_string(detection.segments.size()) + " segments"};
  }
  return Status::Ok();
}

Status CheckDepth(const std::string& where, const Grid<float>& depth, const Detection& detection) {
  if (depth.width != detection.width || depth.height != detection.height ||
      depth.data.size() != detection.labels.size()) {
    return Error{where + ": depth image is " + SizeText(depth.width, depth.height) +
                 ", detection is " + SizeText(detection.width, detection.height)};
  }
  return Status::Ok();
}

Json Vec3(const Eigen::Vector3d& v) { return Json::array({v.x(), v.y(), v.z()}); }

const char* ClassName(SegmentClass cls) {
  switch (cls) {
    case SegmentClass::kKept:
      return "kept";
    case SegmentClass::kRejected:
      return "rejected";
    case SegmentClass::kNone:
      break;
  }
  return "none";
}

Json SettingsJson(const DetectSettings& s) {
  const DetectorConfig& d = s.detector;
  const RuleConfig& r = s.rules;
  Json detector = {{"min_height_m", d.min_height_m},
                   {"max_height_m", d.max_height_m},
                   {"min_slope_deg", d.min_slope_rad * kRadToDeg},
                   {"search", SearchModeName(d.search)},
                   {"window_scale", d.window_scale},
                   {"region_slabs", d.region_slabs},
                   {"threads", d.threads}};
  Json rules = {{"min_points", r.min_points},
                {"min_volume_m3", r.min_volume_m3},
                {"min_perimeter_m", r.min_perimeter_m},
                {"min_slope_mean_deg", r.min_slope_mean_rad * kRadToDeg},
                {"min_slope_max_deg", r.min_slope_max_rad * kRadToDeg},
                {"min_height_mean_m", r.min_height_mean_m},
                {"min_height_max_m", r.min_height_max_m},
                {"min_raised", r.min_raised}};
  Json column = {{"min_blob_pixels", s.min_blob_pixels}};
  return {{"detector", detector}, {"rules", rules}, {"column", column}};
}

Json SegmentJson(const SegmentFeatures& f, const SegmentVerdict& v) {
  return {{"id", f.id},
          {"class", ClassName(v.cls)},
          {"rejection_reason", v.reason},
          {"point_count", f.point_count},
          {"foot_count", f.foot_count},
          {"raised_count", f.raised_count},
          {"bbox_min_m", Vec3(f.bbox_min)},
          {"bbox_max_m", Vec3(f.bbox_max)},
          {"bbox_perimeter_m", f.bbox_perimeter_m},
          {"bbox_volume_m3", f.bbox_volume_m3},
          {"slope_mean_deg", f.slope_mean_rad * kRadToDeg},
          {"slope_max_deg", f.slope_max_rad * kRadToDeg},
          {"ground_height_m", f.ground_height_m},
          {"height_mean_m", f.height_mean_m},
          {"height_max_m", f.height_max_m},
          {"centroid_m", Vec3(f.centroid)},
          {"range_mean_m", f.range_mean_m},
          {"range_min_m", f.range_min_m},
          {"rows_px", Json::array({f.row_min, f.row_max})},
          {"cols_px", Json::array({f.col_min, f.col_max})}};
}

/// Grey colour image of the depth, to draw on.
RgbImage GreyRgb(const Grid<float>& depth) {
  const Grid<std::uint8_t> grey = RenderDepthGrey(depth);
  RgbImage out{grey.width, grey.height, {}};
  out.data.reserve(grey.data.size());
  for (const std::uint8_t g : grey.data) out.data.push_back({g, g, g});
  return out;
}

/// Mostly `rgb`, with a little of the grey underneath so that the shape stays readable.
std::array<std::uint8_t, 3> Tint(const std::array<std::uint8_t, 3>& under,
                                 const std::array<std::uint8_t, 3>& rgb) {
  const auto mix = [](std::uint8_t colour, std::uint8_t below) {
    return static_cast<std::uint8_t>((3 * colour + below + 2) / 4);
  };
  return {mix(rgb[0], under[0]), mix(rgb[1], under[1]), mix(rgb[2], under[2])};
}

/// The BGR matrix OpenCV encodes.
cv::Mat ToBgr(const RgbImage& image) {
  cv::Mat out(image.height, image.width, CV_8UC3);
  for (int r = 0; r < image.height; ++r) {
    auto* row = out.ptr<cv::Vec3b>(r);
    for (int c = 0; c < image.width; ++c) {
      const std::array<std::uint8_t, 3>& rgb = image.at(r, c);
      row[c] = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
    }
  }
  return out;
}

}  // namespace

Grid<std::uint8_t> RenderDepthGrey(const Grid<float>& depth_m) {
  Grid<std::uint8_t> grey;
  grey.width = depth_m.width;
  grey.height = depth_m.height;
  grey.data.assign(depth_m.data.size(), 0);
  float near = std::numeric_limits<float>::infinity();
  float far = 0.0f;
  for (const float d : depth_m.data) {
    if (std::isfinite(d) && d > 0.0f) {
      near = std::min(near, d);
      far = std::max(far, d);
    }
  }
  if (!(far > 0.0f)) return grey;
  // Inverse depth spreads the grey levels where the detail is: near the sensor.
  const double inv_far = 1.0 / far;
  const double span = 1.0 / near - inv_far;
  constexpr double kDarkest = 40.0, kBrightest = 240.0;
  for (std::size_t i = 0; i < depth_m.data.size(); ++i) {
    const float d = depth_m.data[i];
    if (!(std::isfinite(d) && d > 0.0f)) continue;
    const double t = span > 0.0 ? (1.0 / d - inv_far) / span : 1.0;
    grey.data[i] = static_cast<std::uint8_t>(std::lround(kDarkest + t * (kBrightest - kDarkest)));
  }
  return grey;
}

std::array<std::uint8_t, 3> SegmentColor(int id) {
  // Golden-ratio steps around the hue circle: consecutive ids land far apart.
  const double hue = std::fmod(0.13 + id * 0.6180339887498949, 1.0) * 6.0;
  const double saturation = id % 2 == 0 ? 0.95 : 0.7;
  const double value = 1.0;
  const int sector = static_cast<int>(hue) % 6;
  const double f = hue - std::floor(hue);
  const double p = value * (1.0 - saturation);
  const double q = value * (1.0 - saturation * f);
  const double t = value * (1.0 - saturation * (1.0 - f));
  double r = 0, g = 0, b = 0;
  switch (sector) {
    case 0:
      r = value;
      g = t;
      b = p;
      break;
    case 1:
      r = q;
      g = value;
      b = p;
      break;
    case 2:
      r = p;
      g = value;
      b = t;
      break;
    case 3:
      r = p;
      g = q;
      b = value;
      break;
    case 4:
      r = t;
      g = p;
      b = value;
      break;
    default:
      r = value;
      g = p;
      b = q;
      break;
  }
  const auto byte = [](double x) { return static_cast<std::uint8_t>(std::lround(x * 255.0)); };
  return {byte(r), byte(g), byte(b)};
}

Status WriteSegmentsPng(const std::filesystem::path& path, const Detection& detection) {
  if (Status s = CheckDetection(path.string(), detection); !s) return s;
  cv::Mat image(detection.height, detection.width, CV_16UC1);
  for (int r = 0; r < detection.height; ++r) {
    auto* row = image.ptr<std::uint16_t>(r);
    for (int c = 0; c < detection.width; ++c) {
      const std::int32_t id = detection.labels[static_cast<std::size_t>(r) * detection.width + c];
      if (id < 0 || id > 65535) {
        return Error{path.string() + ": segment id " + std::to_string(id) + " at row " +
                     std::to_string(r) + ", col " + std::to_string(c) +
                     " does not fit a 16-bit PNG (0..65535)"};
      }
      row[c] = static_cast<std::uint16_t>(id);
    }
  }
  return util::WriteImageAtomic(path, image);
}

Status WriteClassesPng(const std::filesystem::path& path, const Detection& detection,
                       const Classification& classification) {
  if (Status s = CheckDetection(path.string(), detection); !s) return s;
  if (Status s = CheckClassification(path.string(), detection, classification); !s) return s;
  std::vector<std::uint8_t> classes = ClassImage(detection, classification);
  cv::Mat image(detection.height, detection.width, CV_8UC1, classes.data());
  return util::WriteImageAtomic(path, image);
}

Expected<std::string> SegmentsJsonText(const std::string& where, const Detection& detection,
                                       const Classification& classification,
                                       const RunDescription& run) {
  if (Status s = CheckDetection(where, detection); !s) return s.error();
  if (Status s = CheckClassification(where, detection, classification); !s) return s.error();
  Json segments = Json::array();
  for (std::size_t i = 0; i < detection.segments.size(); ++i) {
    segments.push_back(SegmentJson(detection.segments[i], classification.verdicts[i]));
  }
  Json doc = {
      {"format", "cairn-segments-2"},
      {"image", {{"width", detection.width}, {"height", detection.height}}},
      {"method", run.method},
      {"rules_applied", run.rules_applied},
      {"inputs",
       {{"depth", run.depth_file},
        {"intrinsics", run.intrinsics_file},
        {"config", run.config_file.empty() ? Json(nullptr) : Json(run.config_file)}}},
      {"config", SettingsJson(run.settings)},
      {"coordinates", "level frame: sensor-centred, z up along gravity, x the sensor heading"},
      {"stats",
       {{"obstacle_points", detection.stats.obstacle_points},
        {"pairs_tested", detection.stats.pairs_tested},
        {"pairs_found", detection.stats.pairs_compatible}}},
      {"summary",
       {{"segments", detection.segments.size()},
        {"kept", classification.kept},
        {"rejected", classification.rejected}}},
      {"segments", std::move(segments)}};
  // Non-finite measures are written as null (JSON has no NaN).
  return doc.dump(2) + "\n";
}

Status WriteSegmentsJson(const std::filesystem::path& path, const Detection& detection,
                         const Classification& classification, const RunDescription& run) {
  Expected<std::string> text = SegmentsJsonText(path.string(), detection, classification, run);
  if (!text) return text.error();
  return util::WriteFileAtomic(path, *text);
}

Expected<RgbImage> RenderOverlay(const Grid<float>& depth_m, const Detection& detection,
                                 const Classification& classification) {
  if (Status s = CheckDetection("overlay", detection); !s) return s.error();
  if (Status s = CheckClassification("overlay", detection, classification); !s) return s.error();
  if (Status s = CheckDepth("overlay", depth_m, detection); !s) return s.error();
  const std::vector<std::uint8_t> classes = ClassImage(detection, classification);
  RgbImage image = GreyRgb(depth_m);
  const bool feet_known = detection.foot.size() == detection.labels.size();
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const auto cls = static_cast<SegmentClass>(classes[i]);
    if (cls == SegmentClass::kKept && feet_known && detection.foot[i] != 0) {
      image.data[i] = Tint(image.data[i], {120, 220, 255});  // light blue: a kept one's foot
      continue;
    }
    if (cls == SegmentClass::kKept) image.data[i] = Tint(image.data[i], {0, 40, 255});     // blue
    if (cls == SegmentClass::kRejected) image.data[i] = Tint(image.data[i], {255, 0, 0});  // red
  }
  return image;
}

Expected<RgbImage> RenderSegmentsColor(const Grid<float>& depth_m, const Detection& detection) {
  if (Status s = CheckDetection("segment colours", detection); !s) return s.error();
  if (Status s = CheckDepth("segment colours", depth_m, detection); !s) return s.error();
  RgbImage image = GreyRgb(depth_m);
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const std::int32_t id = detection.labels[i];
    if (id != 0) image.data[i] = Tint(image.data[i], SegmentColor(id));
  }
  return image;
}

Status WriteOverlayPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                       const Detection& detection, const Classification& classification) {
  if (Status s = CheckDetection(path.string(), detection); !s) return s;
  if (Status s = CheckClassification(path.string(), detection, classification); !s) return s;
  if (Status s = CheckDepth(path.string(), depth_m, detection); !s) return s;
  Expected<RgbImage> image = RenderOverlay(depth_m, detection, classification);
  if (!image) return Error{path.string() + ": " + image.error().message};
  return util::WriteImageAtomic(path, ToBgr(*image));
}

Status WriteSegmentsColorPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                             const Detection& detection) {
  if (Status s = CheckDetection(path.string(), detection); !s) return s;
  if (Status s = CheckDepth(path.string(), depth_m, detection); !s) return s;
  Expected<RgbImage> image = RenderSegmentsColor(depth_m, detection);
  if (!image) return Error{path.string() + ": " + image.error().message};
  return util::WriteImageAtomic(path, ToBgr(*image));
}

Expected<DetectionFiles> WriteDetectionFiles(const std::filesystem::path& dir,
                                             const Grid<float>& depth_m, const Detection& detection,
                                             const Classification& classification,
                                             const RunDescription& run) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{dir.string() + ": cannot create the output directory: " + ec.message()};
  if (!std::filesystem::is_directory(dir, ec)) {
    return Error{dir.string() + ": exists and is not a directory"};
  }
  DetectionFiles files{dir / "segments.png", dir / "classes.png", dir / "segments.json",
                       dir / "overlay.png", dir / "segments_color.png"};
  if (Status s = WriteSegmentsPng(files.segments_png, detection); !s) return s.error();
  if (Status s = WriteClassesPng(files.classes_png, detection, classification); !s) {
    return s.error();
  }
  if (Status s = WriteSegmentsJson(files.segments_json, detection, classification, run); !s) {
    return s.error();
  }
  if (Status s = WriteOverlayPng(files.overlay_png, depth_m, detection, classification); !s) {
    return s.error();
  }
  if (Status s = WriteSegmentsColorPng(files.segments_color_png, depth_m, detection); !s) {
    return s.error();
  }
  return files;
}

namespace {

template <typename T>
Grid<T> GridFrom(const cv::Mat& image) {
  Grid<T> grid;
  grid.width = image.cols;
  grid.height = image.rows;
  grid.data.reserve(static_cast<std::size_t>(image.cols) * image.rows);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      if (image.depth() == CV_16U) {
        grid.data.push_back(static_cast<T>(image.at<std::uint16_t>(r, c)));
      } else {
        grid.data.push_back(static_cast<T>(image.at<std::uint8_t>(r, c)));
      }
    }
  }
  return grid;
}

}  // namespace

Expected<Grid<std::int32_t>> ReadSegmentsPng(const std::filesystem::path& path) {
  Expected<cv::Mat> image = detail::ReadPng(path, CV_16UC1, "16-bit single-channel segment-id");
  if (!image) return image.error();
  return GridFrom<std::int32_t>(*image);
}

Expected<Grid<std::uint8_t>> ReadClassesPng(const std::filesystem::path& path) {
  Expected<cv::Mat> image = detail::ReadPng(path, CV_8UC1, "8-bit single-channel class");
  if (!image) return image.error();
  Grid<std::uint8_t> classes = GridFrom<std::uint8_t>(*image);
  for (std::size_t i = 0; i < classes.data.size(); ++i) {
    if (classes.data[i] > 2) {
      return Error{path.string() + ": class " + std::to_string(classes.data[i]) + " at row " +
                   std::to_string(i / classes.width) + ", col " +
                   std::to_string(i % classes.width) + " (expected 0 none, 1 kept, 2 rejected)"};
    }
  }
  return classes;
}

}  // namespace cairn::od::io
