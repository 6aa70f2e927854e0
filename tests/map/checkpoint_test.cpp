// Checkpoints of a TerrainMap: a map saved after some frames of a drive, loaded and fed the
// remaining frames ends exactly like the map that was never interrupted (every cell field,
// every octree node, every obstacle), unbounded and with a rolling window; bad files and a
// changed config are refused with messages naming the file and the field.
#include "cairn/map/checkpoint.hpp"

#include <gtest/gtest.h>
#include <octomap/OcTreeKey.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <tuple>
#include <vector>

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/scene.hpp"
#include "io/temp_dir.hpp"
#include "sim_frames.hpp"

namespace cairn::map {
namespace {

namespace fs = std::filesystem;
fs::path TempDir(const std::string& name) {
  return test::FreshDir("cairn_checkpoint_test", name);
}

// A short drive along +x past boxes and poles on flat ground: 14 frames of a small camera
// (noise seeded per frame), 0.5 m apart, heading turning slowly.
std::vector<test::SimFrame> DriveFrames() {
  sim::Scene scene;
  scene.AddBox(4.0, 0.5, {1.0, 1.0, 0.8}, 0.3, true, "box");
  scene.AddPole(6.0, 2.0, 0.1, 1.2, true, "pole");
  scene.AddBox(8.5, -1.5, {0.6, 0.8, 0.5}, 0.0, true, "rock");
  scene.AddPole(10.0, 0.5, 0.15, 1.5, true, "pole2");
  const Expected<od::io::DetectSettings> settings = test::DefaultDetectSettings();
  EXPECT_TRUE(settings.ok()) << (settings ? "" : settings.error().message);
  std::vector<test::SimFrame> frames;
  if (!settings) return frames;
  const sim::RangeCameraSpec spec = sim::RangeCameraSpec::Default().Scaled(120);
  for (int k = 0; k < 14; ++k) {
    const Eigen::Vector3d position(0.5 * k, 0.1 * k, 1.5);
    const Eigen::Isometry3d T =
        sim::Camera::FromAttitude(od::PinholeModel{}, position, (2.0 * k - 8.0) * kDegToRad,
                                  20.0 * kDegToRad, 0.0)
            .T_world_camera;
    Expected<test::SimFrame> frame =
        test::CameraFrame(scene, spec, T, 0.1 * k, 100 + k, *settings, 7 + k);
    EXPECT_TRUE(frame.ok()) << (frame ? "" : frame.error().message);
    if (!frame) return {};
    frames.push_back(std::move(*frame));
  }
  return frames;
}

const std::vector<test::SimFrame>& Frames() {
  static const std::vector<test::SimFrame> frames = DriveFrames();
  return frames;
}

void Integrate(TerrainMap& map, int first, int last) {
  for (int k = first; k < last; ++k) {
    const Expected<FrameSummary> s = Frames()[k].IntegrateInto(map);
    ASSERT_TRUE(s.ok()) << s.error().message;
  }
}

// Bit-for-bit float equality (NaN == NaN when the bits match).
bool Same(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

void ExpectSameCells(const TerrainMap& a, const TerrainMap& b) {
  ASSERT_EQ(a.grid().min_index(), b.grid().min_index());
  ASSERT_EQ(a.grid().extent(), b.grid().extent());
  ASSERT_EQ(a.grid().slot_count(), b.grid().slot_count());
  int compared = 0, observed = 0;
  const CellIndex lo = a.grid().min_index();
  for (int j = lo.y(); j < lo.y() + a.grid().extent().y(); ++j) {
    for (int i = lo.x(); i < lo.x() + a.grid().extent().x(); ++i) {
      const Cell& x = a.grid().At({i, j});
      const Cell& y = b.grid().At({i, j});
      ASSERT_EQ(a.grid().Slot({i, j}), b.grid().Slot({i, j}));
      const bool same =
          Same(x.elevation_mean_m, y.elevation_mean_m) &&
          Same(x.elevation_min_m, y.elevation_min_m) &&
          Same(x.elevation_max_m, y.elevation_max_m) && x.ground_points == y.ground_points &&
          x.obstacle_points == y.obstacle_points && Same(x.obstacle_top_m, y.obstacle_top_m) &&
          Same(x.obstacle_log_odds, y.obstacle_log_odds) && x.hits == y.hits &&
          x.misses == y.misses && Same(x.slope_rad, y.slope_rad) &&
          Same(x.roughness_m, y.roughness_m) && x.terrain_cost == y.terrain_cost &&
          x.cost == y.cost && x.observed == y.observed && x.lethal == y.lethal &&
          x.obstacle_id == y.obstacle_id;
      ASSERT_TRUE(same) << "cell " << i << "," << j;
      ++compared;
      observed += x.observed ? 1 : 0;
    }
  }
  EXPECT_GT(observed, 100) << "of " << compared;  // the drive saw something
}

// Every node of the tree (inner ones too), in traversal order: key, depth and both log-odds.
using NodeRow = std::tuple<std::uint16_t, std::uint16_t, std::uint16_t, unsigned, float, float>;
std::vector<NodeRow> Nodes(const TerrainOcTree& tree) {
  std::vector<NodeRow> rows;
  for (auto it = tree.begin_tree(), end = tree.end_tree(); it != end; ++it) {
    const octomap::OcTreeKey k = it.getKey();
    rows.emplace_back(k[0], k[1], k[2], it.getDepth(), it->getLogOdds(), it->obstacle_log_odds());
  }
  return rows;
}

void ExpectSameObstacles(const TerrainMap& a, const TerrainMap& b) {
  ASSERT_EQ(a.obstacles().size(), b.obstacles().size());
  for (std::size_t k = 0; k < a.obstacles().size(); ++k) {
    const Obstacle& x = a.obstacles()[k];
    const Obstacle& y = b.obstacles()[k];
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.bbox_min, y.bbox_min);
    EXPECT_EQ(x.bbox_max, y.bbox_max);
    EXPECT_EQ(x.centroid, y.centroid);
    EXPECT_EQ(x.height_m, y.height_m);
    EXPECT_EQ(x.point_count, y.point_count);
    EXPECT_EQ(x.cells, y.cells);
    EXPECT_EQ(x.footprint_min, y.footprint_min);
    EXPECT_EQ(x.footprint_max, y.footprint_max);
    EXPECT_EQ(x.footprint_area_m2, y.footprint_area_m2);
    EXPECT_EQ(x.first_seen_s, y.first_seen_s);
    EXPECT_EQ(x.last_seen_s, y.last_seen_s);
    EXPECT_EQ(x.frames, y.frames);
    EXPECT_EQ(x.merged_ids, y.merged_ids);
  }
}

void ExpectSameMaps(const TerrainMap& a, const TerrainMap& b) {
  ExpectSameCells(a, b);
  ExpectSameObstacles(a, b);
  EXPECT_EQ(a.frames_integrated(), b.frames_integrated());
  EXPECT_EQ(a.obstacles_retired(), b.obstacles_retired());
  const std::optional<CellBox> ba = a.ObservedBounds(), bb = b.ObservedBounds();
  ASSERT_EQ(ba.has_value(), bb.has_value());
  if (ba) {
    EXPECT_EQ(ba->min, bb->min);
    EXPECT_EQ(ba->max, bb->max);
  }
  const std::vector<NodeRow> na = Nodes(a.octree()), nb = Nodes(b.octree());
  EXPECT_GT(na.size(), 1000u);
  EXPECT_TRUE(na == nb) << na.size() << " vs " << nb.size() << " nodes";
}

std::string ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteBytes(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

// Saves after `split` frames, loads, and runs the rest of the drive on both maps.
void ResumeMatchesUninterrupted(const MapConfig& config, int split, const std::string& name) {
  ASSERT_EQ(Frames().size(), 14u);
  const fs::path dir = TempDir(name);
  Expected<TerrainMap> full = TerrainMap::Create(config);
  ASSERT_TRUE(full.ok());
  Integrate(*full, 0, split);
  ASSERT_TRUE(SaveCheckpoint(*full, dir, "next=" + std::to_string(split)).ok());
  EXPECT_TRUE(fs::exists(dir / kCheckpointFileName));
  // Nothing but the checkpoint (no temporary left behind).
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);

  std::string user_data;
  Expected<TerrainMap> resumed = LoadCheckpoint(dir, config, &user_data);
  ASSERT_TRUE(resumed.ok()) << resumed.error().message;
  EXPECT_EQ(user_data, "next=" + std::to_string(split));
  EXPECT_EQ(resumed->frames_integrated(), split);
  // The loaded map saves to the very same bytes (before anything looks at its octree).
  const fs::path again = dir / "again.checkpoint";
  ASSERT_TRUE(SaveCheckpoint(*resumed, again, user_data).ok());
  EXPECT_TRUE(ReadBytes(again) == ReadBytes(dir / kCheckpointFileName));

  Integrate(*full, split, static_cast<int>(Frames().size()));
  Integrate(*resumed, split, static_cast<int>(Frames().size()));
  ExpectSameMaps(*full, *resumed);
  EXPECT_FALSE(full->obstacles().empty());
  fs::remove_all(dir);
}

TEST(Checkpoint, ResumedMapMatchesUninterruptedMap) {
  // 5 frames: the octree's inner nodes are stale at the save (refreshed every 8 frames).
  ResumeMatchesUninterrupted(MapConfig{}, 5, "unbounded");
}

TEST(Checkpoint, ResumedMapMatchesAfterAnOctreeRefresh) {
  ResumeMatchesUninterrupted(MapConfig{}, 8, "unbounded8");
}

TEST(Checkpoint, ResumedRollingWindowMapMatchesUninterruptedMap) {
  MapConfig config;
  config.window_size_m = 5.0;  // 25 cells: the window moves and the octree is cut to it
  ResumeMatchesUninterrupted(config, 6, "rolling");
}

TEST(Checkpoint, EmptyMapRoundTrips) {
  const fs::path dir = TempDir("empty");
  Expected<TerrainMap> map = TerrainMap::Create(MapConfig{});
  ASSERT_TRUE(map.ok());
  ASSERT_TRUE(SaveCheckpoint(*map, dir).ok());
  Expected<TerrainMap> loaded = LoadCheckpoint(dir, MapConfig{});
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->frames_integrated(), 0);
  EXPECT_FALSE(loaded->ObservedBounds().has_value());
  EXPECT_EQ(loaded->octree().size(), 0u);
  Integrate(*map, 0, 2);
  Integrate(*loaded, 0, 2);
  ExpectSameObstacles(*map, *loaded);
  EXPECT_TRUE(Nodes(map->octree()) == Nodes(loaded->octree()));
  fs::remove_all(dir);
}

class CheckpointFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = TempDir("files");
    Expected<TerrainMap> map = TerrainMap::Create(MapConfig{});
    ASSERT_TRUE(map.ok());
    Integrate(*map, 0, 3);
    ASSERT_TRUE(SaveCheckpoint(*map, dir_).ok());
    path_ = dir_ / kCheckpointFileName;
    bytes_ = ReadBytes(path_);
    ASSERT_GT(bytes_.size(), 1000u);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string LoadError(const MapConfig& config = {}) {
    const Expected<TerrainMap> m = LoadCheckpoint(path_, config);
    EXPECT_FALSE(m.ok());
    return m ? std::string() : m.error().message;
  }

