// Detector speed, stage by stage, on the frames users judge it by: the KITTI 00 scan 0
// (HDL-64E), the RELLIS-3D OS1-64 scan (both in ../shared/datasets), the bundled 640 x 480
// demo frame, the TUM office Kinect frame, seeded rendered views of growing size, and
// HDL-64E scans of the dense_forest world of growing azimuth resolution.
//
// Every frame is also run through references in the same process, so that each figure
// comes with its ratio:
//  - region scan: the earlier exact method (od::DetectRegionScan), 1 thread;
//  - brute force: the O(N^2) definition, on small frames;
//  - floor: one pass that any detector must make (level-frame points and a 3x3 min/max of
//    height over the range image), the physical limit to compare with.
// The exact detector's result is compared with the reference on every frame it times; the
// benchmark fails (SkipWithError, non-zero exit) when they differ. Quote medians:
//   cairn_detector_benchmark --benchmark_repetitions=5 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sim/random_scene.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/world.hpp"
#include "detection_internal.hpp"  // libod/src: the features stage
#include "pair_search.hpp"         // libod/src: the candidates stage

namespace {

using namespace cairn;  // NOLINT: a benchmark file
using Clock = std::chrono::steady_clock;

const std::string kSource = CAIRN_SOURCE_DIR;
bool g_differs = false;  // an exact result differed from its reference: exit 1
const std::string kShared = CAIRN_SHARED_DATASETS;

// One benchmark frame: the range image, its settings, and how it was made (for the
// range-image stage).
struct Frame {
  std::string name;
  od::RangeImage image;
  od::io::DetectSettings settings;
  std::function<Expected<od::RangeImage>()> make;  // the range image from its file's data
  // LiDAR: the scan's layout (rings, columns) found from its points, as readers do per scan.
  std::function<Expected<od::FoundLayout>()> layout;
  // The reference result (region scan or brute force) and its time [ms], made once.
  std::unique_ptr<od::Detection> reference;
  std::string reference_name;
  double reference_ms = 0.0;
  double floor_ms = 0.0;
};

Expected<od::io::DetectSettings> Settings(const std::string& config) {
  // The presets may configure the Mapper too (config/default.yaml); its sections are the
  // Mapper's to read.
  return od::io::LoadDetectSettings(kSource + "/config/" + config, {"map", "tilt", "frames"});
}

Expected<Frame> LidarFrame(const std::string& name, const std::string& path,
                           const std::string& sensor, const std::string& config) {
  Expected<od::PointCloud> cloud = od::io::ReadPointFile(path);
  if (!cloud) return cloud.error();
  od::LayoutOptions options;
  Expected<od::SphericalModel> preset = od::SphericalModel::Preset(sensor);
  if (!preset) return preset.error();
  options.preset = *preset;
  Expected<od::FoundLayout> layout = od::FindLayout(*cloud, options, path);
  if (!layout) return layout.error();
  Expected<od::io::DetectSettings> settings = Settings(config);
  if (!settings) return settings.error();
  Frame f;
  f.name = name;
  f.settings = *settings;
  auto points = std::make_shared<od::PointCloud>(std::move(*cloud));
  auto found = std::make_shared<od::FoundLayout>(std::move(*layout));
  f.make = [points, found] {
    return od::RangeImage::FromPoints(points->points, found->model, Eigen::Vector3d::UnitZ(),
                                      found->rows, found->cols);
  };
  f.layout = [points, options, path] { return od::FindLayout(*points, options, path); };
  Expected<od::RangeImage> image = f.make();
  if (!image) return image.error();
  f.image = std::move(*image);
  return f;
}

// The gallery's dense_forest world scanned by its HDL-64E from 1.8 m above the terrain at
// the origin, with `azimuth_steps` columns per revolution (the scan's width).
Expected<Frame> ForestScan(int azimuth_steps) {
  Expected<sim::World> world = sim::LoadWorld(kSource + "/datasets/worlds/dense_forest.yaml");
  if (!world) return world.error();
  if (!world->lidar) return Error{"dense_forest.yaml: no lidar"};
  sim::LidarSpec spec = *world->lidar;
  spec.azimuth_steps = azimuth_steps;
  Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
  T_world_lidar.translation() =
      Eigen::Vector3d(0.0, 0.0, world->scene.terrain().Height(0.0, 0.0) + 1.8);
  Expected<sim::LidarScan> scan = sim::RenderLidar(world->scene, spec, T_world_lidar, 7);
  if (!scan) return scan.error();
  Expected<od::io::DetectSettings> settings = Settings("sensors/hdl-64e.yaml");
  if (!settings) return settings.error();
  od::SphericalModel model;
  model.width = spec.azimuth_steps;
  model.ring_elevation_rad = spec.elevations_rad;
  model.azimuth_start_rad = spec.AzimuthRad(0);
  Frame f;
  f.name = "forest" + std::to_string(azimuth_steps);
  f.settings = *settings;
  auto rendered = std::make_shared<sim::LidarScan>(std::move(*scan));
  f.make = [rendered, model] {
    return od::RangeImage::FromPoints(rendered->points, model, Eigen::Vector3d::UnitZ(),
                                      rendered->ring, rendered->column);
  };
  Expected<od::RangeImage> image = f.make();
  if (!image) return image.error();
  f.image = std::move(*image);
  return f;
}

Expected<Frame> DepthFrame(const std::string& name, const std::string& depth,
                           const std::string& intrinsics) {
  Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(intrinsics);
  if (!camera) return camera.error();
  Expected<od::Grid<float>> grid = od::io::ReadDepthImage(depth, *camera);
  if (!grid) return grid.error();
  Expected<od::io::DetectSettings> settings = Settings("default.yaml");
  if (!settings) return settings.error();
  Frame f;
  f.name = name;
  f.settings = *settings;
  auto data = std::make_shared<std::vector<float>>(std::move(grid->data));
  const od::io::CameraIntrinsics cam = *camera;
  f.make = [data, cam] { return od::RangeImage::FromDepth(*data, cam.model, cam.up); };
  Expected<od::RangeImage> image = f.make();
  if (!image) return image.error();
  f.image = std::move(*image);
  return f;
}

// A seeded random view, width x (3/4 width), with `objects` obstacles.
Expected<Frame> RenderedFrame(int width, int objects = 12) {
  sim::RandomSceneOptions options;
  options.width = width;
  options.height = width * 3 / 4;
  options.min_objects = options.max_objects = objects;
  const sim::RandomView view = sim::MakeRandomView(2002, options);
  Expected<sim::DepthFrame> frame = sim::RenderDepth(view.scene, view.camera);
  if (!frame) return frame.error();
  Expected<od::io::DetectSettings> settings = Settings("default.yaml");
  if (!settings) return settings.error();
  Frame f;
  f.name = "rendered" + std::to_string(width) + "_" + std::to_string(objects);
  f.settings = *settings;
  auto rendered = std::make_shared<sim::DepthFrame>(std::move(*frame));
  f.make = [rendered] {
    return od::RangeImage::FromDepth(rendered->depth_m, rendered->model, rendered->up_optical);
  };
  Expected<od::RangeImage> image = f.make();
  if (!image) return image.error();
  f.image = std::move(*image);
  return f;
}

double MillisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

od::DetectorConfig OneThread(const Frame& f) {
  od::DetectorConfig c = f.settings.detector;
  c.search = od::SearchMode::kExact;
  c.threads = 1;
  return c;
}

// The one-pass floor: every point into the level frame, then the 3x3 height min and max
// (separable: rows, then columns), as any detector must at least do.
float Floor(const od::RangeImage& image) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int w = image.width(), h = image.height(), n = image.size();
  const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();
  std::vector<float> lo(n), hi(n), row_lo(n), row_hi(n);
  for (int i = 0; i < n; ++i) {
    const float z = R(2, 0) * image.x()[i] + R(2, 1) * image.y()[i] + R(2, 2) * image.z()[i];
    const bool valid = image.valid(i);
    lo[i] = valid ? z : kInf;
    hi[i] = valid ? z : -kInf;
  }
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const int i = r * w + c, a = c > 0 ? i - 1 : i, b = c + 1 < w ? i + 1 : i;
      row_lo[i] = std::min(lo[a], std::min(lo[i], lo[b]));
      row_hi[i] = std::max(hi[a], std::max(hi[i], hi[b]));
    }
  }
  float spread = 0.0f;
  for (int r = 0; r < h; ++r) {
    const int up = r > 0 ? -w : 0, down = r + 1 < h ? w : 0;
    for (int c = 0; c < w; ++c) {
      const int i = r * w + c;
      const float l = std::min(row_lo[i + up], std::min(row_lo[i], row_lo[i + down]));
      const float u = std::max(row_hi[i + up], std::max(row_hi[i], row_hi[i + down]));
      if (l < u) spread = std::max(spread, u - l);
    }
  }
  return spread;
}

