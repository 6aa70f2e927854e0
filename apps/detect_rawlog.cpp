// cairn detect --rawlog FILE: every range observation of an MRPT rawlog (3-D range scans,
// Velodyne and rotating scans, point clouds, stereo pairs), optionally of one sensor label,
// detected frame by frame.
//
// Per frame, DIR/NNNNNN_<label>/ (NNNNNN the frame's number among the range frames read)
// holds what the single-frame inputs write: segments.png, classes.png, segments.json,
// overlay.png, segments_color.png; LiDAR frames add labels.label (one SemanticKITTI word per
// decoded point, in decode order) and birds_eye.png; stereo frames add depth.tiff. DIR/
// summary.json describes the run and every frame. With --annotated, a copy of the rawlog
// whose range observations carry their segments (cairn/sources/annotate.hpp), written to a
// temporary file and renamed when the whole file has been copied.
//
// Gravity: the up vector of each frame comes from its sensor's pose on the body
// (T_body_sensor, from the observation's sensorPose / cameraPose), with the body taken as
// level, unless an IMU observation read before the frame gives roll and pitch, which then
// tilt the body (sources::UpInSensor). Odometry does not tilt it: a planar odometry knows no
// tilt, and a 6-D one drifts.
#include <mrpt/obs/CSensoryFrame.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/sources/annotate.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "cairn/util/atomic_file.hpp"
#include "detect.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
namespace io = od::io;
using nlohmann::json;

// A label as a folder-name part: letters, digits, '-', '_', '.'; anything else '_'.
std::string FolderLabel(const std::string& label) {
  if (label.empty()) return "nolabel";
  std::string out = label;
  for (char& ch : out) {
    const bool ok = std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.';
    if (!ok) ch = '_';
  }
  return out;
}