  fs::path dir_, path_;
  std::string bytes_;
};

TEST_F(CheckpointFileTest, TruncatedFilesAreRefusedNamingTheFile) {
  for (const std::size_t size :
       {std::size_t{0}, std::size_t{20}, std::size_t{32}, bytes_.size() / 2, bytes_.size() - 1}) {
    WriteBytes(path_, bytes_.substr(0, size));
    const std::string error = LoadError();
    EXPECT_NE(error.find(path_.string()), std::string::npos) << error;
    EXPECT_NE(error.find("truncated"), std::string::npos) << size << ": " << error;
  }
  WriteBytes(path_, bytes_.substr(0, 20));
  EXPECT_NE(LoadError().find("expected a 32-byte header"), std::string::npos);
  WriteBytes(path_, bytes_.substr(0, bytes_.size() - 1));
  EXPECT_NE(LoadError().find("announces " + std::to_string(bytes_.size() - 32) +
                             " bytes after it, the file has " + std::to_string(bytes_.size() - 33)),
            std::string::npos);
}

TEST_F(CheckpointFileTest, CorruptedFilesAreRefused) {
  std::string flipped = bytes_;
  flipped[bytes_.size() / 2] ^= 0x10;
  WriteBytes(path_, flipped);
  std::string error = LoadError();
  EXPECT_NE(error.find(path_.string()), std::string::npos) << error;
  EXPECT_NE(error.find("checksum"), std::string::npos) << error;

  std::string magic = bytes_;
  magic[0] = 'X';
  WriteBytes(path_, magic);
  EXPECT_NE(LoadError().find("not a cairn map checkpoint"), std::string::npos);

  std::string version = bytes_;
  version[8] = 9;  // little-endian u32 after the magic
  WriteBytes(path_, version);
  EXPECT_NE(LoadError().find("format version 9, expected 1"), std::string::npos);

  WriteBytes(path_, bytes_ + "extra");
  EXPECT_NE(LoadError().find("corrupted"), std::string::npos);

  fs::remove(path_);
  error = LoadError();
  EXPECT_NE(error.find("cannot open"), std::string::npos) << error;
}