// Frames by name, made once. Real frames whose files are absent are null.
Frame* Get(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Frame>> cache;
  auto it = cache.find(name);
  if (it != cache.end()) return it->second.get();
  Expected<Frame> made = Error{"unknown frame " + name};
  if (name == "kitti") {
    made = LidarFrame(name, kShared + "/kitti-seq00-0-10/velodyne/000000.bin", "HDL-64E",
                      "sensors/hdl-64e.yaml");
  } else if (name == "rellis") {
    made = LidarFrame(name, kShared + "/rellis3d-000104/os1_bin/000104.bin", "OS1-64",
                      "sensors/os1-64.yaml");
  } else if (name == "demo") {
    made = DepthFrame(name, kSource + "/datasets/frames/demo/depth.png",
                      kSource + "/datasets/frames/demo/intrinsics.yaml");
  } else if (name == "tum") {
    made = DepthFrame(name, kShared + "/rgbd-tum-frame/TUM_depth.png",
                      kSource + "/datasets/real/tum-kinect.yaml");
  } else if (name.rfind("rendered", 0) == 0) {
    made = RenderedFrame(std::atoi(name.c_str() + 8));
  } else if (name.rfind("objects", 0) == 0) {  // density: 320 x 240 with N obstacles
    made = RenderedFrame(320, std::atoi(name.c_str() + 7));
  } else if (name.rfind("forest", 0) == 0) {  // LiDAR: 64 x N
    made = ForestScan(std::atoi(name.c_str() + 6));
  }
  if (!made) {
    cache[name] = nullptr;
    return nullptr;
  }
  auto frame = std::make_unique<Frame>(std::move(*made));
  // The reference: brute force on small frames, else the region scan; and the floor.
  const od::DetectorConfig config = OneThread(*frame);
  const bool small = frame->image.valid_count() <= 20000;
  const Clock::time_point start = Clock::now();
  Expected<od::Detection> ref =
      small ? od::DetectBruteForce(frame->image, config) : od::DetectRegionScan(frame->image, config);
  frame->reference_ms = MillisecondsSince(start);
  frame->reference_name = small ? "brute_force" : "region_scan";
  if (ref) frame->reference = std::make_unique<od::Detection>(std::move(*ref));
  std::vector<double> floors;
  for (int k = 0; k < 5; ++k) {
    const Clock::time_point s = Clock::now();
    benchmark::DoNotOptimize(Floor(frame->image));
    floors.push_back(MillisecondsSince(s));
  }
  std::sort(floors.begin(), floors.end());
  frame->floor_ms = floors[2];
  return (cache[name] = std::move(frame)).get();
}