json Vector(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

json Stamp(double stamp_s) { return std::isfinite(stamp_s) ? json(stamp_s) : json(nullptr); }

// What one frame gave, for the summary and the annotated copy.
struct FrameResult {
  json record;
  int found = 0, kept = 0, rejected = 0;
};

// The range image of a frame and what to render it with; stereo frames are matched first.
struct Prepared {
  od::RangeImage image;
  od::Grid<float> render;  ///< depth (cameras) or range (LiDAR) for the images [m]
  std::optional<od::StereoDepth> stereo;
  double stereo_ms = 0.0;
};

Expected<Prepared> Prepare(const sources::Frame& frame, const io::DetectSettings& settings) {
  const Eigen::Vector3d up = sources::UpInSensor(frame);
  Prepared out;
  // Stereo frames: the time is the matching's (the range image from its depth adds little).
  const DetectClock::time_point start = DetectClock::now();
  Expected<sources::FrameImage> image = sources::ToRangeImage(frame, up, settings.stereo);
  if (!image) return image.error();
  out.image = std::move(image->image);
  if (const sources::DepthImage* depth = frame.depth()) {
    out.render = od::Grid<float>{depth->model.width, depth->model.height, depth->depth_m};
  } else if (image->stereo) {
    out.stereo_ms = MillisecondsSince(start);
    out.render = image->stereo->depth_m;
    out.stereo = std::move(image->stereo);
  } else {
    out.render = io::RangeGrid(out.image);
  }
  return out;
}

class RawlogRun {
 public:
  RawlogRun(const DetectOptions& options, io::DetectSettings settings)
      : options_(options), settings_(std::move(settings)), out_(options.out) {}

  int Run();

 private:
  Expected<FrameResult> DetectFrame(const sources::Frame& frame,
                                    ::mrpt::obs::CObservation& observation,
                                    std::vector<::mrpt::obs::CObservation::Ptr>& inserted);
  void Progress(const sources::Frame& frame, const FrameResult& result);

  const DetectOptions& options_;
  const io::DetectSettings settings_;
  const fs::path out_;
  DetectClock::time_point start_ = DetectClock::now();
  DetectClock::time_point last_progress_ = start_;
  bool progress_shown_ = false;
};

Expected<FrameResult> RawlogRun::DetectFrame(const sources::Frame& frame,
                                             ::mrpt::obs::CObservation& observation,
                                             std::vector<::mrpt::obs::CObservation::Ptr>& inserted) {
  char number[16];
  std::snprintf(number, sizeof(number), "%06d", frame.index);
  const fs::path dir = out_ / (std::string(number) + "_" + FolderLabel(frame.label));
  const std::string where = sources::EntryName(options_.rawlog, frame.entry) + " ('" +
                            frame.label + "', " + frame.mrpt_class + ")";
  Expected<Prepared> prepared = Prepare(frame, settings_);
  if (!prepared) return Error{where + ": " + prepared.error().message};
  Expected<DetectResult> result = DetectAndClassify(prepared->image, settings_, options_);
  if (!result) return Error{where + ": " + result.error().message};
  const od::Detection& d = result->detection;
  const od::Classification& c = result->classification;

  io::RunDescription run;
  run.method = options_.method;
  run.rules_applied = !options_.no_rules;
  run.settings = settings_;
  run.depth_file = options_.rawlog + " (entry " + std::to_string(frame.entry) + ")";
  run.intrinsics_file = "sensor '" + frame.label + "' (" + frame.mrpt_class + ")";
  run.config_file = options_.config;
  Expected<io::DetectionFiles> files =
      io::WriteDetectionFiles(dir, prepared->render, d, c, run);
  if (!files) return files.error();

  FrameResult out;
  out.found = static_cast<int>(d.segments.size());
  out.kept = c.kept;
  out.rejected = c.rejected;
  json& r = out.record;
  r["index"] = frame.index;
  r["folder"] = dir.filename().string();
  r["entry"] = frame.entry;
  r["label"] = frame.label;
  r["class"] = frame.mrpt_class;
  r["kind"] = frame.kind();
  r["stamp_s"] = Stamp(frame.stamp_s);
  r["width"] = d.width;
  r["height"] = d.height;
  r["valid"] = prepared->image.valid_count();
  r["up_sensor"] = Vector(prepared->image.up());
  r["up_from"] = frame.imu ? "imu roll and pitch" : "sensor pose, body level";
  r["segments_found"] = out.found;
  r["segments_kept"] = out.kept;
  r["segments_rejected"] = out.rejected;
  r["obstacle_points"] = d.stats.obstacle_points;
  r["detect_ms"] = result->detect_ms;
  if (frame.odometry) {
    const Eigen::Isometry3d& T = frame.odometry->T_odom_body;
    r["odometry"] = {{"stamp_s", Stamp(frame.odometry->stamp_s)},
                     {"source", frame.odometry->source},
                     {"xyz_m", Vector(T.translation())},
                     {"yaw_rad", std::atan2(T(1, 0), T(0, 0))}};
  }
  if (frame.imu) {
    r["imu"] = {{"stamp_s", Stamp(frame.imu->stamp_s)},
                {"roll_rad", frame.imu->roll_rad},
                {"pitch_rad", frame.imu->pitch_rad}};
  }

  if (const sources::DepthImage* depth = frame.depth()) {
    if (auto* scan = dynamic_cast<::mrpt::obs::CObservation3DRangeScan*>(&observation);
        scan != nullptr && !options_.annotated.empty()) {
      if (Status s = sources::LabelRangeScan(*scan, *depth, d, c); !s) {
        return Error{where + ": " + s.message()};
      }
    }
    if (!depth->decoded_of_source.empty()) r["undistorted"] = true;
  } else if (const sources::PointScan* scan = frame.points()) {
    Expected<std::vector<std::uint32_t>> words = io::PointLabels(prepared->image, d, c);
    if (!words) return Error{where + ": " + words.error().message};
    if (Status s = io::WriteLabelFile(dir / "labels.label", *words); !s) return s.error();
    std::vector<std::uint8_t> point_class(words->size());
    for (std::size_t i = 0; i < words->size(); ++i) point_class[i] = (*words)[i] & 0xFFFFu;
    Expected<io::RgbImage> birds_eye = io::RenderBirdsEye(prepared->image, scan->points, point_class);
    if (!birds_eye) return Error{where + ": " + birds_eye.error().message};
    if (Status s = io::WriteRgbPng(dir / "birds_eye.png", *birds_eye); !s) return s.error();
    r["points"] = scan->points.size();
    r["layout"] = scan->layout;
    if (!options_.annotated.empty()) {
      Expected<::mrpt::obs::CObservationPointCloud::Ptr> cloud =
          sources::MakeSegmentCloud(observation, *scan, *words);
      if (!cloud) return Error{where + ": " + cloud.error().message};
      inserted.push_back(*cloud);
    }
  } else if (prepared->stereo) {
    if (Status s = io::WriteDepthTiff(dir / "depth.tiff", prepared->stereo->depth_m); !s) {
      return s.error();
    }
    r["stereo_ms"] = prepared->stereo_ms;
    r["stereo_holes"] = prepared->stereo->hole_fraction();
    // Large: the scene is nearer than the search range allows (StereoDisparity).
    r["stereo_range_end_fraction"] = prepared->stereo->disparity.range_end_fraction;
    r["stereo_range_too_short"] = prepared->stereo->disparity.range_too_short();
    r["baseline_m"] = frame.stereo()->baseline_m;
    r["rectified_here"] = frame.stereo()->rectified_here;
  }
  return out;
}

void RawlogRun::Progress(const sources::Frame& frame, const FrameResult& result) {
  // One line a second at most: long runs show they are alive, short ones stay quiet.
  const DetectClock::time_point now = DetectClock::now();
  if (std::chrono::duration<double>(now - last_progress_).count() < 1.0) return;
  last_progress_ = now;
  progress_shown_ = true;
  std::cerr << std::fixed << std::setprecision(1) << "cairn detect: frame " << frame.index + 1
            << (options_.max_frames > 0 ? " of at most " + std::to_string(options_.max_frames)
                                        : std::string())
            << " (entry " << frame.entry << ", '" << frame.label << "'): " << result.found
            << " segments, " << result.kept << " kept; "
            << std::chrono::duration<double>(now - start_).count() << " s\n";
}

int RawlogRun::Run() {
  sources::SourceOptions source_options;
  source_options.label = options_.label;
  Expected<sources::RawlogSource> source = sources::RawlogSource::Open(options_.rawlog, source_options);
  if (!source) return DetectFail(source.error().message);
  std::error_code ec;
  fs::create_directories(out_, ec);
  if (ec) return DetectFail(out_.string() + ": cannot create the output directory: " + ec.message());
  std::optional<sources::RawlogWriter> annotated;
  if (!options_.annotated.empty()) {
    if (fs::exists(options_.annotated, ec) && fs::equivalent(options_.annotated, options_.rawlog, ec)) {
      return DetectFail("--annotated " + options_.annotated + ": is the input rawlog");
    }
    Expected<sources::RawlogWriter> writer = sources::RawlogWriter::Create(options_.annotated);
    if (!writer) return DetectFail("--annotated: " + writer.error().message);
    annotated.emplace(std::move(*writer));
  }

  json frames = json::array();
  json skipped = json::array();
  std::map<std::string, int> labels_seen;
  int detected = 0, found = 0, kept = 0, rejected = 0;
  double detect_ms = 0.0;
  while (true) {
    Expected<std::optional<sources::SourceEntry>> entry = source->NextEntry();
    if (!entry) return DetectFail(entry.error().message);
    if (!*entry) break;
    sources::SourceEntry& e = **entry;
    std::vector<std::vector<::mrpt::obs::CObservation::Ptr>> inserted(e.observations.size());
    for (std::size_t k = 0; k < e.frames.size(); ++k) {
      const sources::Frame& frame = e.frames[k];
      ++labels_seen[frame.label];
      if (options_.max_frames > 0 && detected >= options_.max_frames) continue;
      ::mrpt::obs::CObservation& observation = *e.observations[e.frame_observation[k]];
      Expected<FrameResult> result =
          DetectFrame(frame, observation, inserted[e.frame_observation[k]]);
      if (!result) return DetectFail(result.error().message);
      ++detected;
      found += result->found;
      kept += result->kept;
      rejected += result->rejected;
      detect_ms += result->record["detect_ms"].get<double>();
      frames.push_back(result->record);
      Progress(frame, *result);
    }
    if (annotated) {
      // Observations format: the observation, then what goes after it. Sensory frames: the
      // inserted clouds join the frame.
      auto sf = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>(e.raw.object);
      for (const auto& extra : inserted) {
        for (const auto& cloud : extra) {
          if (sf) sf->insert(cloud);
        }
      }
      if (Status s = annotated->Write(*e.raw.object); !s) return DetectFail(s.message());
      if (!sf) {
        for (const auto& extra : inserted) {
          for (const auto& cloud : extra) {
            if (Status s = annotated->Write(*cloud); !s) return DetectFail(s.message());
          }
        }
      }
    }
  }
  if (progress_shown_) {
    std::cerr << "cairn detect: " << detected << " frames detected in " << std::fixed
              << std::setprecision(1) << MillisecondsSince(start_) / 1000.0 << " s\n";
  }
  for (const sources::SkippedObservation& s : source->skipped()) {
    skipped.push_back({{"entry", s.entry}, {"label", s.label}, {"class", s.mrpt_class},
                       {"reason", s.reason}});
  }
  if (detected == 0) {
    std::string message = options_.rawlog + ": no range observation";
    if (!options_.label.empty()) message += " labelled '" + options_.label + "'";
    message += " to detect (3-D range scans, Velodyne or rotating scans, point clouds, stereo "
               "pairs); `cairn info " + options_.rawlog + "` lists its sensors";
    return DetectFail(message);
  }
  if (annotated) {
    if (Status s = annotated->Commit(); !s) return DetectFail(s.message());
  }
  const double total_ms = MillisecondsSince(start_);
  json summary = {{"rawlog", options_.rawlog},
                  {"label", options_.label},
                  {"config", options_.config},
                  {"method", options_.method},
                  {"rules_applied", !options_.no_rules},
                  {"max_frames", options_.max_frames},
                  {"annotated", options_.annotated},
                  {"frames_detected", detected},
                  {"segments_found", found},
                  {"segments_kept", kept},
                  {"segments_rejected", rejected},
                  {"detect_ms", detect_ms},
                  {"total_ms", total_ms},
                  {"odometry_poses", source->odometry().size()},
                  {"skipped", skipped},
                  {"frames", frames}};
  const fs::path summary_path = out_ / "summary.json";
  if (Status s = util::WriteFileAtomic(summary_path, summary.dump(2) + "\n"); !s) {
    return DetectFail(s.message());
  }

  std::cout << std::fixed << std::setprecision(1) << "cairn detect: " << options_.rawlog << ": "
            << detected << " range frame" << (detected == 1 ? "" : "s");
  if (!options_.label.empty()) std::cout << " labelled '" << options_.label << "'";
  std::cout << ", method " << options_.method << ", rules " << (options_.no_rules ? "off" : "on")
            << "\n";
  for (const json& f : frames) {
    std::cout << "  " << f["folder"].get<std::string>() << ": " << f["class"].get<std::string>()
              << " " << f["width"].get<int>() << "x" << f["height"].get<int>();
    if (f.contains("points")) std::cout << ", " << f["points"].get<std::size_t>() << " points";
    std::cout << ", " << f["valid"].get<int>() << " valid; segments "
              << f["segments_found"].get<int>() << " found, " << f["segments_kept"].get<int>()
              << " kept, " << f["segments_rejected"].get<int>() << " rejected; detect "
              << f["detect_ms"].get<double>() << " ms\n";
    if (frames.size() > 20 && &f == &frames[9]) {
      std::cout << "  ... (" << frames.size() - 20 << " more in summary.json)\n";
      break;
    }
  }
  for (const sources::SkippedObservation& s : source->skipped()) {
    std::cout << "  skipped entry " << s.entry << " ('" << s.label << "', " << s.mrpt_class
              << "): " << s.reason << "\n";
  }
  std::cout << "  total: segments " << found << " found, " << kept << " kept, " << rejected
            << " rejected; detect " << detect_ms << " ms, total " << total_ms << " ms\n"
            << "  wrote: " << summary_path.string() << " and one folder per frame in "
            << out_.string() << "\n";
  if (annotated) std::cout << "         " << options_.annotated << " (annotated copy)\n";
  return kExitOk;
}

}  // namespace

int RunDetectRawlog(const DetectOptions& options) {
  Expected<io::DetectSettings> settings = LoadDetectSettingsOrDefaults(options);
  if (!settings) return DetectFail(settings.error().message);
  RawlogRun run(options, std::move(*settings));
  return run.Run();
}

}  // namespace cairn::apps
