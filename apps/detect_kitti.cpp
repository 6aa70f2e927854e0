// cairn detect --kitti DIR: every scan of a KITTI odometry sequence (or --frames A:B of
// it) through the single-scan path, one output folder per frame (labels.label,
// birds_eye.png, segments.png, classes.png, segments.json, overlay.png,
// segments_color.png), and summary.csv over the frames with their poses. Progress goes to
// stderr, one line per frame; a frame that fails is reported and the others still run.
#include <Eigen/Core>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/util/atomic_file.hpp"
#include "cairn/od/io/kitti.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "detect.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace io = od::io;

// One line of summary.csv.
struct FrameSummary {
  const io::KittiFrame* frame = nullptr;
  std::size_t points = 0;
  int rings = 0, columns = 0;
  std::string ring_source;
  std::size_t segments = 0;
  int kept = 0, rejected = 0;
  std::size_t kept_points = 0;  // input points labelled as kept obstacles
  double detect_ms = 0.0, total_ms = 0.0;
  std::string error;  // empty when the frame went through
};

std::string FrameName(int index) {
  std::ostringstream name;
  name << std::setw(6) << std::setfill('0') << index;
  return name.str();
}

std::string SummaryCsv(const std::vector<FrameSummary>& rows) {
  std::ostringstream csv;
  csv << "frame,stamp_s,points,rings,columns,ring_source,segments,kept,rejected,kept_points,"
         "detect_ms,total_ms,map_x_m,map_y_m,map_z_m,error\n";
  csv << std::fixed;
  for (const FrameSummary& r : rows) {
    csv << r.frame->index << "," << std::setprecision(6) << r.frame->stamp_s << "," << r.points
        << "," << r.rings << "," << r.columns << "," << r.ring_source << "," << r.segments << ","
        << r.kept << "," << r.rejected << "," << r.kept_points << "," << std::setprecision(1)
        << r.detect_ms << "," << r.total_ms << ",";
    if (r.frame->T_map_velodyne) {
      const Eigen::Vector3d t = r.frame->T_map_velodyne->translation();
      csv << std::setprecision(4) << t.x() << "," << t.y() << "," << t.z();
    } else {
      csv << ",,";
    }
    std::string error = r.error;
    for (char& ch : error) {
      if (ch == ',' || ch == '\n') ch = ';';
    }
    csv << "," << error << "\n";
  }
  return csv.str();
}

// The single-scan path on one frame; fills `row`, returns an error message or "".
std::string DetectFrame(const io::KittiFrame& frame, const io::DetectSettings& settings,
                        const od::LayoutOptions& layout_options, const Eigen::Vector3d& up,
                        const DetectOptions& options, FrameSummary& row) {
  const DetectClock::time_point start = DetectClock::now();
  Expected<od::PointCloud> cloud = io::ReadKittiBin(frame.scan);
  if (!cloud) return cloud.error().message;
  row.points = cloud->points.size();
  Expected<od::FoundLayout> layout = od::FindLayout(*cloud, layout_options, frame.scan.string());
  if (!layout) return layout.error().message;
  Expected<od::RangeImage> image =
      od::RangeImage::FromPoints(cloud->points, layout->model, up, layout->rows, layout->cols);
  if (!image) return frame.scan.string() + ": " + image.error().message;
  row.rings = image->height();
  row.columns = image->width();
  row.ring_source = od::RingSourceName(layout->source);
  Expected<DetectResult> result = DetectAndClassify(*image, settings, options);
  if (!result) return result.error().message;
  row.detect_ms = result->detect_ms;
  row.segments = result->detection.segments.size();
  row.kept = result->classification.kept;
  row.rejected = result->classification.rejected;

  io::RunDescription run;
  run.method = options.method;
  run.rules_applied = !options.no_rules;
  run.settings = settings;
  run.depth_file = frame.scan.string();
  std::ostringstream described;
  described << "KITTI frame " << frame.index << " at " << std::fixed << std::setprecision(6)
            << frame.stamp_s << " s, "
            << (options.sensor.empty() ? "rings from the data" : "sensor " + options.sensor) << ", "
            << row.rings << " rings (" << row.ring_source << ") x " << row.columns;
  run.intrinsics_file = described.str();
  run.config_file = options.config;
  const std::filesystem::path dir = std::filesystem::path(options.out) / FrameName(frame.index);
  Expected<io::ScanOutputs> files = io::WriteScanOutputs(
      dir, *image, cloud->points, result->detection, result->classification, run);
  if (!files) return files.error().message;
  for (std::uint32_t label : files->point_labels) {
    row.kept_points += (label & 0xFFFFu) == static_cast<std::uint32_t>(od::SegmentClass::kKept);
  }
  row.total_ms = MillisecondsSince(start);
  return "";
}

}  // namespace