const std::vector<std::string> kFrames = {"kitti", "rellis", "demo", "tum", "rendered160",
                                          "rendered320", "rendered640"};

// Same obstacle points, segments (numbering is deterministic), feet and raised points.
bool SameAsReference(const od::Detection& d, const Frame& f) {
  if (!f.reference) return false;
  const od::Detection& r = *f.reference;
  if (d.labels != r.labels || d.foot != r.foot || d.segments.size() != r.segments.size()) {
    return false;
  }
  for (std::size_t s = 0; s < d.segments.size(); ++s) {
    if (d.segments[s].raised_count != r.segments[s].raised_count) return false;
  }
  return true;
}

void Counters(benchmark::State& state, const Frame& f, const od::Detection& d) {
  state.counters["valid_points"] = f.image.valid_count();
  state.counters["pairs"] = static_cast<double>(d.stats.pairs_compatible);
  state.counters["tested"] = static_cast<double>(d.stats.pairs_tested);
  state.counters["segments"] = static_cast<double>(d.segments.size());
  state.counters["node_pairs"] = static_cast<double>(d.stats.node_pairs);
  state.counters["blocks_accepted"] = static_cast<double>(d.stats.blocks_accepted);
}

// Per-iteration times, for the ratio counters (seconds of the median iteration).
double MedianMs(std::vector<double> ms) {
  if (ms.empty()) return 0.0;
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

// A frame whose reference failed: an error that fails the run (a benchmark that returns
// before its loop without one aborts the process).
bool NoReference(benchmark::State& state, const std::string& name, const Frame& f) {
  if (f.reference) return false;
  g_differs = true;
  state.SkipWithError((name + ": the reference (" + f.reference_name + ") failed").c_str());
  return true;
}

Frame* FrameOrSkip(benchmark::State& state, const std::string& name) {
  Frame* f = Get(name);
  if (f == nullptr) state.SkipWithError((name + ": its data is absent").c_str());
  return f;
}

// Runs `detect` once per iteration, timing each run into `ms`; returns the last result, or
// null after an error (the benchmark is then skipped with it).
template <typename F>
std::unique_ptr<od::Detection> TimedRuns(benchmark::State& state, std::vector<double>& ms,
                                         F&& detect) {
  std::unique_ptr<od::Detection> last;
  for (auto _ : state) {
    const Clock::time_point start = Clock::now();
    Expected<od::Detection> d = detect();
    ms.push_back(MillisecondsSince(start));
    if (!d) {
      state.SkipWithError(d.error().message.c_str());
      return nullptr;
    }
    last = std::make_unique<od::Detection>(std::move(*d));
  }
  return last;
}

// The exact detector (od::Detect); range(0): threads (1 or 0 = every core).
void BM_Detect(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  od::DetectorConfig config = OneThread(*f);
  config.threads = static_cast<int>(state.range(0));
  std::vector<double> ms;
  const std::unique_ptr<od::Detection> last =
      TimedRuns(state, ms, [&] { return od::Detect(f->image, config); });
  if (last == nullptr) return;
  if (!SameAsReference(*last, *f)) {
    g_differs = true;
    state.SkipWithError((name + ": the exact detector differs from " + f->reference_name).c_str());
    return;
  }
  Counters(state, *f, *last);
  const double med = MedianMs(ms);
  state.counters[f->reference_name + "_x"] = f->reference_ms / med;  // how many times faster
  state.counters["floor_x"] = med / f->floor_ms;                     // how many floors it takes
}

// The earlier exact method, the reference (1 thread).
void BM_RegionScan(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  for (auto _ : state) {
    Expected<od::Detection> d = od::DetectRegionScan(f->image, OneThread(*f));
    benchmark::DoNotOptimize(d);
  }
}

void BM_PaperWindow(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  od::DetectorConfig config = OneThread(*f);
  config.search = od::SearchMode::kPaperWindow;
  for (auto _ : state) benchmark::DoNotOptimize(od::Detect(f->image, config));
}

// The column baseline, checked against its definition (od::DetectColumnsBruteForce, timed
// once in the same process: the counter brute_force_x).
void BM_Columns(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  od::ColumnConfig config = od::ColumnConfig::From(f->settings.detector);
  config.min_blob_pixels = f->settings.min_blob_pixels;
  std::vector<double> ms;
  const std::unique_ptr<od::Detection> last =
      TimedRuns(state, ms, [&] { return od::DetectColumns(f->image, config); });
  if (last == nullptr) return;
  const Clock::time_point start = Clock::now();
  const Expected<od::Detection> brute = od::DetectColumnsBruteForce(f->image, config);
  const double brute_ms = MillisecondsSince(start);
  bool same = brute && last->labels == brute->labels && last->foot == brute->foot &&
              last->segments.size() == brute->segments.size();
  for (std::size_t k = 0; same && k < last->segments.size(); ++k) {
    same = last->segments[k].raised_count == brute->segments[k].raised_count;
  }
  if (!same) {
    g_differs = true;
    state.SkipWithError((name + ": the column baseline differs from its definition").c_str());
    return;
  }
  Counters(state, *f, *last);
  const double med = MedianMs(ms);
  state.counters["brute_force_x"] = brute_ms / med;
  state.counters["floor_x"] = med / f->floor_ms;
}

void BM_BruteForce(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  for (auto _ : state) benchmark::DoNotOptimize(od::DetectBruteForce(f->image, OneThread(*f)));
}

void BM_Floor(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  for (auto _ : state) benchmark::DoNotOptimize(Floor(f->image));
}

void BM_RangeImage(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  for (auto _ : state) benchmark::DoNotOptimize(f->make());
}

// A LiDAR scan's layout from its points (od::FindLayout), which every reader of scans runs
// before the range image; camera frames have none and skip.
void BM_Layout(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  if (!f->layout) {
    state.SkipWithError("no layout to find (a camera frame)");
    return;
  }
  for (auto _ : state) benchmark::DoNotOptimize(f->layout());
}

void BM_Rules(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr || NoReference(state, name, *f)) return;
  for (auto _ : state) {
    benchmark::DoNotOptimize(od::Classify(*f->reference, f->settings.rules));
  }
}

