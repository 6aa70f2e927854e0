// cairn map: a whole sequence fused into an OctoMap and a 2.5-D cost grid.
//
//   read    frames from an MRPT rawlog (poses from its odometry and IMU), a KITTI sequence
//           (poses.txt) or a folder of depth PNGs with a TUM pose file; each becomes a
//           RangeImage levelled by its pose's gravity (stereo pairs are matched first)
//   detect  od::Detect + od::Classify (the cone detector and the rules)
//   refine  optional (tilt.refine): Ceres matches the frame's ground to the terrain fused
//           so far, correcting roll, pitch and height (map::RefineTilt)
//   fuse    TerrainMap::Integrate
//   write   the map files (map_files.hpp), an overlay, per-frame poses and a summary
//
// Outputs are written into a staging folder inside --out and renamed into place at the end,
// so a failed or interrupted run leaves nothing half-written behind.
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/map/checkpoint.hpp"
#include "cairn/map/map_config_file.hpp"
#include "cairn/map/map_files.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/map/tilt_refiner.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/atomic_file.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/kitti.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/io/stereo.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sources/decode.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "cairn/sources/trajectory.hpp"
#include "subcommands.hpp"
#include "yaml_fields.hpp"  // cairn_od_io's strict field reader
#ifdef CAIRN_HAVE_SYNTH
#include "cairn/sim/shapes.hpp"
#include "cairn/sim/world.hpp"
#endif

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr double kDeg = 3.14159265358979323846 / 180.0;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

int Fail(const std::string& message) {
  std::cerr << "cairn map: error: " << message << "\n";
  return kExitFailure;
}

std::string Fixed(double v, int decimals) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(decimals) << v;
  return out.str();
}

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
  // Settings.
  std::string config;
  std::string out;
  double window_m = -1.0;  ///< < 0: the config's map.window_size
  bool offline = false;
  bool refine_tilt = false;
  bool no_refine_tilt = false;
  int max_frames = 0;
  int progress_every = 10;
  std::string truth;  ///< world YAML to score against
  // Crash safety.
  int checkpoint_every = 20;  ///< frames between checkpoints in DIR/map.checkpoint; 0: none
  bool resume = false;        ///< continue from DIR/map.checkpoint
  int interrupt_after = 0;    ///< tests: raise SIGINT after this many frames (0: never)
};

// ---------------------------------------------------------------------------------------
// Settings: detector, rules, stereo (od::io), map (map::LoadMapConfig) and tilt (here).

/// The `tilt:` section: Ceres tilt refinement against the fused terrain.
///   tilt:
///     refine: false         # on/off
///     prior_sigma: 2.0      # prior on the roll and pitch corrections [deg]
///     prior_sigma_z: 0.5    # prior on the height correction [m]
///     huber: 0.05           # robust loss scale of the height residuals [m]
///     max_range: 25.0       # ground points farther away are not used [m]
///     max_points: 1500      # ground points per frame
///     min_points: 50        # fewer over known terrain: the prior is kept
///     max_iterations: 50
struct TiltSettings {
  bool refine = false;
  map::TiltRefinerConfig refiner;
};

struct MapSettings {
  od::io::DetectSettings detect;
  map::MapConfig map;
  TiltSettings tilt;
};

/// The text with the top-level `tilt:` section replaced by blank lines (so that the other
/// loaders, which know nothing of it, report the same line numbers).
std::string WithoutTiltSection(const std::string& text) {
  std::istringstream in(text);
  std::string line, out;
  bool inside = false;
  while (std::getline(in, line)) {
    const bool top_level = !line.empty() && line[0] != ' ' && line[0] != '\t' && line[0] != '#';
    if (top_level) inside = line.rfind("tilt:", 0) == 0 || line.rfind("tilt :", 0) == 0;
    out += inside ? "\n" : line + "\n";
  }
  return out;
}

Status ParseTiltSection(const YAML::Node& root, const std::string& source, TiltSettings& tilt) {
  namespace detail = od::io::detail;
  const detail::FieldReader reader(source);
  const YAML::Node section = root["tilt"];
  if (!section || section.IsNull()) return {};
  const std::vector<std::string> keys = {"refine",     "prior_sigma",   "prior_sigma_z",
                                         "huber",      "max_range",     "max_points",
                                         "min_points", "max_iterations"};
  if (Status s = reader.CheckMapping(section, "tilt", keys); !s) return s;
  if (const YAML::Node v = section["refine"]) {
    bool ok = v.IsScalar();
    if (ok) {
      try {
        tilt.refine = v.as<bool>();
      } catch (const YAML::Exception&) {
        ok = false;
      }
    }
    if (!ok)
      return reader.Fail("tilt.refine", "expected true or false, got " + detail::Describe(v));
  }
  map::TiltRefinerConfig& c = tilt.refiner;
  const struct {
    const char* key;
    double* target;
    double scale;
  } doubles[] = {{"prior_sigma", &c.prior_sigma_rad, kDeg},
                 {"prior_sigma_z", &c.prior_sigma_z_m, 1.0},
                 {"huber", &c.huber_m, 1.0},
                 {"max_range", &c.max_range_m, 1.0}};
  for (const auto& f : doubles) {
    if (const YAML::Node v = section[f.key]) {
      Expected<double> value = reader.Double(v, std::string("tilt.") + f.key);
      if (!value) return value.error();
      *f.target = *value * f.scale;
    }
  }
  const struct {
    const char* key;
    int* target;
  } ints[] = {{"max_points", &c.max_points},
              {"min_points", &c.min_points},
              {"max_iterations", &c.max_iterations}};
  for (const auto& f : ints) {
    if (const YAML::Node v = section[f.key]) {
      Expected<std::int64_t> value = reader.Integer(v, std::string("tilt.") + f.key);
      if (!value) return value.error();
      if (*value < 0 || *value > 100000000) {
        return reader.Fail(std::string("tilt.") + f.key, "expected 0 .. 100000000");
      }
      *f.target = static_cast<int>(*value);
    }
  }
  if (Status s = c.Validate(); !s) return reader.Fail("tilt", s.message());
  return {};
}

Expected<MapSettings> LoadMapSettings(const std::string& path) {
  MapSettings settings;
  if (path.empty()) return settings;
  Expected<std::string> text = od::io::detail::ReadTextFile(path);
  if (!text) return text.error();
  std::string others = WithoutTiltSection(*text);
  // A file with only a tilt section leaves the other loaders an empty document.
  if (Expected<YAML::Node> rest = od::io::detail::ParseYaml(others, path); rest && rest->IsNull()) {
    others = "{}\n";
  }
  Expected<od::io::DetectSettings> detect = od::io::ParseDetectSettings(others, path);
  if (!detect) return detect.error();
  settings.detect = std::move(*detect);
  Expected<map::MapConfig> map_config = map::ParseMapConfig(others, path);
  if (!map_config) return map_config.error();
  settings.map = *map_config;
  Expected<YAML::Node> root = od::io::detail::ParseYaml(*text, path);
  if (!root) return root.error();
  if (root->IsMap()) {
    if (Status s = ParseTiltSection(*root, path, settings.tilt); !s) return s.error();
  }
  return settings;
}

// ---------------------------------------------------------------------------------------
// Frame sources: each hands out range images placed in the world.

struct InputFrame {
  int index = 0;  ///< among the frames fused (0-based)
  double stamp_s = 0.0;
  std::string name;  ///< for messages: "frame 3 ('CAMERA', entry 12)", a file name
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  bool tilt_from_imu = false;
  od::RangeImage image;
};

/// Gravity's up vector in the sensor frame, from the sensor's pose in the z-up world.
Eigen::Vector3d UpInSensor(const Eigen::Isometry3d& T_world_sensor) {
  return T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
}

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// The next frame, or nullopt at the end.
  virtual Expected<std::optional<InputFrame>> Next() = 0;
  /// Passes over the next `n` frames without making their range images (a resumed run).
  virtual Status Skip(int n) = 0;
  /// Frames the source will give (for the progress bar).
  virtual int total() const = 0;
  virtual json Describe() const = 0;
  const sources::Trajectory& trajectory() const { return *trajectory_; }

 protected:
  std::optional<sources::Trajectory> trajectory_;
};

std::string FrameName(const sources::Frame& f) {
  std::string name = "frame " + std::to_string(f.index) + " (";
  if (!f.label.empty()) name += "'" + f.label + "', ";
  return name + "entry " + std::to_string(f.entry) + ")";
}