int RunDetectKitti(const DetectOptions& options) {
  const DetectClock::time_point start = DetectClock::now();
  Expected<io::DetectSettings> settings = LoadDetectSettingsOrDefaults(options);
  if (!settings) return DetectFail(settings.error().message);
  Expected<Eigen::Vector3d> up = ParseUpVector(options.up);
  if (!up) return DetectFail(up.error().message);
  od::LayoutOptions layout_options;
  layout_options.columns = options.columns;
  layout_options.organised = options.organised == "yes"  ? od::OrganisedMode::kYes
                             : options.organised == "no" ? od::OrganisedMode::kNo
                                                         : od::OrganisedMode::kAuto;
  if (!options.sensor.empty()) {
    Expected<od::SphericalModel> preset =
        od::SphericalModel::Preset(options.sensor, options.columns);
    if (!preset) return DetectFail("--sensor: " + preset.error().message);
    layout_options.preset = *preset;
  }
  Expected<io::KittiSequence> sequence = io::OpenKittiSequence(options.kitti);
  if (!sequence) return DetectFail(sequence.error().message);
  std::vector<io::KittiFrame> frames = sequence->frames;
  if (!options.frames.empty()) {
    Expected<std::vector<io::KittiFrame>> selected =
        io::SelectKittiFrames(*sequence, options.frames);
    if (!selected) return DetectFail(selected.error().message);
    frames = std::move(*selected);
  }
  std::error_code ec;
  std::filesystem::create_directories(options.out, ec);
  if (ec) return DetectFail(options.out + ": cannot create the output folder: " + ec.message());

  std::vector<FrameSummary> rows(frames.size());
  int failed = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    FrameSummary& row = rows[k];
    row.frame = &frames[k];
    row.error = DetectFrame(frames[k], *settings, layout_options, *up, options, row);
    std::cerr << std::fixed << std::setprecision(0) << "cairn detect: frame "
              << FrameName(frames[k].index) << " (" << k + 1 << "/" << frames.size() << "): ";
    if (!row.error.empty()) {
      ++failed;
      std::cerr << "error: " << row.error << "\n";
      continue;
    }
    std::cerr << row.points << " points, " << row.rings << " rings (" << row.ring_source << ") x "
              << row.columns << ", " << row.segments << " segments (" << row.kept
              << " kept), detect " << row.detect_ms << " ms, total " << row.total_ms << " ms\n";
  }
  const std::filesystem::path summary = std::filesystem::path(options.out) / "summary.csv";
  if (Status s = util::WriteFileAtomic(summary, SummaryCsv(rows)); !s) return DetectFail(s.message());

  double detect_sum = 0.0, total_sum = 0.0;
  for (const FrameSummary& r : rows) {
    if (!r.error.empty()) continue;
    detect_sum += r.detect_ms;
    total_sum += r.total_ms;
  }
  const std::size_t done = frames.size() - static_cast<std::size_t>(failed);
  std::cout << std::fixed << std::setprecision(1) << "cairn detect: " << options.kitti << " ("
            << sequence->frames.size() << " scans, " << (sequence->has_poses ? "with" : "no")
            << " poses): " << done << " of " << frames.size() << " frames, method "
            << options.method << ", rules " << (options.no_rules ? "off" : "on") << "\n";
  if (done > 0) {
    std::cout << "  time per frame: detect " << detect_sum / done << " ms, total "
              << total_sum / done << " ms (all " << MillisecondsSince(start) << " ms)\n";
  }
  std::cout << "  wrote: " << summary.string() << " and one folder per frame in " << options.out
            << "\n";
  if (failed > 0) {
    return DetectFail(std::to_string(failed) + " of " + std::to_string(frames.size()) +
                      " frames failed (see above and summary.csv)");
  }
  return kExitOk;
}

}  // namespace cairn::apps