// The features stage alone (internal::BuildDetection, one thread): labels, each segment's
// features and the feet, from the reference's segments. The detectors' raised marks stay
// inside them; every segment point that is not a foot stands in for them here.
void BM_Features(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr || NoReference(state, name, *f)) return;
  const od::Detection& r = *f->reference;
  const od::internal::LevelPoints level(f->image);
  std::vector<std::int32_t> component(r.labels.size(), -1), first(r.segments.size() + 1, -1);
  std::vector<std::uint8_t> raised(r.labels.size(), 0);
  for (std::size_t i = 0; i < r.labels.size(); ++i) {
    const int id = r.labels[i];
    if (id == 0) continue;
    if (first[id] < 0) first[id] = static_cast<std::int32_t>(i);
    component[i] = first[id];
    raised[i] = r.foot[i] == 0;
  }
  const float min_height = static_cast<float>(f->settings.detector.min_height_m);
  od::Detection last;
  for (auto _ : state) {
    // The stage takes the names and makes them the labels: a copy of them each time (a
    // memcpy into the last labels' storage, timed with the stage).
    std::vector<std::int32_t> names = std::move(last.labels);
    names.assign(component.begin(), component.end());
    last = od::internal::BuildDetection(f->image, level, std::move(names), raised, min_height,
                                        r.stats);
    benchmark::DoNotOptimize(last);
  }
  // The same labels, feet and features as the reference's (but the raised counts, which
  // the stand-in marks change): the stage computed them the same way.
  bool same =
      last.labels == r.labels && last.foot == r.foot && last.segments.size() == r.segments.size();
  for (std::size_t k = 0; same && k < r.segments.size(); ++k) {
    const od::SegmentFeatures &a = last.segments[k], &b = r.segments[k];
    same = a.point_count == b.point_count && a.foot_count == b.foot_count &&
           a.bbox_min == b.bbox_min && a.bbox_max == b.bbox_max && a.centroid == b.centroid &&
           a.slope_points == b.slope_points && a.slope_mean_rad == b.slope_mean_rad &&
           a.slope_max_rad == b.slope_max_rad && a.ground_height_m == b.ground_height_m &&
           a.range_mean_m == b.range_mean_m && a.range_min_m == b.range_min_m &&
           a.row_min == b.row_min && a.row_max == b.row_max && a.col_min == b.col_min &&
           a.col_max == b.col_max;
  }
  if (!same) {
    g_differs = true;
    state.SkipWithError((name + ": the features differ from the reference's").c_str());
    return;
  }
  state.counters["points"] = static_cast<double>(last.stats.obstacle_points);
  state.counters["segments"] = static_cast<double>(last.segments.size());
}

