// The one map scorer (cairn::eval_map, map_score.hpp) on a small mapped scene: a box and a
// pole seen by two noiseless range cameras. The truth it draws must lie where the objects
// stand, and each of its counts must move as the world it is scored against changes.
#include "cairn/eval/map_score.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "cairn/eval/pose_score.hpp"
#include "cairn/od/units.hpp"
#include "map_scene.hpp"

namespace cairn::test {
namespace {

Expected<map::TerrainMap> MappedOrFail() {
  Expected<map::TerrainMap> m = SmallMappedScene();
  EXPECT_TRUE(m.ok()) << m.error().message;
  return m;
}

const eval::MapObjectScore* Named(const eval::MapScore& score, const std::string& name) {
  for (const eval::MapObjectScore& o : score.objects) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

TEST(MapScore, TheWorldTheMapWasMadeInIsFoundWithItsCellsWhereTheObjectsStand) {
  const Expected<map::TerrainMap> m = MappedOrFail();
  ASSERT_TRUE(m.ok());
  const Expected<eval::MapScore> score = eval::ScoreMap(SmallScene(), *m);
  ASSERT_TRUE(score.ok()) << score.error().message;
  const double s = m->grid().cell_size();
  ASSERT_EQ(score->objects.size(), 2u);
  const eval::MapObjectScore* box = Named(*score, "box");
  const eval::MapObjectScore* pole = Named(*score, "pole");
  ASSERT_NE(box, nullptr);
  ASSERT_NE(pole, nullptr);
  // A cell is the object's when one of its 4 x 4 vertical rays hits it: its centre lies
  // within half a cell (a diagonal's half for the round pole) of the object's footprint.
  ASSERT_FALSE(box->obstacle_cells.empty());
  for (const eval::MapCell& c : box->obstacle_cells) {
    const Eigen::Vector2d centre = m->grid().CentreOf({c.first, c.second});
    EXPECT_LE(std::abs(centre.x() - 4.0), 0.5 + 0.5 * s + 1e-9);
    EXPECT_LE(std::abs(centre.y()), 0.5 + 0.5 * s + 1e-9);
  }
  ASSERT_FALSE(pole->obstacle_cells.empty());
  for (const eval::MapCell& c : pole->obstacle_cells) {
    const Eigen::Vector2d centre = m->grid().CentreOf({c.first, c.second});
    EXPECT_LE((centre - Eigen::Vector2d(6.0, 2.0)).norm(), 0.1 + std::sqrt(0.5) * s + 1e-9);
  }
  EXPECT_EQ(score->obstacles, 2);
  EXPECT_EQ(score->found, 2);
  EXPECT_LE(box->nearest_lethal_m, 0.3);
  EXPECT_LE(pole->nearest_lethal_m, 0.3);
  EXPECT_NE(box->map_obstacle_id, 0);
  EXPECT_NE(box->map_obstacle_id, pole->map_obstacle_id);
  EXPECT_GE(score->iou, 0.3);
  EXPECT_EQ(score->false_lethal, 0);
  EXPECT_TRUE(score->false_obstacle_ids.empty());
  EXPECT_EQ(score->marked_non_obstacles, 0);
  // Flat ground seen without noise.
  EXPECT_GT(score->elevation_cells, 100);
  EXPECT_LT(score->elevation_rms_m, 0.02);
}

TEST(MapScore, AnObstacleWhereTheMapSawOnlyGroundIsMissed) {
  const Expected<map::TerrainMap> m = MappedOrFail();
  ASSERT_TRUE(m.ok());
  // A cell of observed, level ground at least 2 m from both objects.
  const map::TerrainGrid& grid = m->grid();
  std::optional<Eigen::Vector2d> free_ground;
  for (int j = 0; j < grid.extent().y() && !free_ground; ++j) {
    for (int i = 0; i < grid.extent().x() && !free_ground; ++i) {
      const map::CellIndex index = grid.min_index() + map::CellIndex(i, j);
      const map::Cell& cell = grid.At(index);
      const Eigen::Vector2d c = grid.CentreOf(index);
      if (cell.has_elevation() && !cell.lethal && (c - Eigen::Vector2d(4.0, 0.0)).norm() > 2.0 &&
          (c - Eigen::Vector2d(6.0, 2.0)).norm() > 2.0) {
        free_ground = c;
      }
    }
  }
  ASSERT_TRUE(free_ground.has_value());
  sim::Scene scene = SmallScene();
  scene.AddBox(free_ground->x(), free_ground->y(), {0.4, 0.4, 0.5}, 0.0, true, "unseen");
  const Expected<eval::MapScore> score = eval::ScoreMap(scene, *m);
  ASSERT_TRUE(score.ok()) << score.error().message;
  const eval::MapObjectScore* unseen = Named(*score, "unseen");
  ASSERT_NE(unseen, nullptr);
  EXPECT_TRUE(unseen->scored());
  EXPECT_FALSE(unseen->found);
  EXPECT_GT(unseen->nearest_lethal_m, 1.0);
  EXPECT_EQ(score->obstacles, 3);
  EXPECT_EQ(score->found, 2);
  const Expected<eval::MapScore> without = eval::ScoreMap(SmallScene(), *m);
  ASSERT_TRUE(without.ok());
  EXPECT_LT(score->iou, without->iou);  // more true cells, the same lethal ones
  EXPECT_LT(score->elevation_cells, without->elevation_cells);  // cells near it left out
}

TEST(MapScore, AgainstAnEmptyWorldEveryLethalCellAndObstacleIsFalse) {
  const Expected<map::TerrainMap> m = MappedOrFail();
  ASSERT_TRUE(m.ok());
  const Expected<eval::MapScore> score = eval::ScoreMap(sim::Scene(), *m);
  ASSERT_TRUE(score.ok()) << score.error().message;
  EXPECT_TRUE(score->objects.empty());
  EXPECT_EQ(score->obstacles, 0);
  ASSERT_FALSE(score->lethal_cells.empty());
  EXPECT_EQ(score->false_lethal, static_cast<int>(score->lethal_cells.size()));
  EXPECT_EQ(score->false_obstacle_ids.size(), m->obstacles().size());
  EXPECT_EQ(score->iou, 0.0);
}

TEST(MapScore, AnObjectThatIsNoObstacleUnderALethalCellIsMarked) {
  const Expected<map::TerrainMap> m = MappedOrFail();
  ASSERT_TRUE(m.ok());
  sim::Scene scene;
  scene.AddBox(4.0, 0.0, {1.0, 1.0, 0.8}, 0.0, false, "box");  // said to be no obstacle
  scene.AddPole(6.0, 2.0, 0.1, 1.2, true, "pole");
  const Expected<eval::MapScore> score = eval::ScoreMap(scene, *m);
  ASSERT_TRUE(score.ok()) << score.error().message;
  EXPECT_EQ(score->obstacles, 1);
  EXPECT_EQ(score->marked_non_obstacles, 1);
  const eval::MapObjectScore* box = Named(*score, "box");
  ASSERT_NE(box, nullptr);
  EXPECT_FALSE(box->scored());
  EXPECT_TRUE(box->obstacle_cells.empty());
  EXPECT_FALSE(box->cells.empty());
  // Its lethal cells are away from every obstacle cell now; the map obstacle on it still
  // lies on an object.
  EXPECT_GT(score->false_lethal, 0);
  EXPECT_TRUE(score->false_obstacle_ids.empty());
}

TEST(MapScore, OptionsOutOfRangeAreNamed) {
  const Expected<map::TerrainMap> m = MappedOrFail();
  ASSERT_TRUE(m.ok());
  eval::MapScoreOptions options;
  options.found_within_m = 0.0;
  const Expected<eval::MapScore> score = eval::ScoreMap(SmallScene(), *m, options);
  ASSERT_FALSE(score.ok());
  EXPECT_NE(score.error().message.find("found_within_m"), std::string::npos);
  const Expected<map::TerrainMap> empty = map::TerrainMap::Create({});
  ASSERT_TRUE(empty.ok());
  const Expected<eval::MapScore> nothing = eval::ScoreMap(SmallScene(), *empty);
  ASSERT_FALSE(nothing.ok());
  EXPECT_NE(nothing.error().message.find("observed nothing"), std::string::npos);
}

// Fused poses against true ones: each fused pose is the true one tilted by a known angle
// (about an axis that varies) and raised by a known height, so the figures are known.
TEST(PoseScore, TiltAndHeightErrorsAreTheOnesPutIn) {
  std::vector<sources::StampedPose> truth;
  for (int k = 0; k <= 10; ++k) {
    sources::StampedPose p;
    p.stamp_s = 100.0 + k;
    p.T_world_x.linear() = (Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(0.05 * k, Eigen::Vector3d::UnitX()))
                               .toRotationMatrix();
    p.T_world_x.translation() = Eigen::Vector3d(2.0 * k, 0.5 * k, 0.1 * k);
    truth.push_back(p);
  }
  const Expected<sources::Trajectory> trajectory = sources::Trajectory::FromPoses(truth, "truth");
  ASSERT_TRUE(trajectory.ok()) << trajectory.error().message;
  std::vector<eval::FusedPose> fused;
  const double tilt_deg[] = {0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0};
  const double dz_m[] = {0.1, -0.1, 0.1, -0.1, 0.1, -0.1, 0.1, -0.1, 0.1, -0.1, 0.1};
  for (int k = 0; k <= 10; ++k) {
    eval::FusedPose f;
    f.index = k;
    f.stamp_s = truth[k].stamp_s;
    f.T_world_sensor = truth[k].T_world_x;
    // A rotation about an axis in the sensor's own x-y plane tilts its up vector by the angle.
    const Eigen::Vector3d axis(std::cos(0.7 * k), std::sin(0.7 * k), 0.0);
    const Eigen::Vector3d up_sensor =
        truth[k].T_world_x.linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d tilt_axis = up_sensor.cross(axis).normalized();
    f.T_world_sensor.linear() =
        truth[k].T_world_x.linear() *
        Eigen::AngleAxisd(tilt_deg[k] * kDegToRad, tilt_axis).toRotationMatrix();
    f.T_world_sensor.translation().z() += dz_m[k];
    fused.push_back(f);
  }
  const Expected<eval::PoseScore> score = eval::ScorePoses(*trajectory, fused, "poses.tum");
  ASSERT_TRUE(score.ok()) << score.error().message;
  EXPECT_EQ(score->frames, 11);
  EXPECT_NEAR(score->tilt_median_deg, 2.5, 1e-9);
  EXPECT_NEAR(score->tilt_p95_deg, 5.0, 1e-9);  // rank round(0.95 * 10) = 10
  EXPECT_NEAR(score->tilt_max_deg, 5.0, 1e-9);
  EXPECT_NEAR(score->height_rms_m, 0.1, 1e-12);

  // A stamp the truth does not span is an error naming the file and the frame.
  fused.back().stamp_s = 200.0;
  const Expected<eval::PoseScore> beyond = eval::ScorePoses(*trajectory, fused, "poses.tum");
  ASSERT_FALSE(beyond.ok());
  EXPECT_NE(beyond.error().message.find("poses.tum: frame 10"), std::string::npos)
      << beyond.error().message;
}

}  // namespace
}  // namespace cairn::test
