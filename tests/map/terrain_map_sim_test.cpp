// TerrainMap on the gallery's worlds (datasets/worlds), driven with true poses: the lethal
// cells against the true obstacles (IoU over the observed cells, distance from each seen
// obstacle to the nearest lethal cell, lethal cells far from any obstacle), the elevation
// against the true terrain, and one persistent obstacle per object over a drive that passes
// the same objects twice. The figures are printed per world (the report quotes them).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "cairn/eval/map_score.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/render.hpp"
#include "sim_frames.hpp"

namespace cairn::map {
namespace {

using test::SimFrame;

Expected<sim::World> LoadWorld(const std::string& name) {
  return sim::LoadWorld((test::SourceDir() / "datasets" / "worlds" / (name + ".yaml")).string());
}

struct DriveRun {
  TerrainMap map;
  std::map<int, int> pixels_seen;  // object id -> most pixels of it in one frame
  int frames = 0;
};

// Drives through the world with true poses, camera (or LiDAR) on the body: one pass per
// waypoint list, one after the other (frame ids and stamps run on across passes).
DriveRun Drive(const sim::World& world, const std::vector<std::vector<Eigen::Vector2d>>& passes,
               double rate_hz, bool lidar, const MapConfig& config = {}) {
  Expected<TerrainMap> map = TerrainMap::Create(config);
  EXPECT_TRUE(map.ok());
  DriveRun run{std::move(*map), {}, 0};
  const Expected<od::io::DetectSettings> settings = test::DefaultDetectSettings();
  EXPECT_TRUE(settings.ok());
  if (!settings) return run;
  const sim::RangeCameraSpec camera = world.camera.Scaled(160);
  for (const std::vector<Eigen::Vector2d>& waypoints : passes) {
    const Expected<sim::Drive> drive =
        test::TrueDrive(world.scene.terrain(), waypoints, 2.0, rate_hz, 8.0 * kDegToRad,
                        lidar ? sim::SensorFrame::kLidar : sim::SensorFrame::kCameraOptical);
    EXPECT_TRUE(drive.ok()) << (drive ? "" : drive.error().message);
    if (!drive) return run;
    for (const sim::DriveSample& s : drive->samples) {
      const int id = run.frames;
      const double stamp_s = id / rate_hz;
      const std::uint64_t seed = sim::MixSeed(world.seed, id);
      const Expected<SimFrame> frame =
          lidar ? test::LidarFrame(world.scene, *world.lidar, s.T_world_sensor, stamp_s, id,
                                   *settings, seed)
                : test::CameraFrame(world.scene, camera, s.T_world_sensor, stamp_s, id, *settings,
                                    seed);
      EXPECT_TRUE(frame.ok()) << (frame ? "" : frame.error().message);
      if (!frame) return run;
      const Expected<FrameSummary> summary = frame->IntegrateInto(run.map);
      EXPECT_TRUE(summary.ok()) << (summary ? "" : summary.error().message);
      std::map<int, int> pixels;
      for (const std::int32_t object : frame->object_id) {
        if (object > 0) ++pixels[object];
      }
      for (const auto& [object, n] : pixels) {
        run.pixels_seen[object] = std::max(run.pixels_seen[object], n);
      }
      ++run.frames;
    }
  }
  return run;
}

double Distance(const eval::MapCell& a, const eval::MapCell& b, double s) {
  return std::hypot(a.first - b.first, a.second - b.second) * s;
}

struct Scores {
  double iou = 0.0;
  int lethal = 0, truth = 0;
  int far_lethal = 0;           // lethal cells more than 0.5 m from every obstacle cell
  double worst_distance = 0.0;  // over the seen obstacles: to the nearest lethal cell [m]
  int seen = 0, found = 0;      // seen obstacles; of which within 0.3 m of a lethal cell
  double elevation_rms = 0.0;
  int elevation_cells = 0;
  // Persistent obstacles against the objects: for each seen obstacle, how many persistent
  // obstacles have a cell within one cell of it (the most over the objects, and the least);
  // persistent obstacles with no object within one cell.
  int most_per_object = 0, least_per_object = 0, unmatched = 0;
  std::map<int, std::vector<int>> persistent_of;  // object id -> persistent obstacle ids
};

Scores Score(const sim::World& world, const DriveRun& run, const std::string& label) {
  const TerrainMap& map = run.map;
  const double s = map.grid().cell_size();
  Scores out;
  // The one scorer: true obstacle cells where an obstacle rises 0.15 m or more.
  const Expected<eval::MapScore> score = eval::ScoreMap(world.scene, map);
  EXPECT_TRUE(score.ok()) << score.error().message;
  if (!score) return out;
  out.lethal = static_cast<int>(score->lethal_cells.size());
  out.truth = static_cast<int>(score->obstacle_cells.size());
  out.iou = score->iou;
  out.far_lethal = score->false_lethal;
  out.elevation_rms = score->elevation_rms_m;
  out.elevation_cells = score->elevation_cells;
  // Each obstacle seen well (30 pixels in a frame at least): its distance to a lethal cell,
  // and the persistent obstacles on it.
  std::printf("%s: per obstacle (pixels, distance to nearest lethal cell [m]):", label.c_str());
  for (const eval::MapObjectScore& object : score->objects) {
    const auto seen = run.pixels_seen.find(object.id);
    if (!object.scored() || seen == run.pixels_seen.end() || seen->second < 30) continue;
    std::printf(" %s %d %.2f;", object.name.c_str(), seen->second, object.nearest_lethal_m);
    std::vector<int>& ids = out.persistent_of[object.id];
    for (const Obstacle& o : map.obstacles()) {
      bool touches = false;
      for (const CellIndex& oc : o.cells) {
        for (const auto& c : object.obstacle_cells) {
          touches = touches || Distance({oc.x(), oc.y()}, c, s) < 0.3;
        }
      }
      if (touches) ids.push_back(o.id);
    }
    const int n = static_cast<int>(ids.size());
    out.most_per_object = out.seen == 0 ? n : std::max(out.most_per_object, n);
    out.least_per_object = out.seen == 0 ? n : std::min(out.least_per_object, n);
    ++out.seen;
    out.found += object.found ? 1 : 0;
    out.worst_distance = std::max(out.worst_distance, object.nearest_lethal_m);
  }
  std::printf("\n");
  for (const Obstacle& o : map.obstacles()) {
    bool matched = false;
    for (const CellIndex& oc : o.cells) {
      for (const auto& t : score->obstacle_cells) {
        matched = matched || Distance({oc.x(), oc.y()}, t, s) < 0.3;
      }
    }
    out.unmatched += !matched;
  }
  std::printf(
      "%s: %d frames, IoU %.3f (lethal %d, true %d), lethal cells > 0.5 m from any obstacle "
      "%d, obstacles found %d/%d, worst distance %.2f m, elevation RMS %.3f m over %d cells, "
      "%zu persistent obstacles\n",
      label.c_str(), run.frames, out.iou, out.lethal, out.truth, out.far_lethal, out.found,
      out.seen, out.worst_distance, out.elevation_rms, out.elevation_cells, map.obstacles().size());
  return out;
}

// What every drive must show: each obstacle seen well is mapped (a lethal cell on it) as one
// persistent obstacle, no lethal cell lies away from the obstacles, the lethal cells cover
// the obstacles' footprints (IoU), and the elevation is the terrain's within 3 cm RMS.
void ExpectGoodMap(const Scores& s, double min_iou) {
  EXPECT_GE(s.seen, 7);
  EXPECT_EQ(s.found, s.seen);
  EXPECT_LE(s.worst_distance, 0.2);
  EXPECT_EQ(s.far_lethal, 0);
  EXPECT_GE(s.iou, min_iou);
  EXPECT_EQ(s.most_per_object, 1);
  EXPECT_EQ(s.least_per_object, 1);
  EXPECT_EQ(s.unmatched, 0);
  EXPECT_LT(s.elevation_rms, 0.03);
  EXPECT_GT(s.elevation_cells, 5000);
}

TEST(TerrainMapWorlds, PolesAndRocksCameraDrive) {
  const Expected<sim::World> loaded = LoadWorld("poles_and_rocks");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const sim::World& world = *loaded;
  const DriveRun run = Drive(world, {{{0.0, 0.0}, {16.0, 0.0}}}, 2.5, false);
  const Scores s = Score(world, run, "poles_and_rocks (camera)");
  ExpectGoodMap(s, 0.6);
}

TEST(TerrainMapWorlds, UphillTiltedCameraDrive) {
  const Expected<sim::World> loaded = LoadWorld("uphill_tilted");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const sim::World& world = *loaded;
  const DriveRun run = Drive(world, {{{0.0, 0.0}, {20.0, 1.0}, {30.0, -0.5}}}, 2.0, false);
  const Scores s = Score(world, run, "uphill_tilted (camera)");
  ExpectGoodMap(s, 0.65);
}

TEST(TerrainMapWorlds, UphillTiltedLidarDrive) {
  const Expected<sim::World> loaded = LoadWorld("uphill_tilted");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const sim::World& world = *loaded;
  ASSERT_TRUE(world.lidar.has_value());
  const DriveRun run = Drive(world, {{{0.0, 0.0}, {20.0, 1.0}, {30.0, -0.5}}}, 1.0, true);
  const Scores s = Score(world, run, "uphill_tilted (VLP-16)");
  ExpectGoodMap(s, 0.5);
}

// The same stretch driven twice, the second time 1 m to the side (other viewpoints, other
// noise): every object is seen in both passes and stays one persistent obstacle.
TEST(TerrainMapWorlds, DrivingOverTheSamePlaceTwiceDoesNotDoubleObstacles) {
  const Expected<sim::World> loaded = LoadWorld("poles_and_rocks");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  const sim::World& world = *loaded;
  const DriveRun run =
      Drive(world, {{{0.0, 0.0}, {16.0, 0.0}}, {{0.0, 1.0}, {16.0, 1.0}}}, 2.0, false);
  const Scores s = Score(world, run, "poles_and_rocks, two passes (camera)");
  ExpectGoodMap(s, 0.6);
  EXPECT_EQ(static_cast<int>(run.map.obstacles().size()), s.seen);
  const std::int64_t second_pass = run.frames / 2;
  int both_passes = 0;
  for (const Obstacle& o : run.map.obstacles()) {
    both_passes += o.frames.front() < second_pass && o.frames.back() >= second_pass;
  }
  EXPECT_EQ(both_passes, s.seen);
}

}  // namespace
}  // namespace cairn::map