// The exact detector's first stage (od::internal::FindCandidates), one thread: the points that
// may be the lower or the upper point of a pair. Checked to keep every obstacle point of the
// reference (each is one or the other), and counted: the share of the valid points kept.
void BM_Candidates(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr || NoReference(state, name, *f)) return;
  const od::DetectorConfig config = OneThread(*f);
  const od::internal::LevelPoints level(f->image, 1, config.min_range_m);
  const od::PairTest test(config);
  od::internal::Candidates last;
  for (auto _ : state) {
    last = od::internal::FindCandidates(level, test, 1);
    benchmark::DoNotOptimize(last);
  }
  const std::vector<std::int32_t>& labels = f->reference->labels;
  std::int64_t kept = 0, valid = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    kept += last.lower[i] || last.upper[i];
    valid += level.z[i] == level.z[i];  // min_range's returns are not
    if (labels[i] != 0 && !last.lower[i] && !last.upper[i]) {
      g_differs = true;
      state.SkipWithError((name + ": an obstacle point is no candidate").c_str());
      return;
    }
  }
  state.counters["kept"] =
      static_cast<double>(kept) / static_cast<double>(std::max<std::int64_t>(1, valid));
}

// The exact detector's trees (od::internal::PointTree) of the lower and the upper candidates,
// one thread, with Detect's blocks: checked to hold every candidate once (each tree's stored
// pixels, sorted, are its candidates; its root spans them all).
void BM_Trees(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  const od::DetectorConfig config = OneThread(*f);
  const od::internal::LevelPoints level(f->image, 1, config.min_range_m);
  const od::internal::Candidates candidates =
      od::internal::FindCandidates(level, od::PairTest(config), 1);
  const od::internal::BlockShape block = od::internal::BlockShapeFor(f->image);
  const int width = f->image.width(), height = f->image.height();
  std::optional<od::internal::PointTree> lower, upper;
  for (auto _ : state) {
    lower.emplace(level, candidates.lower, width, height, block.rows, block.cols);
    upper.emplace(level, candidates.upper, width, height, block.rows, block.cols);
    benchmark::DoNotOptimize(lower->nodes.data());
    benchmark::DoNotOptimize(upper->nodes.data());
  }
  const auto holds_its_candidates = [](const od::internal::PointTree& tree,
                                       const std::vector<std::uint8_t>& mask) {
    std::vector<std::int32_t> stored = tree.pixel, wanted;
    std::sort(stored.begin(), stored.end());
    for (std::size_t i = 0; i < mask.size(); ++i) {
      if (mask[i] != 0) wanted.push_back(static_cast<std::int32_t>(i));
    }
    if (wanted.empty()) return tree.roots.size() == 1 && tree.roots[0] < 0;
    const od::internal::PointTree::Node& root = tree.nodes[tree.roots[0]];
    return stored == wanted && root.begin == 0 && root.end == tree.size();
  };
  if (lower && (!holds_its_candidates(*lower, candidates.lower) ||
                !holds_its_candidates(*upper, candidates.upper))) {
    g_differs = true;
    state.SkipWithError((name + ": the trees do not hold every candidate once").c_str());
    return;
  }
  state.counters["points"] = lower ? static_cast<double>(lower->size() + upper->size()) : 0.0;
}