/// A rawlog: a first pass gathers the odometry and IMU (and checks the whole file), a
/// second decodes the range frames one at a time.
class RawlogFrames : public FrameSource {
 public:
  static Expected<std::unique_ptr<RawlogFrames>> Open(const std::string& path,
                                                      const std::string& label,
                                                      const od::io::StereoConfig& stereo) {
    auto frames = std::unique_ptr<RawlogFrames>(new RawlogFrames());
    frames->path_ = path;
    frames->label_ = label;
    frames->stereo_ = stereo;
    sources::SourceOptions scan;
    scan.label = label;
    scan.decode_frames = false;
    Expected<sources::RawlogSource> first = sources::RawlogSource::Open(path, scan);
    if (!first) return first.error();
    std::vector<sources::ImuAttitude> imu;
    std::vector<std::string> labels;
    while (true) {
      Expected<std::optional<sources::SourceEntry>> entry = first->NextEntry();
      if (!entry) return entry.error();
      if (!*entry) break;
      for (const auto& o : (*entry)->observations) {
        if (const auto* m = dynamic_cast<const ::mrpt::obs::CObservationIMU*>(o.get())) {
          if (std::optional<sources::ImuAttitude> a = sources::DecodeImu(*m)) imu.push_back(*a);
        }
        if (!sources::IsRangeObservation(*o) || sources::WhyNoRangeData(*o)) continue;
        if (std::find(labels.begin(), labels.end(), o->sensorLabel) == labels.end()) {
          labels.push_back(o->sensorLabel);
        }
        if (label.empty() || o->sensorLabel == label) ++frames->total_;
      }
    }
    if (frames->total_ == 0) {
      std::string found = labels.empty() ? "none" : "";
      for (const std::string& l : labels) found += (found.empty() ? "'" : ", '") + l + "'";
      return Error{path + ": no range frames" +
                   (label.empty() ? std::string() : " with label '" + label + "'") +
                   " (range sensors in the file: " + found + ")"};
    }
    if (first->odometry().empty()) {
      return Error{path +
                   ": no odometry (CObservationOdometry or robot movement actions), so "
                   "the frames cannot be placed"};
    }
    Expected<sources::Trajectory> trajectory =
        sources::Trajectory::FromOdometry(first->odometry(), imu);
    if (!trajectory) return Error{path + ": " + trajectory.error().message};
    frames->trajectory_ = std::move(*trajectory);
    frames->imu_samples_ = static_cast<int>(imu.size());
    sources::SourceOptions read;
    read.label = label;
    Expected<sources::RawlogSource> second = sources::RawlogSource::Open(path, read);
    if (!second) return second.error();
    frames->source_.emplace(std::move(*second));
    return frames;
  }

  Expected<std::optional<InputFrame>> Next() override {
    Expected<std::optional<sources::Frame>> frame = source_->NextFrame();
    if (!frame) return frame.error();
    if (!*frame) return std::optional<InputFrame>();
    const sources::Frame& f = **frame;
    InputFrame out;
    out.index = f.index;
    out.stamp_s = f.stamp_s;
    out.name = path_ + ": " + FrameName(f);
    Expected<sources::BodyPose> body = trajectory_->PoseAt(f.stamp_s);
    if (!body) return Error{out.name + ": " + body.error().message};
    out.T_world_body = body->T_world_body;
    out.T_world_sensor = body->T_world_body * f.T_body_sensor;
    out.tilt_from_imu = body->tilt_from_imu;
    const Eigen::Vector3d up = UpInSensor(out.T_world_sensor);
    Expected<od::RangeImage> image = Error{"no range data"};
    if (const sources::DepthImage* depth = f.depth()) {
      image = od::RangeImage::FromDepth(depth->depth_m, depth->model, up);
    } else if (const sources::PointScan* scan = f.points()) {
      image = od::RangeImage::FromPoints(scan->points, scan->model, up, scan->rows, scan->cols);
    } else if (const sources::StereoPair* pair = f.stereo()) {
      od::io::StereoPair rectified;
      rectified.left = pair->left;
      rectified.right = pair->right;
      rectified.calibration.model = pair->left_model;
      rectified.calibration.baseline_m = pair->baseline_m;
      Expected<od::io::StereoDepth> matched = od::io::ComputeStereoDepth(rectified, stereo_);
      if (!matched) return Error{out.name + ": stereo: " + matched.error().message};
      image = od::RangeImage::FromDepth(matched->depth_m.data, pair->left_model, up);
    }
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<InputFrame>(std::move(out));
  }

  Status Skip(int n) override {
    for (int k = 0; k < n; ++k) {
      Expected<std::optional<sources::Frame>> frame = source_->NextFrame();
      if (!frame) return frame.error();
      if (!*frame) return Error{path_ + ": holds fewer frames than the checkpoint fused"};
    }
    return {};
  }

  int total() const override { return total_; }
  json Describe() const override {
    return {{"kind", "rawlog"},
            {"path", path_},
            {"label", label_},
            {"frames", total_},
            {"poses", trajectory_->source()},
            {"imu_samples", imu_samples_}};
  }

 private:
  RawlogFrames() = default;
  std::string path_, label_;
  od::io::StereoConfig stereo_;
  std::optional<sources::RawlogSource> source_;
  int total_ = 0;
  int imu_samples_ = 0;
};

/// A KITTI odometry sequence: velodyne scans placed by poses.txt.
class KittiFrames : public FrameSource {
 public:
  static Expected<std::unique_ptr<KittiFrames>> Open(const std::string& dir,
                                                     const std::string& sequence,
                                                     const std::string& range,
                                                     const std::string& lidar) {
    auto frames = std::unique_ptr<KittiFrames>(new KittiFrames());
    fs::path folder = dir;
    if (!sequence.empty()) {
      folder = fs::path(dir) / "sequences" / sequence;
      if (!fs::is_directory(folder)) {
        return Error{folder.string() +
                     ": no such sequence folder (--kitti DIR --sequence NN "
                     "reads DIR/sequences/NN)"};
      }
    }
    Expected<od::io::KittiSequence> opened = od::io::OpenKittiSequence(folder);
    if (!opened) return opened.error();
    frames->sequence_ = std::move(*opened);
    frames->selected_ = frames->sequence_.frames;
    if (!range.empty()) {
      Expected<std::vector<od::io::KittiFrame>> selected =
          od::io::SelectKittiFrames(frames->sequence_, range);
      if (!selected) return Error{"--range: " + selected.error().message};
      frames->selected_ = std::move(*selected);
    }
    Expected<sources::Trajectory> trajectory = sources::Trajectory::FromKitti(frames->sequence_);
    if (!trajectory) return trajectory.error();
    frames->trajectory_ = std::move(*trajectory);
    Expected<od::SphericalModel> preset = od::SphericalModel::Preset(lidar);
    if (!preset) return Error{"--lidar: " + preset.error().message};
    frames->layout_.preset = *preset;
    frames->lidar_ = lidar;
    return frames;
  }

  Expected<std::optional<InputFrame>> Next() override {
    if (next_ >= selected_.size()) return std::optional<InputFrame>();
    const od::io::KittiFrame& k = selected_[next_];
    InputFrame out;
    out.index = static_cast<int>(next_++);
    out.stamp_s = k.stamp_s;
    out.name = k.scan.string();
    Expected<sources::BodyPose> pose = trajectory_->PoseAt(k.stamp_s);
    if (!pose) return Error{out.name + ": " + pose.error().message};
    out.T_world_body = out.T_world_sensor = pose->T_world_body;
    Expected<od::io::PointCloud> cloud = od::io::ReadKittiBin(k.scan);
    if (!cloud) return cloud.error();
    Expected<od::io::FoundLayout> layout = od::io::FindLayout(*cloud, layout_, out.name);
    if (!layout) return layout.error();
    Expected<od::RangeImage> image = od::RangeImage::FromPoints(
        cloud->points, layout->model, UpInSensor(out.T_world_sensor), layout->rows, layout->cols);
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<InputFrame>(std::move(out));
  }

  Status Skip(int n) override {
    if (next_ + n > selected_.size()) {
      return Error{sequence_.folder.string() + ": holds fewer scans than the checkpoint fused"};
    }
    next_ += n;
    return {};
  }

  int total() const override { return static_cast<int>(selected_.size()); }
  json Describe() const override {
    return {{"kind", "kitti"},
            {"path", sequence_.folder.string()},
            {"lidar", lidar_},
            {"frames", total()},
            {"poses", trajectory_->source()}};
  }

 private:
  KittiFrames() = default;
  od::io::KittiSequence sequence_;
  std::vector<od::io::KittiFrame> selected_;
  od::io::LayoutOptions layout_;
  std::string lidar_;
  std::size_t next_ = 0;
};

