// The Mapper per frame (detect, tilt, fuse: map::Mapper::Process), on drives through the
// gallery's worlds: a 640 x 480 range camera through poles_and_rocks and a 64 x 2048 HDL-64E
// scan through dense_forest. Frames are rendered once; each iteration hands the next frame
// of the drive to the same Mapper (config/default.yaml's detector and rules), as a sequence
// does (the Mapper starts afresh when the drive wraps, outside the timing). range(0) is
// max_range [m]. The counters split the time: detection, the tilt step, and fusion by
// TerrainMap's stages.
//   Mapper*      the whole frame, tilt mode prior (the odometry pose as it is), on every
//                core (OneCore: the detector and the map on one thread);
//   MapperTilt/* the camera drive in each tilt mode, with the drive's raw IMU (100 Hz) for
//                gravity: tilt_ms is the stage that mode adds;
//   FreeRays/*   the free-space rays of a LiDAR-like frame (52,000 ends within 20 m, 0.1 m
//                voxels, in azimuth order as a scan gives them) into a brick set: `walk` as
//                TerrainMap casts them (ForEachRayKeyInTurn, four or eight rays at a time, into a
//                box of bits, then into a set indexed in the rays' box), `computeRayKeys` as
//                OctoMap does (each ray stored in a KeyRay, then inserted into a hashed set); one
//                thread. The walk's counter octomap_x is the reference's time over its own, both
//                measured in the same process; the sets are checked equal.
//   MapFiles     every file `cairn map` writes of the map the camera drive built
//                (map::WriteMapFiles: map.bt, map.ot, obstacles.ot, cost.pgm/.png,
//                elevation.tiff, obstacles.json), into a temporary folder.
//   cairn_map_benchmark --benchmark_repetitions=3 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "cairn/eval/drift_run.hpp"  // the drive's IMU as the Mapper takes it
#include "cairn/map/map_files.hpp"
#include "cairn/map/mapper.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/world.hpp"
#include "key_bricks.hpp"  // libmap/src: the free-space key set
#include "ray_keys.hpp"    // libmap/src: the ray walk