TEST_F(CheckpointFileTest, ChangedConfigIsRefusedNamingTheField) {
  MapConfig config;
  config.cell_size_m = 0.25;
  std::string error = LoadError(config);
  EXPECT_NE(error.find(path_.string()), std::string::npos) << error;
  EXPECT_NE(error.find("'cell_size' = 0.20000000000000001 but the run's config has 0.25"),
            std::string::npos)
      << error;
  config = MapConfig{};
  config.cost_scaling_factor = 2.5;
  error = LoadError(config);
  EXPECT_NE(error.find("'cost_scaling_factor'"), std::string::npos) << error;
  // The checkpoint itself is fine.
  EXPECT_TRUE(LoadCheckpoint(path_, MapConfig{}).ok());
}

TEST_F(CheckpointFileTest, FailedSaveLeavesThePreviousCheckpoint) {
  Expected<TerrainMap> other = TerrainMap::Create(MapConfig{});
  ASSERT_TRUE(other.ok());
  const Status s = SaveCheckpoint(*other, dir_ / "missing" / "map.checkpoint");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("missing"), std::string::npos) << s.message();
  EXPECT_TRUE(ReadBytes(path_) == bytes_);
  // Overwriting replaces it whole.
  ASSERT_TRUE(SaveCheckpoint(*other, dir_).ok());
  Expected<TerrainMap> loaded = LoadCheckpoint(dir_, MapConfig{});
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->frames_integrated(), 0);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

}  // namespace
}  // namespace cairn::map