/// A folder of depth PNGs with a TUM file of the camera's poses (optical frame in a z-up
/// world). Files named by their stamp (TUM RGB-D's "1305031102.160407.png") are placed at
/// that time; otherwise the k-th file (by name) takes the k-th pose.
class DepthFolderFrames : public FrameSource {
 public:
  static Expected<std::unique_ptr<DepthFolderFrames>> Open(const std::string& dir,
                                                           const std::string& poses,
                                                           const std::string& intrinsics) {
    auto frames = std::unique_ptr<DepthFolderFrames>(new DepthFolderFrames());
    if (!fs::is_directory(dir)) return Error{dir + ": no such folder (--frames)"};
    for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
      if (e.is_regular_file() && e.path().extension() == ".png") frames->files_.push_back(e.path());
    }
    std::sort(frames->files_.begin(), frames->files_.end());
    if (frames->files_.empty()) return Error{dir + ": no .png depth images (--frames)"};
    const fs::path intrinsics_path =
        intrinsics.empty() ? fs::path(dir) / "intrinsics.yaml" : fs::path(intrinsics);
    Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(intrinsics_path);
    if (!camera) return camera.error();
    frames->camera_ = *camera;
    Expected<std::vector<sources::StampedPose>> tum = sources::ReadTumPoses(poses);
    if (!tum) return tum.error();
    Expected<sources::Trajectory> trajectory = sources::Trajectory::FromPoses(*tum, poses);
    if (!trajectory) return trajectory.error();
    frames->trajectory_ = std::move(*trajectory);
    // Stamps from the names, when every name is a number.
    bool named_by_stamp = true;
    for (const fs::path& f : frames->files_) {
      const std::string stem = f.stem().string();
      char* end = nullptr;
      const double stamp = std::strtod(stem.c_str(), &end);
      if (stem.empty() || end != stem.c_str() + stem.size() || !std::isfinite(stamp)) {
        named_by_stamp = false;
        break;
      }
      frames->stamps_.push_back(stamp);
    }
    if (!named_by_stamp) {
      frames->stamps_.clear();
      if (tum->size() != frames->files_.size()) {
        return Error{dir + ": " + std::to_string(frames->files_.size()) +
                     " depth images not named by their stamps, but " + poses + " holds " +
                     std::to_string(tum->size()) + " poses (the k-th image takes the k-th pose)"};
      }
      for (const sources::StampedPose& p : *tum) frames->stamps_.push_back(p.stamp_s);
    }
    frames->dir_ = dir;
    frames->poses_ = poses;
    return frames;
  }

  Expected<std::optional<InputFrame>> Next() override {
    if (next_ >= files_.size()) return std::optional<InputFrame>();
    InputFrame out;
    out.index = static_cast<int>(next_);
    out.stamp_s = stamps_[next_];
    out.name = files_[next_].string();
    ++next_;
    Expected<sources::BodyPose> pose = trajectory_->PoseAt(out.stamp_s);
    if (!pose) return Error{out.name + ": " + pose.error().message};
    out.T_world_body = out.T_world_sensor = pose->T_world_body;
    Expected<od::io::Grid<float>> depth = od::io::ReadDepthPng(out.name, camera_);
    if (!depth) return depth.error();
    Expected<od::RangeImage> image =
        od::RangeImage::FromDepth(depth->data, camera_.model, UpInSensor(out.T_world_sensor));
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<InputFrame>(std::move(out));
  }

  Status Skip(int n) override {
    if (next_ + n > files_.size()) {
      return Error{dir_ + ": holds fewer images than the checkpoint fused"};
    }
    next_ += n;
    return {};
  }

  int total() const override { return static_cast<int>(files_.size()); }
  json Describe() const override {
    return {{"kind", "depth_frames"}, {"path", dir_}, {"frames", total()}, {"poses", poses_}};
  }

 private:
  DepthFolderFrames() = default;
  std::string dir_, poses_;
  std::vector<fs::path> files_;
  std::vector<double> stamps_;
  od::io::CameraIntrinsics camera_;
  std::size_t next_ = 0;
};

// ---------------------------------------------------------------------------------------
// Progress on stderr: a bar on a terminal, a line every N frames otherwise.

class Progress {
 public:
  /// `first`: frames already done when the run starts (a resumed run), not in the rate.
  Progress(int total, int every, int first = 0)
      : total_(std::max(total, 1)), every_(std::max(every, 1)), first_(first) {
    tty_ = isatty(fileno(stderr)) != 0;
    start_ = Clock::now();
  }
  void Update(int done) {
    const double elapsed = SecondsSince(start_);
    const double rate = elapsed > 0.0 ? (done - first_) / elapsed : 0.0;
    const double left = rate > 0.0 ? (total_ - done) / rate : 0.0;
    if (tty_) {
      constexpr int kWidth = 30;
      const int filled = kWidth * done / total_;
      std::cerr << "\r[" << std::string(filled, '#') << std::string(kWidth - filled, '.') << "] "
                << done << "/" << total_ << " frames, " << Fixed(rate, 1) << " frames/s, "
                << Minutes(left) << " left   " << std::flush;
    } else if (done % every_ == 0 || done == total_) {
      std::cerr << "cairn map: " << done << "/" << total_ << " frames (" << 100 * done / total_
                << "%), " << Fixed(rate, 1) << " frames/s, about " << Minutes(left) << " left\n";
    }
  }
  void Finish() {
    if (tty_) std::cerr << "\n";
  }

 private:
  static std::string Minutes(double seconds) {
    const long s = std::lround(seconds);
    std::ostringstream out;
    out << s / 60 << ":" << std::setw(2) << std::setfill('0') << s % 60;
    return out.str();
  }
  int total_, every_, first_;
  bool tty_ = false;
  std::chrono::steady_clock::time_point start_;
};

volatile std::sig_atomic_t g_interrupted = 0;
extern "C" void OnInterrupt(int) { g_interrupted = 1; }

// ---------------------------------------------------------------------------------------
// The run.

struct FrameRecord {
  int index = 0;
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< as fused
  int valid_points = 0;
  int segments = 0, kept = 0;
  map::FrameSummary fused;
  bool tilt_from_imu = false;  ///< the prior's roll and pitch came from the IMU
  bool refined = false;        ///< tilt refinement ran and was usable
  double d_roll_rad = 0.0, d_pitch_rad = 0.0, dz_m = 0.0;  ///< total correction fused
  double rms_before_m = 0.0, rms_after_m = 0.0;
  int refine_points = 0;
  double read_s = 0.0, detect_s = 0.0, refine_s = 0.0, fuse_s = 0.0;
};

struct StageTimes {
  double read_s = 0.0, detect_s = 0.0, refine_s = 0.0, fuse_s = 0.0, write_s = 0.0;
  double checkpoint_s = 0.0;
  double total() const { return read_s + detect_s + refine_s + fuse_s + write_s; }
};

// --- resume state: what the run keeps beside the map, stored in its checkpoint ---

/// Everything of the run besides the TerrainMap that a resumed run needs to end as the
/// uninterrupted one would: the frames' records, the tilt correction carried from frame to
/// frame, the stage times; and what identifies the run (its input and its settings file),
/// so that a checkpoint is never resumed on other data or other settings.
struct RunState {
  json input;               ///< FrameSource::Describe()
  std::string config_text;  ///< the --config file's bytes ("" for the defaults)
  json options;             ///< the command-line options that change the map (RunOptions)
  double wall_s = 0.0;      ///< wall time of the runs before this one [s]
  std::vector<FrameRecord> records;
  double carry_roll = 0.0, carry_pitch = 0.0, carry_dz = 0.0;
  int refined_frames = 0;
  StageTimes times;
};

json IsometryJson(const Eigen::Isometry3d& T) {
  json m = json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m.push_back(T.matrix()(r, c));
  }
  return m;
}

Eigen::Isometry3d IsometryFromJson(const json& m) {
  if (!m.is_array() || m.size() != 12) throw std::runtime_error("a pose is not 12 numbers");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) T.matrix()(r, c) = m.at(4 * r + c).get<double>();
  }
  return T;
}

// The fields of FrameRecord and FrameSummary that the outputs use, by name. json keeps
// doubles exactly (shortest round-trip form), so a resumed run writes the same figures.
#define CAIRN_RECORD_FIELDS(X)                                                              \
  X(index) X(stamp_s) X(valid_points) X(segments) X(kept) X(tilt_from_imu) X(refined)       \
  X(d_roll_rad) X(d_pitch_rad) X(dz_m) X(rms_before_m) X(rms_after_m) X(refine_points)      \
  X(read_s) X(detect_s) X(refine_s) X(fuse_s)