namespace {

using namespace cairn;  // NOLINT: a benchmark file

struct Frame {
  od::RangeImage image;
  Eigen::Isometry3d T_world_sensor;
  double stamp_s = 0.0;
  std::vector<map::ImuSample> imu;  ///< raw samples since the previous frame, body frame
};

struct DriveFrames {
  std::vector<Frame> frames;
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
};

// config/default.yaml's detector and rules (the struct defaults if it cannot be read).
const od::io::DetectSettings& Settings() {
  static const od::io::DetectSettings settings = [] {
    const Expected<od::io::DetectSettings> loaded = od::io::LoadDetectSettings(
        std::string(CAIRN_SOURCE_DIR) + "/config/default.yaml", map::MapperSettingsSections());
    return loaded ? *loaded : od::io::DetectSettings{};
  }();
  return settings;
}

// `count` frames of a drive along +x through `world_name`, every 0.8 m, with the raw IMU.
DriveFrames MakeDrive(const std::string& world_name, bool lidar, int count) {
  const std::string dir = std::string(CAIRN_SOURCE_DIR);
  Expected<sim::World> world = sim::LoadWorld(dir + "/datasets/worlds/" + world_name + ".yaml");
  if (!world) return {};
  sim::DriveSpec spec;
  spec.waypoints = {{0.0, 0.0}, {0.8 * count, 0.0}};
  spec.speed_mps = 2.0;
  spec.frame_rate_hz = 2.5;
  spec.sensor_pitch_rad = 8.0 * kDegToRad;
  const sim::SensorFrame sensor =
      lidar ? sim::SensorFrame::kLidar : sim::SensorFrame::kCameraOptical;
  Expected<sim::Drive> drive = sim::SimulateDrive(world->scene.terrain(), spec, sensor, 1, count);
  if (!drive) return {};
  DriveFrames out;
  out.T_body_sensor = drive->T_body_sensor;
  std::size_t next_imu = 0;
  sim::RangeCameraSpec camera = world->camera;
  camera.model.width = 640;
  camera.model.height = 480;
  camera.model.fx = camera.model.fy = 520.0;
  camera.model.cx = 319.5;
  camera.model.cy = 239.5;
  for (const sim::DriveSample& s : drive->samples) {
    Frame f;
    f.T_world_sensor = s.T_world_sensor;
    f.stamp_s = s.stamp_s;
    f.imu = eval::BodyImuUpTo(*drive, s.stamp_s, &next_imu);
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
    out.frames.push_back(std::move(f));
  }
  return out;
}

const DriveFrames& Drive(bool lidar) {
  static std::map<bool, DriveFrames> cache;
  auto it = cache.find(lidar);
  if (it == cache.end()) {
    it = cache.emplace(lidar, MakeDrive(lidar ? "dense_forest" : "poles_and_rocks", lidar, 12))
             .first;
  }
  return it->second;
}

// threads: the detector's and the map's (0: every core).
map::MapperConfig Config(double max_range_m, map::TiltMode tilt, int threads = 0) {
  map::MapperConfig config;
  config.detector = Settings().detector;
  config.rules = Settings().rules;
  config.detector.threads = threads;
  config.map.threads = threads;
  config.map.max_range_m = max_range_m;
  config.tilt.mode = tilt;
  return config;
}

std::unique_ptr<map::Mapper> NewMapper(const map::MapperConfig& config, const DriveFrames& drive) {
  auto mapper = std::make_unique<map::Mapper>(map::Mapper::Create(config).value());
  if (!mapper->SetSensorMount(drive.T_body_sensor)) return nullptr;
  return mapper;
}

void Process(benchmark::State& state, bool lidar, map::TiltMode tilt, int threads = 0) {
  const DriveFrames& drive = Drive(lidar);
  const std::vector<Frame>& frames = drive.frames;
  if (frames.empty()) {
    state.SkipWithError("cannot make the drive (datasets/worlds, config/default.yaml)");
    return;
  }
  const map::MapperConfig config = Config(static_cast<double>(state.range(0)), tilt, threads);
  std::unique_ptr<map::Mapper> mapper;
  std::size_t next = 0;
  double free_voxels = 0.0, detect_s = 0.0, tilt_s = 0.0, fuse_s = 0.0, octree_s = 0.0,
         classify_s = 0.0, grid_s = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    if (mapper == nullptr || next == frames.size()) {
      mapper = NewMapper(config, drive);
      next = 0;
    }
    const Frame& f = frames[next];
    od::RangeImage image = f.image;
    state.ResumeTiming();
    auto record = mapper->Process(std::move(image), f.T_world_sensor, f.stamp_s, f.imu);
    benchmark::DoNotOptimize(record);
    if (!record || !record->used()) {
      state.SkipWithError("a frame was not fused");
      return;
    }
    free_voxels += static_cast<double>(record->fused.voxels_free);
    detect_s += record->detect_s;
    tilt_s += record->tilt_s;
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
  state.counters["tilt_ms"] = 1e3 * tilt_s / n;
  state.counters["fuse_ms"] = 1e3 * fuse_s / n;
  state.counters["octree_ms"] = 1e3 * octree_s / n;
  state.counters["classify_ms"] = 1e3 * classify_s / n;
  state.counters["grid_ms"] = 1e3 * grid_s / n;
}

void BM_MapperDepth640x480(benchmark::State& state) {
  Process(state, false, map::TiltMode::kPrior);
}
void BM_MapperLidar64x2048(benchmark::State& state) { Process(state, true, map::TiltMode::kPrior); }
void BM_MapperLidar64x2048OneCore(benchmark::State& state) {
  Process(state, true, map::TiltMode::kPrior, 1);
}
void BM_MapperTilt(benchmark::State& state, map::TiltMode tilt) { Process(state, false, tilt); }

// Every map file of the camera drive's map, written afresh per iteration.
void BM_MapFiles(benchmark::State& state) {
  const DriveFrames& drive = Drive(false);
  if (drive.frames.empty()) {
    state.SkipWithError("cannot make the drive (datasets/worlds, config/default.yaml)");
    return;
  }
  const map::MapperConfig config = Config(20.0, map::TiltMode::kPrior);
  std::unique_ptr<map::Mapper> mapper = NewMapper(config, drive);
  for (const Frame& f : drive.frames) {
    if (!mapper->Process(f.image, f.T_world_sensor, f.stamp_s, f.imu)) {
      state.SkipWithError("a frame was not fused");
      return;
    }
  }
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("cairn-bench-map-files-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir, ec);
  for (auto _ : state) {
    if (Status written = map::WriteMapFiles(mapper->map(), dir); !written) {
      state.SkipWithError(written.message().c_str());
      break;
    }
  }
  std::uintmax_t bytes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    bytes += entry.is_regular_file() ? entry.file_size() : 0;
  }
  state.counters["kib_written"] = static_cast<double>(bytes) / 1024.0;
  std::filesystem::remove_all(dir, ec);
}

// The end voxels of a LiDAR-like frame: a sensor 1.7 m above flat ground, returns on the
// ground out to 20 m and on upright surfaces (trunks, walls) 2-20 m away up to 4 m high.
struct RayFrame {
  map::TerrainOcTree tree{0.1};
  octomap::point3d sensor{0.05f, -0.03f, 1.7f};
  std::vector<octomap::OcTreeKey> ends;
  octomap::OcTreeKey lo, hi;  // the box of the sensor and the ends
};

void MakeRays(RayFrame& f) {
  std::mt19937 rng(7);
  {
    std::uniform_real_distribution<float> angle(-3.14159f, 3.14159f), u(0.0f, 1.0f);
    map::internal::KeyBricks unique;
    while (f.ends.size() < 52000) {
      const float a = angle(rng);
      const bool ground = u(rng) < 0.6f;
      const float r = ground ? 2.0f + 18.0f * u(rng) * u(rng) : 2.0f + 18.0f * u(rng);
      const float z = ground ? 0.0f : 4.0f * u(rng);
      const octomap::OcTreeKey key = f.tree.coordToKey(r * std::cos(a), r * std::sin(a), z);
      if (unique.Contains(key)) continue;
      unique.Insert(key);
      f.ends.push_back(key);
    }
    // In scan order, as a sensor's returns come (by azimuth): neighbouring rays share bricks.
    const auto azimuth = [&f](const octomap::OcTreeKey& k) {
      const octomap::point3d p = f.tree.keyToCoord(k);
      return std::atan2(p.y(), p.x());
    };
    std::sort(f.ends.begin(), f.ends.end(),
              [&](const octomap::OcTreeKey& a, const octomap::OcTreeKey& b) {
                return azimuth(a) < azimuth(b);
              });
    f.lo = f.hi = f.tree.coordToKey(f.sensor);
    for (const octomap::OcTreeKey& k : f.ends) {
      for (int i = 0; i < 3; ++i) {
        f.lo[i] = std::min(f.lo[i], k[i]);
        f.hi[i] = std::max(f.hi[i], k[i]);
      }
    }
  }
}

const RayFrame& Rays() {
  static RayFrame frame;
  static const bool made = (MakeRays(frame), true);
  (void)made;
  return frame;
}

// OctoMap's way: computeRayKeys into a KeyRay, then each key into a hashed set.
void CastWithComputeRayKeys(const RayFrame& f, map::internal::KeyBricks& keys) {
  keys.Clear();
  octomap::KeyRay ray;
  for (const octomap::OcTreeKey& end : f.ends) {
    if (!f.tree.computeRayKeys(f.sensor, f.tree.keyToCoord(end), ray)) continue;
    for (const octomap::OcTreeKey& k : ray) keys.Insert(k);
  }
}

// TerrainMap's way: four or eight rays at a time into a box of bits, then into a set indexed in the
// rays' box.
std::int64_t CastWithWalk(const RayFrame& f, map::internal::KeyBitBox& box,
                          map::internal::KeyBricks& keys) {
  keys.Clear(f.lo, f.hi);
  if (!box.Reset(f.lo, f.hi)) return -1;  // too large a box: the caller fails the benchmark
  map::internal::KeyLayout layout;
  box.Layout(layout.lo, layout.stride);
  std::int64_t steps = 0;
  map::internal::ForEachRayKeyInTurn(f.tree, f.sensor, f.ends.data(), f.ends.data() + f.ends.size(),
                                     layout, [&](std::size_t, std::int64_t key) {
                                       box.Set(key);
                                       ++steps;
                                     });
  box.MoveInto(keys);
  return steps;
}

double SecondsOf(const std::function<void()>& run) {
  const auto start = std::chrono::steady_clock::now();
  run();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void BM_FreeRays(benchmark::State& state, bool walk) {
  const RayFrame& f = Rays();
  map::internal::KeyBricks keys, reference;
  map::internal::KeyBitBox box;
  std::int64_t steps = 0;
  for (auto _ : state) {
    if (walk) {
      steps = CastWithWalk(f, box, keys);
    } else {
      CastWithComputeRayKeys(f, keys);
    }
    benchmark::DoNotOptimize(keys);
  }
  if (!walk) return;
  // The reference, in the same process: the same keys, and how much longer it takes.
  const double reference_s = SecondsOf([&] { CastWithComputeRayKeys(f, reference); });
  const double walk_s = SecondsOf([&] { CastWithWalk(f, box, keys); });
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  bool all_in_reference = true;
  keys.ForEachInMortonOrder(&reference, order, [&](const octomap::OcTreeKey&, bool in) {
    all_in_reference = all_in_reference && in;
  });
  if (steps < 0 || keys.size() != reference.size() || !all_in_reference) {
    state.SkipWithError("the walk's keys differ from computeRayKeys'");
    return;
  }
  state.counters["rays"] = static_cast<double>(f.ends.size());
  state.counters["steps"] = static_cast<double>(steps);
  state.counters["free_voxels"] = static_cast<double>(keys.size());
  state.counters["ns_per_step"] = 1e9 * walk_s / static_cast<double>(steps);
  state.counters["octomap_x"] = reference_s / walk_s;
}
BENCHMARK_CAPTURE(BM_FreeRays, walk, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_FreeRays, computeRayKeys, false)->Unit(benchmark::kMillisecond);

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
BENCHMARK(BM_MapperLidar64x2048OneCore)->Arg(20)->Iterations(12)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_MapperTilt, prior, map::TiltMode::kPrior)
    ->Arg(20)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_MapperTilt, refine_to_map, map::TiltMode::kRefineToMap)
    ->Arg(20)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_MapperTilt, gravity, map::TiltMode::kGravity)
    ->Arg(20)
    ->Iterations(12)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MapFiles)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
