// The Mapper per frame (detect, tilt, fuse: map::Mapper::Process), on drives through the
// gallery's worlds: a 640 x 480 range camera through poles_and_rocks and a 64 x 2048 HDL-64E
// scan through dense_forest. Frames are rendered once; each iteration hands the next frame
// of the drive to the same Mapper (config/default.yaml's detector and rules), as a sequence
// does (the Mapper starts afresh when the drive wraps, outside the timing). range(0) is
// max_range [m]. The counters split the time: detection, and fusion by TerrainMap's stages.
//   cairn_map_benchmark --benchmark_repetitions=3 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cairn/map/mapper.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/world.hpp"

namespace {

using namespace cairn;  // NOLINT: a benchmark file

struct Frame {
  od::RangeImage image;
  Eigen::Isometry3d T_world_sensor;
  double stamp_s = 0.0;
};

// config/default.yaml's detector and rules (the struct defaults if it cannot be read).
const od::io::DetectSettings& Settings() {
  static const od::io::DetectSettings settings = [] {
    const Expected<od::io::DetectSettings> loaded =
        od::io::LoadDetectSettings(std::string(CAIRN_SOURCE_DIR) + "/config/default.yaml");
    return loaded ? *loaded : od::io::DetectSettings{};
  }();
  return settings;
}

constexpr double kDeg = 3.14159265358979323846 / 180.0;

// `count` frames of a drive along +x through `world_name`, every 0.8 m.
std::vector<Frame> MakeDrive(const std::string& world_name, bool lidar, int count) {
  const std::string dir = std::string(CAIRN_SOURCE_DIR);
  Expected<sim::World> world = sim::LoadWorld(dir + "/datasets/worlds/" + world_name + ".yaml");
  if (!world) return {};
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

void Process(benchmark::State& state, bool lidar) {
  const std::vector<Frame>& frames = Drive(lidar);
  if (frames.empty()) {
    state.SkipWithError("cannot make the drive (datasets/worlds, config/default.yaml)");
    return;
  }
  map::MapperConfig config;
  config.detector = Settings().detector;
  config.rules = Settings().rules;
  config.map.max_range_m = static_cast<double>(state.range(0));
  std::unique_ptr<map::Mapper> mapper;
  std::size_t next = 0;
  double free_voxels = 0.0, detect_s = 0.0, fuse_s = 0.0, octree_s = 0.0, classify_s = 0.0,
         grid_s = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    if (mapper == nullptr || next == frames.size()) {
      mapper = std::make_unique<map::Mapper>(map::Mapper::Create(config).value());
      next = 0;
    }
    const Frame& f = frames[next];
    od::RangeImage image = f.image;
    state.ResumeTiming();
    auto record = mapper->Process(std::move(image), f.T_world_sensor, f.stamp_s);
    benchmark::DoNotOptimize(record);
    if (!record || !record->used()) {
      state.SkipWithError("a frame was not fused");
      return;
    }
    free_voxels += static_cast<double>(record->fused.voxels_free);
    detect_s += record->detect_s;
    fuse_s += record->fuse_s;
    octree_s += record->fused.octree_s;
    classify_s += record->fused.classify_s;
    grid_s += record->fused.grid_s;
    ++next;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["pixels"] = frames.front().image.size();
  state.counters["free_voxels"] = free_voxels / n;
  state.counters["detect_ms"] = 1e3 * detect_s / n;
  state.counters["fuse_ms"] = 1e3 * fuse_s / n;
  state.counters["octree_ms"] = 1e3 * octree_s / n;
  state.counters["classify_ms"] = 1e3 * classify_s / n;
  state.counters["grid_ms"] = 1e3 * grid_s / n;
}

void BM_MapperDepth640x480(benchmark::State& state) { Process(state, false); }
void BM_MapperLidar64x2048(benchmark::State& state) { Process(state, true); }

// One pass over the 12 frames of the drive per run.
BENCHMARK(BM_MapperDepth640x480)
    ->Arg(20)
    ->Arg(40)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MapperLidar64x2048)
    ->Arg(20)
    ->Arg(40)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