// Growth of the cost: Hmax (range(0), cm) on a frame, one thread.
void BM_DetectHmax(benchmark::State& state, const std::string& name) {
  Frame* f = FrameOrSkip(state, name);
  if (f == nullptr) return;
  od::DetectorConfig config = OneThread(*f);
  config.max_height_m = state.range(0) / 100.0;
  od::Detection last;
  for (auto _ : state) {
    Expected<od::Detection> d = od::Detect(f->image, config);
    benchmark::DoNotOptimize(d);
    last = std::move(*d);
  }
  Counters(state, *f, last);
}

void Register() {
  const auto ms = [](benchmark::internal::Benchmark* b) {
    return b->Unit(benchmark::kMillisecond)->UseRealTime();
  };
  for (const std::string& name : kFrames) {
    ms(benchmark::RegisterBenchmark(("Floor/" + name).c_str(), BM_Floor, name));
    ms(benchmark::RegisterBenchmark(("RangeImage/" + name).c_str(), BM_RangeImage, name));
    if (name == "kitti" || name == "rellis") {
      ms(benchmark::RegisterBenchmark(("Layout/" + name).c_str(), BM_Layout, name));
    }
    ms(benchmark::RegisterBenchmark(("Detect/" + name).c_str(), BM_Detect, name))
        ->ArgName("threads")
        ->Arg(1)
        ->Arg(0);
    ms(benchmark::RegisterBenchmark(("Columns/" + name).c_str(), BM_Columns, name));
    ms(benchmark::RegisterBenchmark(("Candidates/" + name).c_str(), BM_Candidates, name));
    ms(benchmark::RegisterBenchmark(("Trees/" + name).c_str(), BM_Trees, name));
    ms(benchmark::RegisterBenchmark(("Features/" + name).c_str(), BM_Features, name));
    ms(benchmark::RegisterBenchmark(("Rules/" + name).c_str(), BM_Rules, name));
    ms(benchmark::RegisterBenchmark(("PaperWindow/" + name).c_str(), BM_PaperWindow, name));
    // The region scan takes tens of seconds on the TUM frame: one iteration there.
    auto* scan = ms(benchmark::RegisterBenchmark(("RegionScan/" + name).c_str(), BM_RegionScan,
                                                 name));
    if (name == "tum") scan->Iterations(1);
  }
  // Growth with obstacle density (the exact detector, one thread, on 320 x 240 views).
  for (int objects : {0, 6, 12, 24, 48}) {
    const std::string name = "objects" + std::to_string(objects);
    ms(benchmark::RegisterBenchmark(("Detect/" + name).c_str(), BM_Detect, name))
        ->ArgName("threads")
        ->Arg(1);
  }
  for (const char* name : {"rendered80", "rendered160"}) {
    ms(benchmark::RegisterBenchmark((std::string("BruteForce/") + name).c_str(), BM_BruteForce,
                                    std::string(name)));
  }
  // Growth with the LiDAR scan's width (64 rings, one thread).
  for (int steps : {512, 1024, 2048, 4096}) {
    const std::string name = "forest" + std::to_string(steps);
    ms(benchmark::RegisterBenchmark(("Detect/" + name).c_str(), BM_Detect, name))
        ->ArgName("threads")
        ->Arg(1);
  }
  // Growth with Hmax, on a camera frame and a LiDAR scan.
  for (const char* name : {"demo", "kitti"}) {
    ms(benchmark::RegisterBenchmark((std::string("DetectHmax/") + name).c_str(), BM_DetectHmax,
                                    std::string(name)))
        ->ArgName("hmax_cm")
        ->Arg(50)
        ->Arg(100)
        ->Arg(150)
        ->Arg(200);
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  Register();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (g_differs) std::fprintf(stderr, "an exact detection differed from its reference\n");
  return g_differs ? 1 : 0;
}