#define CAIRN_SUMMARY_FIELDS(X)                                                             \
  X(frame_id) X(stamp_s) X(valid_points) X(points_in_range) X(obstacle_points)              \
  X(ground_points) X(kept_segments) X(obstacles_created) X(obstacles_updated)               \
  X(obstacles_merged) X(obstacles_retired) X(voxels_occupied) X(voxels_free) X(cells_hit)   \
  X(cells_missed) X(lethal_cells) X(window_moved) X(classify_s) X(octree_s) X(grid_s)       \
  X(obstacles_s)
#define CAIRN_TIME_FIELDS(X) X(read_s) X(detect_s) X(refine_s) X(fuse_s) X(write_s) X(checkpoint_s)

std::string ResumeStateJson(const RunState& state) {
  json records = json::array();
  for (const FrameRecord& r : state.records) {
    json j, fused;
#define CAIRN_PUT(f) j[#f] = r.f;
    CAIRN_RECORD_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
#define CAIRN_PUT(f) fused[#f] = r.fused.f;
    CAIRN_SUMMARY_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
    j["fused"] = fused;
    j["T_world_body"] = IsometryJson(r.T_world_body);
    j["T_world_sensor"] = IsometryJson(r.T_world_sensor);
    records.push_back(std::move(j));
  }
  json times;
#define CAIRN_PUT(f) times[#f] = state.times.f;
  CAIRN_TIME_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
  const json j = {{"format", "cairn map resume state 1"},
                  {"input", state.input},
                  {"config_text", state.config_text},
                  {"options", state.options},
                  {"wall_s", state.wall_s},
                  {"carry", {state.carry_roll, state.carry_pitch, state.carry_dz}},
                  {"refined_frames", state.refined_frames},
                  {"times", times},
                  {"records", records}};
  return j.dump();
}

Expected<RunState> ResumeStateFromJson(const std::string& text, const std::string& path) {
  try {
    const json j = json::parse(text);
    if (j.at("format") != "cairn map resume state 1") {
      return Error{path + ": not a cairn map checkpoint (its resume state is of another format)"};
    }
    RunState state;
    state.input = j.at("input");
    state.config_text = j.at("config_text").get<std::string>();
    state.options = j.at("options");
    state.wall_s = j.at("wall_s").get<double>();
    state.carry_roll = j.at("carry").at(0).get<double>();
    state.carry_pitch = j.at("carry").at(1).get<double>();
    state.carry_dz = j.at("carry").at(2).get<double>();
    state.refined_frames = j.at("refined_frames").get<int>();
    const json& times = j.at("times");
#define CAIRN_GET(f) times.at(#f).get_to(state.times.f);
    CAIRN_TIME_FIELDS(CAIRN_GET)
#undef CAIRN_GET
    for (const json& rj : j.at("records")) {
      FrameRecord r;
#define CAIRN_GET(f) rj.at(#f).get_to(r.f);
      CAIRN_RECORD_FIELDS(CAIRN_GET)
#undef CAIRN_GET
      const json& fused = rj.at("fused");
#define CAIRN_GET(f) fused.at(#f).get_to(r.fused.f);
      CAIRN_SUMMARY_FIELDS(CAIRN_GET)
#undef CAIRN_GET
      r.T_world_body = IsometryFromJson(rj.at("T_world_body"));
      r.T_world_sensor = IsometryFromJson(rj.at("T_world_sensor"));
      state.records.push_back(r);
    }
    return state;
  } catch (const std::exception& e) {
    return Error{path + ": the run's resume state is unreadable (" + e.what() + ")"};
  }
}
#undef CAIRN_RECORD_FIELDS
#undef CAIRN_SUMMARY_FIELDS
#undef CAIRN_TIME_FIELDS

/// The options of `cairn map` besides the input and --config that change what is fused: a
/// checkpoint is resumed only with the same ones.
json RunOptions(const MapOptions& o, bool refine_tilt, double window_size_m) {
  return {{"--range", o.range},
          {"--intrinsics", o.intrinsics},
          {"--refine-tilt", refine_tilt},
          {"--window", window_size_m}};
}

Expected<std::string> ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot read"};
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string TumLine(double stamp_s, const Eigen::Isometry3d& T) {
  Eigen::Quaterniond q(T.linear());
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  std::ostringstream out;
  out << std::fixed << std::setprecision(6) << stamp_s << " " << T.translation().x() << " "
      << T.translation().y() << " " << T.translation().z() << " " << std::setprecision(9) << q.x()
      << " " << q.y() << " " << q.z() << " " << q.w();
  return out.str();
}

// --- scoring against a synthetic world (--truth) ---

struct TruthObject {
  int id = 0;
  std::string name;
  bool is_obstacle = false;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  std::vector<cv::Point2f> footprint;  ///< polygon of its horizontal footprint, world xy [m]
  // Results.
  bool found = false;
  double distance_m = -1.0;  ///< footprint to the nearest lethal cell's centre; -1: none near
  int obstacle_id = 0;       ///< the map obstacle owning that cell
};

struct TruthScore {
  std::string world;
  std::vector<TruthObject> objects;
  int obstacles = 0, found = 0, marked_non_obstacles = 0, false_obstacles = 0;
  std::vector<int> false_obstacle_ids;
  double iou = 0.0;  ///< lethal cells against the cells inside true obstacles' footprints
  double elevation_rms_m = 0.0, elevation_max_m = 0.0;
  int elevation_cells = 0;
};

/// Distance from `xy` to a footprint polygon: 0 inside [m].
double DistanceToFootprint(const std::vector<cv::Point2f>& polygon, const Eigen::Vector2d& xy) {
  const double signed_distance = cv::pointPolygonTest(
      polygon, cv::Point2f(static_cast<float>(xy.x()), static_cast<float>(xy.y())), true);
  return std::max(0.0, -signed_distance);
}

