// TerrainMap::Integrate per frame, on drives through the gallery's worlds: a 640 x 480 range
// camera through poles_and_rocks and a 64 x 2048 HDL-64E scan through dense_forest. Frames
// are rendered and detected once (config/default.yaml's detector and rules); each iteration
// integrates the next frame of the drive into the same map, as a sequence does (the map
// starts afresh when the drive wraps, outside the timing). range(0) is max_range [m].
//   cairn_map_benchmark --benchmark_repetitions=3 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/world.hpp"

namespace {

using namespace cairn;  // NOLINT: a benchmark file

struct Frame {
  od::RangeImage image;
  od::Detection detection;
  od::Classification classification;
  Eigen::Isometry3d T_world_sensor;
  double stamp_s = 0.0;
};

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// `count` frames of a drive along +x through `world_name`, every 0.8 m.
std::vector<Frame> MakeDrive(const std::string& world_name, bool lidar, int count) {
  const std::string dir = std::string(CAIRN_SOURCE_DIR);
  Expected<sim::World> world = sim::LoadWorld(dir + "/datasets/worlds/" + world_name + ".yaml");
  Expected<od::io::DetectSettings> settings =
      od::io::LoadDetectSettings(dir + "/config/default.yaml");
  if (!world || !settings) return {};
  sim::DriveSpec spec;
  spec.waypoints = {{0.0, 0.0}, {0.8 * count, 0.0}};
  spec.speed_mps = 2.0;
  spec.frame_rate_hz = 2.5;
  spec.sensor_pitch_rad = 8.0 * kDeg;
  Expected<sim::Drive> drive = sim::SimulateDrive(
      world->scene.terrain(), spec,
      lidar ? sim::SensorFrame::kLidar : sim::SensorFrame::kCameraOptical, 1, count);
  if (!drive) return {};
  sim::RangeCameraSpec camera = world->camera;
  camera.model.width = 640;
  camera.model.height = 480;
  camera.model.fx = camera.model.fy = 520.0;
  camera.model.cx = 319.5;
  camera.model.cy = 239.5;
  std::vector<Frame> frames;
  for (const sim::DriveSample& s : drive->samples) {
    Frame f;
    f.T_world_sensor = s.T_world_sensor;
    f.stamp_s = s.stamp_s;
    if (lidar) {
      Expected<sim::LidarScan> scan =
          sim::RenderLidar(world->scene, *world->lidar, s.T_world_sensor, s.index + 1);
      if (!scan) return {};
      od::SphericalModel model;
      model.width = world->lidar->azimuth_steps;
      model.ring_elevation_rad = world->lidar->elevations_rad;
      model.azimuth_start_rad = world->lidar->AzimuthRad(0);
      const Eigen::Vector3d up = s.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
      auto image = od::RangeImage::FromPoints(scan->points, model, up, scan->ring, scan->column);
      if (!image) return {};
      f.image = std::move(*image);
    } else {
      sim::Camera cam;
      cam.model = camera.model;
      cam.T_world_camera = s.T_world_sensor;
      Expected<sim::DepthFrame> depth =
          sim::RenderRangeCamera(world->scene, camera, cam, s.index + 1);
      if (!depth) return {};
      auto image = od::RangeImage::FromDepth(depth->depth_m, depth->model, depth->up_optical);
      if (!image) return {};
      f.image = std::move(*image);
    }
    auto detection = od::Detect(f.image, settings->detector);
    if (!detection) return {};
    f.detection = std::move(*detection);
    auto classes = od::Classify(f.detection, settings->rules);
    if (!classes) return {};
    f.classification = std::move(*classes);
    frames.push_back(std::move(f));
  }
  return frames;
}

const std::vector<Frame>& Drive(bool lidar) {
  static std::map<bool, std::vector<Frame>> cache;
  auto it = cache.find(lidar);
  if (it == cache.end()) {
    it = cache.emplace(lidar, MakeDrive(lidar ? "dense_forest" : "poles_and_rocks", lidar, 12))
             .first;
  }
  return it->second;
}

void Integrate(benchmark::State& state, bool lidar) {
  const std::vector<Frame>& frames = Drive(lidar);
  if (frames.empty()) {
    state.SkipWithError("cannot make the drive (datasets/worlds, config/default.yaml)");
    return;
  }
  map::MapConfig config;
  config.max_range_m = static_cast<double>(state.range(0));
  std::unique_ptr<map::TerrainMap> m;
  std::size_t next = 0;
  double free_voxels = 0.0, octree_s = 0.0, classify_s = 0.0, grid_s = 0.0;
  for (auto _ : state) {
    if (m == nullptr || next == frames.size()) {
      state.PauseTiming();
      m = std::make_unique<map::TerrainMap>(map::TerrainMap::Create(config).value());
      next = 0;
      state.ResumeTiming();
    }
    const Frame& f = frames[next];
    auto summary = m->Integrate(f.image, f.detection, f.classification, f.T_world_sensor, f.stamp_s,
                                static_cast<std::int64_t>(next));
    benchmark::DoNotOptimize(summary);
    free_voxels += static_cast<double>(summary->voxels_free);
    octree_s += summary->octree_s;
    classify_s += summary->classify_s;
    grid_s += summary->grid_s;
    ++next;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["pixels"] = frames.front().image.size();
  state.counters["free_voxels"] = free_voxels / n;
  state.counters["octree_ms"] = 1e3 * octree_s / n;
  state.counters["classify_ms"] = 1e3 * classify_s / n;
  state.counters["grid_ms"] = 1e3 * grid_s / n;
}

void BM_IntegrateDepth640x480(benchmark::State& state) { Integrate(state, false); }
void BM_IntegrateLidar64x2048(benchmark::State& state) { Integrate(state, true); }

// One pass over the 12 frames of the drive per run.
BENCHMARK(BM_IntegrateDepth640x480)
    ->Arg(20)
    ->Arg(40)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_IntegrateLidar64x2048)
    ->Arg(20)
    ->Arg(40)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