#ifdef CAIRN_HAVE_SYNTH
/// A rotated ellipse or rectangle as a polygon.
void AddEllipse(std::vector<cv::Point2f>& out, const Eigen::Vector2d& c, double a, double b,
                double yaw) {
  for (int k = 0; k < 32; ++k) {
    const double t = 2 * M_PI * k / 32;
    const Eigen::Vector2d local(a * std::cos(t), b * std::sin(t));
    const Eigen::Vector2d p = c + Eigen::Rotation2Dd(yaw) * local;
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
}
void AddRectangle(std::vector<cv::Point2f>& out, const Eigen::Vector2d& c, double x_lo, double x_hi,
                  double y_lo, double y_hi, double yaw) {
  for (const Eigen::Vector2d& local : {Eigen::Vector2d(x_lo, y_lo), Eigen::Vector2d(x_hi, y_lo),
                                       Eigen::Vector2d(x_hi, y_hi), Eigen::Vector2d(x_lo, y_hi)}) {
    const Eigen::Vector2d p = c + Eigen::Rotation2Dd(yaw) * local;
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
}

/// The horizontal footprint of a solid as a convex polygon (terrain features have none).
std::vector<cv::Point2f> Footprint(const sim::Shape& shape) {
  std::vector<cv::Point2f> points;
  if (sim::IsTerrainFeature(shape)) return points;
  if (const auto* c = std::get_if<sim::Cylinder>(&shape)) {
    AddEllipse(points, c->base_centre.head<2>(), c->radius_m, c->radius_m, 0.0);
  } else if (const auto* e = std::get_if<sim::Ellipsoid>(&shape)) {
    AddEllipse(points, e->centre.head<2>(), e->radii.x(), e->radii.y(), e->yaw_rad);
  } else if (const auto* b = std::get_if<sim::Box>(&shape)) {
    AddRectangle(points, b->centre.head<2>(), -b->size.x() / 2, b->size.x() / 2, -b->size.y() / 2,
                 b->size.y() / 2, b->yaw_rad);
  } else if (const auto* r = std::get_if<sim::Ridge>(&shape)) {
    const double half_length = r->top_length_m / 2 + r->height_m / std::tan(r->end_slope_rad);
    AddRectangle(points, r->base_centre.head<2>(), -half_length, half_length,
                 -r->top_width_m / 2 - r->height_m / std::tan(r->right_slope_rad),
                 r->top_width_m / 2 + r->height_m / std::tan(r->left_slope_rad), r->yaw_rad);
  } else if (const auto* rod = std::get_if<sim::Rod>(&shape)) {
    AddEllipse(points, rod->start.head<2>(), rod->radius_m, rod->radius_m, 0.0);
    AddEllipse(points, rod->end.head<2>(), rod->radius_m, rod->radius_m, 0.0);
  } else if (const auto* k = std::get_if<sim::Cluster>(&shape)) {
    for (const sim::Ellipsoid& part : k->parts) {
      AddEllipse(points, part.centre.head<2>(), part.radii.x(), part.radii.y(), part.yaw_rad);
    }
  }
  std::vector<cv::Point2f> hull;
  cv::convexHull(points, hull);
  return hull;
}

/// Found: a lethal cell's centre within `tolerance_m` of the object's footprint (odometry
/// drift and the grid's cell). A live map obstacle none of whose cells comes within the
/// tolerance of any object's footprint is a false obstacle.
Expected<TruthScore> ScoreAgainstWorld(const std::string& world_path,
                                       const map::TerrainMap& terrain, double tolerance_m) {
  Expected<sim::World> world = sim::LoadWorld(world_path);
  if (!world) return Error{"--truth: " + world.error().message};
  TruthScore score;
  score.world = world_path;
  for (const sim::Object& o : world->scene.objects()) {
    TruthObject t;
    t.footprint = Footprint(o.shape);
    if (t.footprint.empty()) continue;
    t.id = o.id;
    t.name = o.name;
    t.is_obstacle = o.is_obstacle;
    for (const cv::Point2f& p : t.footprint) t.centre += Eigen::Vector2d(p.x, p.y);
    t.centre /= static_cast<double>(t.footprint.size());
    score.objects.push_back(std::move(t));
  }
  const map::TerrainGrid& grid = terrain.grid();
  int both = 0, either = 0;
  for (int j = 0; j < grid.extent().y(); ++j) {
    for (int i = 0; i < grid.extent().x(); ++i) {
      const map::CellIndex index = grid.min_index() + map::CellIndex(i, j);
      const map::Cell& cell = grid.At(index);
      const Eigen::Vector2d xy = grid.CentreOf(index);
      bool truly = false;
      for (TruthObject& t : score.objects) {
        const double d = DistanceToFootprint(t.footprint, xy);
        if (t.is_obstacle && d == 0.0) truly = true;
        if (cell.lethal && (t.distance_m < 0 || d < t.distance_m)) {
          t.distance_m = d;
          t.obstacle_id = cell.obstacle_id;
        }
      }
      both += truly && cell.lethal ? 1 : 0;
      either += truly || cell.lethal ? 1 : 0;
    }
  }
  score.iou = either > 0 ? static_cast<double>(both) / either : 0.0;
  for (TruthObject& t : score.objects) {
    t.found = t.distance_m >= 0.0 && t.distance_m <= tolerance_m;
    if (t.is_obstacle) {
      ++score.obstacles;
      score.found += t.found ? 1 : 0;
    } else if (t.found) {
      ++score.marked_non_obstacles;
    }
  }
  for (const map::Obstacle& o : terrain.obstacles()) {
    bool matched = false;
    for (const map::CellIndex& c : o.cells) {
      for (const TruthObject& t : score.objects) {
        if (DistanceToFootprint(t.footprint, grid.CentreOf(c)) <= tolerance_m) matched = true;
      }
    }
    if (!matched) {
      ++score.false_obstacles;
      score.false_obstacle_ids.push_back(o.id);
    }
  }
  // Elevation against the true terrain, over every cell with ground points.
  double sum2 = 0.0;
  for (int j = 0; j < grid.extent().y(); ++j) {
    for (int i = 0; i < grid.extent().x(); ++i) {
      const map::CellIndex index = grid.min_index() + map::CellIndex(i, j);
      const map::Cell& cell = grid.At(index);
      if (!cell.has_elevation()) continue;
      const double error =
          cell.elevation_mean_m - world->scene.terrain().Height(grid.CentreOf(index));
      sum2 += error * error;
      score.elevation_max_m = std::max(score.elevation_max_m, std::abs(error));
      ++score.elevation_cells;
    }
  }
  if (score.elevation_cells > 0) score.elevation_rms_m = std::sqrt(sum2 / score.elevation_cells);
  return score;
}
#endif

/// The overlay: the colour cost grid (cost.png) enlarged, the live obstacles outlined with
/// their ids, the path driven, and the true objects when scored.
Status WriteOverlay(const fs::path& cost_png, const fs::path& path, const map::TerrainMap& terrain,
                    const std::vector<FrameRecord>& records, const TruthScore* truth) {
  Expected<map::CellBox> box = map::ExportBounds(terrain);
  if (!box) return box.error();
  const cv::Mat cost = cv::imread(cost_png.string(), cv::IMREAD_COLOR);
  if (cost.empty()) return Error{cost_png.string() + ": cannot read back"};
  const int scale = std::clamp(1200 / std::max(cost.cols, cost.rows), 1, 6);
  cv::Mat image;
  cv::resize(cost, image, cv::Size(), scale, scale, cv::INTER_NEAREST);
  const double s = terrain.grid().cell_size();
  // World xy -> pixel of the enlarged image (map_server orientation: +y up).
  const auto pixel = [&](const Eigen::Vector2d& xy) {
    const double col = (xy.x() / s - box->min.x()) * scale;
    const double row = (box->max.y() + 1 - xy.y() / s) * scale;
    return cv::Point(static_cast<int>(std::lround(col)), static_cast<int>(std::lround(row)));
  };
  if (truth != nullptr) {
    for (const TruthObject& t : truth->objects) {
      std::vector<cv::Point> polygon;
      for (const cv::Point2f& p : t.footprint) polygon.push_back(pixel({p.x, p.y}));
      const cv::Scalar colour = t.is_obstacle ? cv::Scalar(0, 150, 0) : cv::Scalar(220, 170, 0);
      cv::polylines(image, polygon, true, colour, 2, cv::LINE_AA);
    }
  }
  std::vector<cv::Point> path_px;
  for (const FrameRecord& r : records) {
    path_px.push_back(pixel(r.T_world_body.translation().head<2>()));
  }
  if (path_px.size() >= 2) {
    cv::polylines(image, path_px, false, cv::Scalar(200, 80, 0), 2, cv::LINE_AA);
  }
  for (const map::Obstacle& o : terrain.obstacles()) {
    const cv::Point a = pixel(o.footprint_min), b = pixel(o.footprint_max);
    cv::rectangle(image, cv::Point(a.x, b.y), cv::Point(b.x, a.y), cv::Scalar(40, 40, 40), 1);
    cv::putText(image, std::to_string(o.id), cv::Point(b.x + 3, b.y + 2), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  }
  // The key, in a band below the map.
  const int width = std::max(image.cols, 830);
  cv::Mat canvas(image.rows + 64, width, CV_8UC3, cv::Scalar(255, 255, 255));
  image.copyTo(canvas(cv::Rect(0, 0, image.cols, image.rows)));
  const int y0 = image.rows + 8;
  const auto text = [&](const std::string& words, int x, int y) {
    cv::putText(canvas, words, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, 0.42,
                cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  };
  for (int k = 0; k <= 200; ++k) {  // cost.png's terrain colours, 0 .. 252
    const double t = k / 200.0;
    const double blue = 255.0 * std::max(0.0, 1.0 - 2.0 * t);
    const double green = t <= 0.5 ? 255.0 : 255.0 - 2.0 * (t - 0.5) * 135.0;
    cv::line(canvas, cv::Point(10 + k, y0), cv::Point(10 + k, y0 + 14),
             cv::Scalar(blue, green, 255));
  }
  cv::rectangle(canvas, cv::Rect(10, y0, 201, 15), cv::Scalar(120, 120, 120), 1);
  text("terrain cost 0 .. 252", 10, y0 + 30);
  const struct {
    cv::Scalar colour;
    const char* label;
  } swatches[] = {{cv::Scalar(160, 40, 140), "253 inscribed"},
                  {cv::Scalar(0, 0, 220), "254 lethal"},
                  {cv::Scalar(128, 128, 128), "255 unknown"}};
  for (int k = 0; k < 3; ++k) {
    const int x = 230 + 120 * k;
    cv::rectangle(canvas, cv::Rect(x, y0, 15, 15), swatches[k].colour, cv::FILLED);
    text(swatches[k].label, x + 20, y0 + 12);
  }
  cv::line(canvas, cv::Point(320, y0 + 26), cv::Point(340, y0 + 26), cv::Scalar(200, 80, 0), 2);
  text("path", 346, y0 + 30);
  cv::rectangle(canvas, cv::Rect(400, y0 + 20, 14, 12), cv::Scalar(40, 40, 40), 1);
  text("map obstacle (id)", 420, y0 + 30);
  if (truth != nullptr) {
    cv::line(canvas, cv::Point(570, y0 + 26), cv::Point(590, y0 + 26), cv::Scalar(0, 150, 0), 2);
    text("true obstacle", 596, y0 + 30);
    cv::line(canvas, cv::Point(700, y0 + 26), cv::Point(720, y0 + 26), cv::Scalar(220, 170, 0), 2);
    text("not obstacle", 726, y0 + 30);
  }
  text("1 px = " + Fixed(s / scale, 3) + " m, north (+y) up", 10, y0 + 50);
  std::vector<unsigned char> bytes;
  if (!cv::imencode(".png", canvas, bytes)) return Error{path.string() + ": cannot encode PNG"};
  return od::io::WriteFileAtomic(
      path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

json ObstacleBrief(const map::Obstacle& o) {
  return {{"id", o.id},
          {"centroid", {o.centroid.x(), o.centroid.y(), o.centroid.z()}},
          {"height_m", o.height_m},
          {"footprint_area_m2", o.footprint_area_m2},
          {"frames", o.frames.size()}};
}

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
  const int inputs = !options.rawlog.empty() + !options.kitti.empty() + !options.frames.empty();
  if (inputs != 1) {
    return Fail("give one input: --rawlog FILE, --kitti DIR or --frames DIR --poses FILE.tum");
  }
  if (!options.frames.empty() && options.poses.empty()) {
    return Fail("--frames DIR needs --poses FILE.tum (the camera's pose per image)");
  }
  Expected<MapSettings> settings = LoadMapSettings(options.config);
  if (!settings) return Fail(settings.error().message);
  if (options.offline) settings->map.window_size_m = 0.0;
  if (options.window_m >= 0.0) settings->map.window_size_m = options.window_m;
  if (options.refine_tilt) settings->tilt.refine = true;
  if (options.no_refine_tilt) settings->tilt.refine = false;
  if (Status s = settings->map.Validate(); !s) return Fail("--window: " + s.message());
  Expected<map::TerrainMap> created = map::TerrainMap::Create(settings->map);
  if (!created) return Fail(created.error().message);
  map::TerrainMap terrain = std::move(*created);

  const Clock::time_point open_start = Clock::now();
  std::unique_ptr<FrameSource> source;
  if (!options.rawlog.empty()) {
    auto opened = RawlogFrames::Open(options.rawlog, options.label, settings->detect.stereo);
    if (!opened) return Fail(opened.error().message);
    source = std::move(*opened);
  } else if (!options.kitti.empty()) {
    auto opened = KittiFrames::Open(options.kitti, options.sequence, options.range, options.lidar);
    if (!opened) return Fail(opened.error().message);
    source = std::move(*opened);
  } else {
    auto opened = DepthFolderFrames::Open(options.frames, options.poses, options.intrinsics);
    if (!opened) return Fail(opened.error().message);
    source = std::move(*opened);
  }
  StageTimes times;
  times.read_s += SecondsSince(open_start);  // the rawlog's pose pass reads the whole file

  // The output folder and a staging folder inside it.
  Cleanup cleanup;
  cleanup.out = options.out;
  std::error_code ec;
  if (!fs::exists(options.out)) {
    fs::create_directories(options.out, ec);
    if (ec) return Fail(options.out + ": cannot create: " + ec.message());
    cleanup.created_out = true;
  } else if (!fs::is_directory(options.out)) {
    return Fail(options.out + ": exists and is not a folder (--out)");
  }
  cleanup.staging = fs::path(options.out) / (".cairn-map-partial-" + std::to_string(getpid()));
  fs::create_directories(cleanup.staging, ec);
  if (ec) return Fail(cleanup.staging.string() + ": cannot create: " + ec.message());

  // From here an interruption is handled (at the next frame): nothing half-written is left.
  g_interrupted = 0;
  std::signal(SIGINT, OnInterrupt);
  std::signal(SIGTERM, OnInterrupt);

  // Checkpoints: the map and the run's state, every --checkpoint-every frames and when
  // interrupted, in DIR/map.checkpoint (atomically); removed once the map files are written.
  Expected<std::string> config_text =
      options.config.empty() ? Expected<std::string>(std::string()) : ReadWholeFile(options.config);
  if (!config_text) return Fail(config_text.error().message);
  const fs::path checkpoint = fs::path(options.out) / map::kCheckpointFileName;
  std::vector<FrameRecord> records;
  // The last usable tilt correction carries to the next frame's prior: IMU biases and the
  // height integrated from them persist from frame to frame.
  double carry_roll = 0.0, carry_pitch = 0.0, carry_dz = 0.0;
  int refined_frames = 0;
  const json run_options = RunOptions(options, settings->tilt.refine, settings->map.window_size_m);
  double earlier_wall_s = 0.0;
  if (!options.resume && fs::exists(checkpoint)) {
    return Fail(checkpoint.string() +
                ": an interrupted run's checkpoint is here: continue it with --resume, or "
                "remove it (or choose another --out) to start afresh");
  }
  if (options.resume) {
    if (!fs::exists(checkpoint)) {
      return Fail(checkpoint.string() +
                  ": no checkpoint to resume from (--resume continues a run interrupted with "
                  "the same --out)");
    }
    std::string user_data;
    Expected<map::TerrainMap> loaded = map::LoadCheckpoint(checkpoint, settings->map, &user_data);
    if (!loaded) return Fail(loaded.error().message + " (--resume)");
    Expected<RunState> state = ResumeStateFromJson(user_data, checkpoint.string());
    if (!state) return Fail(state.error().message);
    if (state->input != source->Describe()) {
      return Fail(checkpoint.string() + ": made from another input (" + state->input.dump() +
                  "), not " + source->Describe().dump() + " (--resume needs the same input)");
    }
    for (const auto& [key, value] : state->options.items()) {
      if (!run_options.contains(key) || run_options.at(key) != value) {
        return Fail(checkpoint.string() + ": made with " + key + " " + value.dump() + ", not " +
                    (run_options.contains(key) ? run_options.at(key).dump() : "none") +
                    " (--resume needs the same options)");
      }
    }
    if (state->config_text != *config_text) {
      return Fail(checkpoint.string() + ": made with other settings than " +
                  (options.config.empty() ? std::string("the defaults") : options.config) +
                  " (--resume needs the same --config)");
    }
    const Clock::time_point skip_start = Clock::now();
    if (Status s = source->Skip(static_cast<int>(state->records.size())); !s) {
      return Fail(s.message());
    }
    const double open_s = times.read_s + SecondsSince(skip_start);
    terrain = std::move(*loaded);
    records = std::move(state->records);
    carry_roll = state->carry_roll;
    carry_pitch = state->carry_pitch;
    carry_dz = state->carry_dz;
    refined_frames = state->refined_frames;
    times = state->times;
    times.read_s += open_s;
    earlier_wall_s = state->wall_s;
    std::cerr << "cairn map: resuming from " << checkpoint.string() << " after "
              << records.size() << " frames\n";
  }
  auto save_checkpoint = [&]() -> Status {
    const Clock::time_point t0 = Clock::now();
    RunState state;
    state.input = source->Describe();
    state.config_text = *config_text;
    state.options = run_options;
    state.wall_s = earlier_wall_s + SecondsSince(run_start);
    state.records = records;
    state.carry_roll = carry_roll;
    state.carry_pitch = carry_pitch;
    state.carry_dz = carry_dz;
    state.refined_frames = refined_frames;
    state.times = times;
    Status saved = map::SaveCheckpoint(terrain, checkpoint, ResumeStateJson(state));
    times.checkpoint_s += SecondsSince(t0);
    return saved;
  };

  const int total =
      options.max_frames > 0 ? std::min(options.max_frames, source->total()) : source->total();
  Progress progress(total, options.progress_every, static_cast<int>(records.size()));
  while (options.max_frames <= 0 || static_cast<int>(records.size()) < options.max_frames) {
    if (g_interrupted) {
      progress.Finish();
      if (records.empty()) {
        std::cerr << "cairn map: interrupted before the first frame was fused; nothing written\n";
        return 130;
      }
      if (Status s = save_checkpoint(); !s) return Fail("interrupted, and " + s.message());
      std::cerr << "cairn map: interrupted after " << records.size() << " frames; the map so far "
                << "is in " << checkpoint.string()
                << ": run the same command with --resume to continue\n";
      return 130;
    }
    FrameRecord r;
    Clock::time_point t = Clock::now();
    Expected<std::optional<InputFrame>> next = source->Next();
    if (!next) {
      progress.Finish();
      return Fail(next.error().message);
    }
    if (!*next) break;
    InputFrame& frame = **next;
    // Returns of the vehicle itself are no returns for the map either, not only for the
    // detector (detector.min_range).
    if (settings->detect.detector.min_range_m > 0.0) {
      frame.image.DropReturnsNearerThan(settings->detect.detector.min_range_m);
    }
    r.read_s = SecondsSince(t);
    r.index = static_cast<int>(records.size());
    r.stamp_s = frame.stamp_s;
    r.T_world_body = frame.T_world_body;
    r.tilt_from_imu = frame.tilt_from_imu;
    r.valid_points = frame.image.valid_count();

    t = Clock::now();
    Expected<od::Detection> detection = od::Detect(frame.image, settings->detect.detector);
    if (!detection) return Fail(frame.name + ": " + detection.error().message);
    Expected<od::Classification> classification = od::Classify(*detection, settings->detect.rules);
    if (!classification) return Fail(frame.name + ": " + classification.error().message);
    r.detect_s = SecondsSince(t);
    r.segments = static_cast<int>(detection->segments.size());
    r.kept = classification->kept;

    Eigen::Isometry3d T_world_sensor = frame.T_world_sensor;
    if (settings->tilt.refine) {
      t = Clock::now();
      const Eigen::Isometry3d prior = map::ApplyTiltCorrection(T_world_sensor, carry_roll, carry_pitch, carry_dz);
      std::vector<Eigen::Vector3f> ground;
      ground.reserve(frame.image.size());
      for (int i = 0; i < frame.image.size(); ++i) {
        if (!frame.image.valid(i)) continue;
        const int label = detection->labels[i];
        if (label > 0 && classification->verdicts[label - 1].cls == od::SegmentClass::kKept) {
          continue;
        }
        ground.push_back(frame.image.point(i).cast<float>());
      }
      const map::ElevationPatch patch =
          map::ElevationPatchAround(terrain, prior.translation().head<2>(),
                                    settings->tilt.refiner.max_range_m);
      Expected<map::TiltEstimate> estimate =
          map::RefineTilt(ground, prior, patch, settings->tilt.refiner);
      if (!estimate) return Fail(frame.name + ": tilt: " + estimate.error().message);
      if (estimate->usable && estimate->rms_after_m <= estimate->rms_before_m) {
        carry_roll += estimate->roll_rad;
        carry_pitch += estimate->pitch_rad;
        carry_dz += estimate->dz_m;
        T_world_sensor = estimate->T_world_sensor;
        r.refined = true;
        ++refined_frames;
      } else {
        T_world_sensor = prior;
      }
      r.d_roll_rad = carry_roll;
      r.d_pitch_rad = carry_pitch;
      r.dz_m = carry_dz;
      r.rms_before_m = estimate->rms_before_m;
      r.rms_after_m = estimate->rms_after_m;
      r.refine_points = estimate->points_used;
      r.refine_s = SecondsSince(t);
    }

    t = Clock::now();
    Expected<map::FrameSummary> fused = terrain.Integrate(frame.image, *detection, *classification,
                                                          T_world_sensor, frame.stamp_s, r.index);
    if (!fused) return Fail(frame.name + ": " + fused.error().message);
    r.fuse_s = SecondsSince(t);
    r.fused = *fused;
    r.T_world_sensor = T_world_sensor;
    times.read_s += r.read_s;
    times.detect_s += r.detect_s;
    times.refine_s += r.refine_s;
    times.fuse_s += r.fuse_s;
    records.push_back(r);
    progress.Update(static_cast<int>(records.size()));
    const int done = static_cast<int>(records.size());
    if (options.checkpoint_every > 0 && done % options.checkpoint_every == 0 && done < total) {
      if (Status s = save_checkpoint(); !s) return Fail(s.message());
    }
    if (options.interrupt_after > 0 && done == options.interrupt_after) std::raise(SIGINT);
  }
  progress.Finish();
  if (records.empty()) return Fail("no frames to fuse");

  // --- write ---
  const Clock::time_point write_start = Clock::now();
  const fs::path& staging = cleanup.staging;
  if (Status s = map::WriteMapFiles(terrain, staging); !s) return Fail(s.message());

  std::optional<TruthScore> truth;
  if (!options.truth.empty()) {
#ifdef CAIRN_HAVE_SYNTH
    Expected<TruthScore> score =
        ScoreAgainstWorld(options.truth, terrain, 0.5 + terrain.grid().cell_size());
    if (!score) return Fail(score.error().message);
    truth = std::move(*score);
#else
    return Fail("--truth needs cairn built with libsim (cairn synth)");
#endif
  }
  if (Status s = WriteOverlay(staging / "cost.png", staging / "overlay.png", terrain, records,
                              truth ? &*truth : nullptr);
      !s) {
    return Fail(s.message());
  }

  // Per-frame poses (TUM, as fused) and figures (CSV).
  std::string tum =
      "# cairn map: T_world_sensor of each frame as fused (stamp tx ty tz qx qy qz qw)\n";
  std::ostringstream csv;
  csv << "frame,stamp_s,valid_points,segments,kept,obstacle_points,obstacles_created,"
         "lethal_cells,tilt_refined,d_roll_deg,d_pitch_deg,dz_m,rms_before_m,rms_after_m,"
         "read_ms,detect_ms,refine_ms,fuse_ms\n";
  double distance_m = 0.0;
  for (std::size_t k = 0; k < records.size(); ++k) {
    const FrameRecord& r = records[k];
    if (k > 0) {
      distance_m +=
          (r.T_world_body.translation() - records[k - 1].T_world_body.translation()).norm();
    }
    tum += TumLine(r.stamp_s, r.T_world_sensor) + "\n";
    csv << r.index << "," << Fixed(r.stamp_s, 6) << "," << r.valid_points << "," << r.segments
        << "," << r.kept << "," << r.fused.obstacle_points << "," << r.fused.obstacles_created
        << "," << r.fused.lethal_cells << "," << (r.refined ? 1 : 0) << ","
        << Fixed(r.d_roll_rad / kDeg, 3) << "," << Fixed(r.d_pitch_rad / kDeg, 3) << ","
        << Fixed(r.dz_m, 3) << "," << Fixed(r.rms_before_m, 4) << "," << Fixed(r.rms_after_m, 4)
        << "," << Fixed(r.read_s * 1e3, 1) << "," << Fixed(r.detect_s * 1e3, 1) << ","
        << Fixed(r.refine_s * 1e3, 1) << "," << Fixed(r.fuse_s * 1e3, 1) << "\n";
  }
  if (Status s = od::io::WriteFileAtomic(staging / "poses.tum", tum); !s) return Fail(s.message());
  if (Status s = od::io::WriteFileAtomic(staging / "frames.csv", csv.str()); !s) {
    return Fail(s.message());
  }
  times.write_s = SecondsSince(write_start);

  // Summary.
  const int n = static_cast<int>(records.size());
  const double wall_s = earlier_wall_s + SecondsSince(run_start);  // all runs of a resumed map
  const map::MapMemory memory = terrain.Memory();
  Expected<map::CellBox> bounds = map::ExportBounds(terrain);
  json summary;
  summary["input"] = source->Describe();
  summary["frames"] = n;
  const int imu_frames = static_cast<int>(std::count_if(
      records.begin(), records.end(), [](const FrameRecord& r) { return r.tilt_from_imu; }));
  summary["imu_tilt_frames"] = imu_frames;
  summary["distance_driven_m"] = distance_m;
  summary["duration_s"] = records.back().stamp_s - records.front().stamp_s;
  summary["map"] = {{"mode", settings->map.window_size_m > 0 ? "online" : "offline"},
                    {"window_size_m", settings->map.window_size_m},
                    {"cell_size_m", settings->map.cell_size_m},
                    {"voxel_size_m", settings->map.voxel_size_m},
                    {"grid_bytes", memory.grid_bytes},
                    {"octree_bytes", memory.octree_bytes},
                    {"octree_leaves", memory.octree_leaves}};
  if (bounds) {
    summary["map"]["extent_cells"] = {bounds->size().x(), bounds->size().y()};
  }
  int lethal = 0, known = 0;
  {
    const map::TerrainGrid& g = terrain.grid();
    for (int j = 0; j < g.extent().y(); ++j) {
      for (int i = 0; i < g.extent().x(); ++i) {
        const map::Cell& c = g.At(g.min_index() + map::CellIndex(i, j));
        lethal += c.lethal ? 1 : 0;
        known += c.observed ? 1 : 0;
      }
    }
  }
  summary["map"]["observed_cells"] = known;
  summary["map"]["lethal_cells"] = lethal;
  json obstacles = json::array();
  for (const map::Obstacle& o : terrain.obstacles()) obstacles.push_back(ObstacleBrief(o));
  summary["obstacles"] = {{"live", terrain.obstacles().size()},
                          {"retired", terrain.obstacles_retired()},
                          {"list", obstacles}};
  if (settings->tilt.refine) {
    double sum_before = 0.0, sum_after = 0.0;
    int counted = 0;
    for (const FrameRecord& r : records) {
      if (!r.refined) continue;
      sum_before += r.rms_before_m;
      sum_after += r.rms_after_m;
      ++counted;
    }
    summary["tilt"] = {{"refine", true},
                       {"refined_frames", refined_frames},
                       {"final_correction_deg",
                        {records.back().d_roll_rad / kDeg, records.back().d_pitch_rad / kDeg}},
                       {"final_dz_m", records.back().dz_m},
                       {"mean_rms_before_m", counted ? sum_before / counted : 0.0},
                       {"mean_rms_after_m", counted ? sum_after / counted : 0.0}};
  } else {
    summary["tilt"] = {{"refine", false}};
  }
  summary["time_s"] = {{"read", times.read_s},     {"detect", times.detect_s},
                       {"refine", times.refine_s}, {"fuse", times.fuse_s},
                       {"write", times.write_s},   {"checkpoint", times.checkpoint_s},
                       {"total", wall_s}};
  summary["frames_per_s"] = wall_s > 0 ? n / wall_s : 0.0;
  if (truth) {
    json objects = json::array();
    for (const TruthObject& t : truth->objects) {
      objects.push_back({{"id", t.id},
                         {"name", t.name},
                         {"is_obstacle", t.is_obstacle},
                         {"x", t.centre.x()},
                         {"y", t.centre.y()},
                         {"found", t.found},
                         {"distance_to_lethal_m", t.distance_m},
                         {"map_obstacle", t.obstacle_id}});
    }
    summary["truth"] = {{"world", truth->world},
                        {"obstacles", truth->obstacles},
                        {"found", truth->found},
                        {"non_obstacles_marked", truth->marked_non_obstacles},
                        {"false_obstacles", truth->false_obstacles},
                        {"false_obstacle_ids", truth->false_obstacle_ids},
                        {"lethal_iou", truth->iou},
                        {"elevation_rms_m", truth->elevation_rms_m},
                        {"elevation_max_error_m", truth->elevation_max_m},
                        {"elevation_cells", truth->elevation_cells},
                        {"objects", objects}};
  }
  std::ostringstream text;
  text << "cairn map: " << n << " frames from " << summary["input"]["path"].get<std::string>()
       << " (" << summary["input"]["kind"].get<std::string>() << "), " << Fixed(distance_m, 1)
       << " m driven in " << Fixed(summary["duration_s"].get<double>(), 1) << " s of data\n"
       << "  poses: " << source->trajectory().source() << " (IMU tilt on " << imu_frames << "/" << n
       << " frames)\n"
       << "  map: " << summary["map"]["mode"].get<std::string>() << ", cell "
       << settings->map.cell_size_m << " m, voxel " << settings->map.voxel_size_m << " m, " << known
       << " cells observed, " << lethal << " lethal\n"
       << "  obstacles: " << terrain.obstacles().size() << " (" << terrain.obstacles_retired()
       << " retired on the way)\n";
  if (settings->tilt.refine) {
    text << "  tilt: refined " << refined_frames << "/" << n << " frames; correction at the end "
         << Fixed(records.back().d_roll_rad / kDeg, 2) << " deg roll, "
         << Fixed(records.back().d_pitch_rad / kDeg, 2) << " deg pitch, "
         << Fixed(records.back().dz_m, 3) << " m height; ground RMS "
         << Fixed(summary["tilt"]["mean_rms_before_m"].get<double>(), 3) << " -> "
         << Fixed(summary["tilt"]["mean_rms_after_m"].get<double>(), 3) << " m\n";
  }
  text << "  time: read " << Fixed(times.read_s, 2) << " s, detect " << Fixed(times.detect_s, 2)
       << " s, refine " << Fixed(times.refine_s, 2) << " s, fuse " << Fixed(times.fuse_s, 2)
       << " s, write " << Fixed(times.write_s, 2) << " s; " << Fixed(wall_s, 2) << " s in all, "
       << Fixed(n / wall_s, 2) << " frames/s\n";
  if (truth) {
    text << "  truth (" << truth->world << "): " << truth->found << "/" << truth->obstacles
         << " obstacles found, " << truth->marked_non_obstacles << " non-obstacles marked, "
         << truth->false_obstacles << " false obstacles; IoU of lethal cells and obstacle "
         << "footprints " << Fixed(truth->iou, 2) << "; elevation RMS error "
         << Fixed(truth->elevation_rms_m, 3) << " m over " << truth->elevation_cells << " cells\n";
    for (const TruthObject& t : truth->objects) {
      text << "    " << std::left << std::setw(12) << t.name << std::right
           << (t.is_obstacle ? " obstacle     " : " not obstacle ") << "at ("
           << Fixed(t.centre.x(), 1) << ", " << Fixed(t.centre.y(), 1)
           << "): " << (t.found ? "found" : (t.is_obstacle ? "MISSED" : "clear"));
      if (t.distance_m >= 0) text << ", nearest lethal cell " << Fixed(t.distance_m, 2) << " m";
      text << "\n";
    }
  }
  if (Status s = od::io::WriteFileAtomic(staging / "summary.json", summary.dump(2) + "\n"); !s) {
    return Fail(s.message());
  }
  if (Status s = od::io::WriteFileAtomic(staging / "summary.txt", text.str()); !s) {
    return Fail(s.message());
  }

  // Everything is written: move it into place.
  std::vector<fs::path> written;
  for (const fs::directory_entry& e : fs::directory_iterator(staging)) written.push_back(e.path());
  std::sort(written.begin(), written.end());
  for (const fs::path& p : written) {
    fs::rename(p, fs::path(options.out) / p.filename(), ec);
    if (ec) return Fail((fs::path(options.out) / p.filename()).string() + ": " + ec.message());
  }
  fs::remove(staging, ec);
  fs::remove(checkpoint, ec);  // the map files hold it all now
  cleanup.armed = false;
  std::cout << text.str() << "  files in " << options.out << ":";
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
  app->add_option("--rawlog", options->rawlog,
                  "MRPT rawlog with range frames and odometry (IMU used when present)")
      ->type_name("FILE");
  app->add_option("--label", options->label, "with --rawlog: the range sensor's label")
      ->type_name("L");
  app->add_option("--kitti", options->kitti,
                  "KITTI odometry sequence folder (velodyne/, calib.txt, times.txt, poses.txt), "
                  "or the data set's root with --sequence")
      ->type_name("DIR");
  app->add_option("--sequence", options->sequence, "with --kitti: DIR/sequences/NN")
      ->type_name("NN");
  app->add_option("--range", options->range, "with --kitti: scans A:B (inclusive)")
      ->type_name("A:B");
  app->add_option("--lidar", options->lidar, "with --kitti: sensor preset")->capture_default_str();
  app->add_option("--frames", options->frames,
                  "folder of 16-bit depth PNGs (named by stamp, or in pose order)")
      ->type_name("DIR");
  app->add_option("--poses", options->poses,
                  "with --frames: TUM file of the camera's poses (optical frame, z-up world)")
      ->type_name("FILE.tum");
  app->add_option("--intrinsics", options->intrinsics,
                  "with --frames: camera YAML (default DIR/intrinsics.yaml)")
      ->type_name("FILE");
  app->add_option("--config", options->config,
                  "settings YAML: detector, rules, stereo, map and tilt sections "
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
  app->add_flag("--no-refine-tilt", options->no_refine_tilt, "do not (overrides the config)")
      ->excludes(refine);
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
  app->add_option("--interrupt-after", options->interrupt_after,
                  "testing: interrupt the run (SIGINT) after N frames")
      ->group("");  // hidden
  app->add_option("--progress-every", options->progress_every,
                  "when stderr is not a terminal: a progress line every N frames")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
#ifdef CAIRN_HAVE_SYNTH
  app->add_option("--truth", options->truth,
                  "world YAML of a synthetic sequence: score the obstacles and the elevation")
      ->type_name("WORLD.yaml");
#endif
  app->footer(
      "Writes into DIR: map.bt, map.ot, obstacles.ot (OctoMap), cost.yaml + cost.pgm "
      "(map_server), cost.png, overlay.png, elevation.tiff + elevation.yaml, obstacles.json, "
      "poses.tum, frames.csv, summary.json, summary.txt. Exit 1 on bad input (nothing "
      "written; a checkpoint of an earlier interruption stays), 130 when interrupted (the map so far kept in DIR/map.checkpoint: run again "
      "with --resume).");
  return {app, [options] { return RunMap(*options); }};
}

}  // namespace cairn::apps
