// TerrainMap on small analytic scenes: the cost of every cell against a brute-force
// inflation of the lethal cells, exact nav2 values at known distances, clearing of a false
// obstacle, one persistent obstacle per object over repeated passes, the rolling window
// against the unbounded map, queries, and input checks.
#include "cairn/map/terrain_map.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "cairn/map/terrain_octree.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/scene.hpp"
#include "ground_rise.hpp"  // libmap/src: the gravity step's ground seen twice
#include "key_bricks.hpp"   // libmap/src: the free-space key set
#include "place_returns.hpp"  // libmap/src: the returns placed in the world
#include "ray_keys.hpp"     // libmap/src: the ray walk
#include "sim_frames.hpp"
#include "simd.hpp"  // libod/src: the vector width

namespace cairn::map {
namespace {

using test::SimFrame;

Eigen::Isometry3d CameraPose(const Eigen::Vector3d& position, double heading_deg,
                             double pitch_deg) {
  return sim::Camera::FromAttitude(od::PinholeModel{}, position, heading_deg * kDegToRad,
                                   pitch_deg * kDegToRad, 0.0)
      .T_world_camera;
}

sim::RangeCameraSpec Camera(int width = 160) {
  return sim::RangeCameraSpec::Default().Scaled(width);
}

od::io::DetectSettings Settings() {
  Expected<od::io::DetectSettings> s = test::DefaultDetectSettings();
  EXPECT_TRUE(s.ok()) << (s ? "" : s.error().message);
  return s ? *s : od::io::DetectSettings{};
}

TerrainMap NewMap(const MapConfig& config = {}) {
  Expected<TerrainMap> map = TerrainMap::Create(config);
  EXPECT_TRUE(map.ok()) << (map ? "" : map.error().message);
  return std::move(map).value();
}

void Integrate(TerrainMap& map, const SimFrame& frame) {
  const Expected<FrameSummary> summary = frame.IntegrateInto(map);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
}

// Every cell of the extent.
template <typename F>
void ForEachCell(const TerrainGrid& grid, F&& f) {
  for (int j = 0; j < grid.extent().y(); ++j) {
    for (int i = 0; i < grid.extent().x(); ++i) {
      const CellIndex index = grid.min_index() + CellIndex(i, j);
      f(index, grid.At(index));
    }
  }
}

// Lets the vector width be capped (CapVectorLanes) for a test, and uncaps it when the test ends.
struct UncapLanesAtEnd {
  ~UncapLanesAtEnd() { od::internal::CapVectorLanes(0); }
};

// A 1 m x 1 m x 0.8 m box on flat ground at (4, 0): its footprint is cells x 17..22
// ([3.4, 4.6)), y -3..2 ([-0.6, 0.6)) of 0.2 m, seen from two noiseless cameras.
struct BoxScene {
  sim::Scene scene;
  std::vector<SimFrame> frames;
  BoxScene() {
    scene.AddBox(4.0, 0.0, {1.0, 1.0, 0.8}, 0.0, true, "box");
    const od::io::DetectSettings settings = Settings();
    const Eigen::Isometry3d poses[] = {CameraPose({1.0, 0.0, 2.0}, 0.0, 25.0),
                                       CameraPose({1.5, 2.5, 2.0}, -40.0, 25.0)};
    int id = 0;
    for (const Eigen::Isometry3d& T : poses) {
      Expected<SimFrame> f = test::CameraFrame(scene, Camera(), T, 0.1 * id, id, settings);
      EXPECT_TRUE(f.ok()) << (f ? "" : f.error().message);
      if (f) frames.push_back(std::move(*f));
      ++id;
    }
  }
};

TEST(TerrainMap, LethalCellsAreTheBoxFootprint) {
  const BoxScene box;
  TerrainMap map = NewMap();
  for (const SimFrame& f : box.frames) Integrate(map, f);
  std::set<std::pair<int, int>> lethal;
  ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
    if (cell.cost == kLethalCost) lethal.insert({c.x(), c.y()});
    EXPECT_EQ(cell.lethal, cell.cost == kLethalCost);
  });
  int inside = 0;
  for (const auto& [i, j] : lethal) {
    EXPECT_TRUE(i >= 17 && i <= 22 && j >= -3 && j <= 2) << "lethal cell " << i << "," << j;
    ++inside;
  }
  // The face towards the first camera (x = 3.5, cells x = 17) is lethal along its width.
  for (int j = -3; j <= 2; ++j) EXPECT_EQ(lethal.count({17, j}), 1u) << "face cell 17," << j;
  EXPECT_GE(inside, 30) << "of the 36 footprint cells";
  ASSERT_EQ(map.obstacles().size(), 1u);
  const Obstacle& o = map.obstacles().front();
  EXPECT_EQ(o.cells.size(), lethal.size());
  EXPECT_NEAR(o.bbox_max.z(), 0.8, 0.02);
  EXPECT_NEAR(o.height_m, 0.8, 0.05);
  EXPECT_EQ(o.frames, (std::vector<std::int64_t>{0, 1}));
  EXPECT_NEAR(o.footprint_min.x(), 3.4, 1e-9);
  EXPECT_NEAR(o.footprint_max.x(), 4.6, 1e-9);
}

// A frame's obstacle points are the points of kept segments that the definition names
// (MapConfig::obstacle_min_height_m): some lowest in-range return q of a cell, within
// ground_radius of p horizontally, lies below p by obstacle_min_height plus the rise of ground
// at ground_max_slope over |p - q|_xy, in the map's float arithmetic; checked against every
// cell's lowest return, on hills with poles and boxes (ground lower and higher around them),
// one frame at a time into fresh maps: the frame's count and each cell's; and the frames'
// counts in one map that takes them all, unbounded and in a rolling window smaller than the
// frames (the returns outside it count for nothing, and their cells are not ground).
TEST(TerrainMap, ObstaclePointsAreThoseTheDefinitionNames) {
  sim::Scene scene(sim::Terrain::Hills(0.0, {sim::SineWave{0.4, 6.0, 0.3, 0.0}}));
  const double poles[][2] = {{4, 1}, {6, -1.5}, {8, 0.5}, {10, -0.5}};
  for (const auto& p : poles) scene.AddPole(p[0], p[1], 0.1, 1.2, true);
  scene.AddBox(7.0, 2.0, {0.8, 0.8, 0.6}, 0.3, true);
  scene.AddBox(5.0, -3.0, {0.8, 1.2, 0.7}, -0.2, true);
  const od::io::DetectSettings settings = Settings();
  const MapConfig config;
  const float rise = static_cast<float>(std::tan(config.ground_max_slope_rad));
  const float reach2 = static_cast<float>(config.ground_radius_m * config.ground_radius_m);
  int frames = 0, obstacle_points = 0, foot_points = 0, outside = 0;
  TerrainMap all = NewMap(config);
  MapConfig rolling_config = config;
  rolling_config.window_size_m = 10.0;
  TerrainMap rolling = NewMap(rolling_config);
  for (const double heading : {0.0, 20.0, -25.0}) {
    const Expected<SimFrame> frame =
        test::CameraFrame(scene, Camera(), CameraPose({0.0, 0.0, 1.5}, heading, 15.0), frames * 0.1,
                          frames, settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    // The definition's count over the returns whose cells `in` holds.
    const auto definition = [&](const std::function<bool(const CellIndex&)>& in) {
      std::vector<Eigen::Vector3f> lowest_in;
      std::map<std::pair<int, int>, std::size_t> lowest_of;
      std::vector<Eigen::Vector3f> kept_in;
      for (int i = 0; i < frame->image.size(); ++i) {
        if (!frame->image.valid(i)) continue;
        const Eigen::Vector3d p = frame->image.point(i);
        const double range = p.norm();
        if (!(range > 0.0) || range > config.max_range_m) continue;
        const Eigen::Vector3d w = frame->T_world_sensor * p;
        const CellIndex c = all.grid().IndexOf(w.head<2>());
        if (!in(c)) continue;
        const auto [at, made] = lowest_of.emplace(std::pair(c.x(), c.y()), lowest_in.size());
        if (made) lowest_in.push_back(w.cast<float>());
        if (w.z() < lowest_in[at->second].z()) lowest_in[at->second] = w.cast<float>();
        const int label = frame->detection.labels[i];
        if (label > 0 && frame->classification.verdicts[label - 1].cls == od::SegmentClass::kKept) {
          kept_in.push_back(w.cast<float>());
        }
      }
      int count = 0;
      for (const Eigen::Vector3f& p : kept_in) {
        float height = -std::numeric_limits<float>::infinity();
        for (const Eigen::Vector3f& q : lowest_in) {
          const float dx = p.x() - q.x(), dy = p.y() - q.y();
          const float dxy2 = dx * dx + dy * dy;
          if (dxy2 > reach2) continue;
          height = std::max(height, p.z() - q.z() - rise * std::sqrt(dxy2));
        }
        count += height >= static_cast<float>(config.obstacle_min_height_m);
      }
      return count;
    };
    const Expected<FrameSummary> in_all = frame->IntegrateInto(all);
    const Expected<FrameSummary> in_window = frame->IntegrateInto(rolling);
    ASSERT_TRUE(in_all.ok() && in_window.ok());
    const TerrainGrid& window = rolling.grid();
    EXPECT_EQ(in_all->obstacle_points, definition([](const CellIndex&) { return true; }))
        << "heading " << heading;
    EXPECT_EQ(in_window->obstacle_points,
              definition([&](const CellIndex& c) { return window.Contains(c); }))
        << "heading " << heading;
    outside += in_all->obstacle_points - in_window->obstacle_points;
    TerrainMap map = NewMap(config);
    const Expected<FrameSummary> summary = frame->IntegrateInto(map);
    ASSERT_TRUE(summary.ok()) << summary.error().message;
    // The returns in range, in the world; each cell's lowest, as the map keeps it.
    const TerrainGrid& grid = map.grid();
    std::vector<Eigen::Vector3d> world(frame->image.size());
    std::vector<bool> in_range(frame->image.size(), false);
    std::map<std::pair<int, int>, Eigen::Vector3f> lowest;
    for (int i = 0; i < frame->image.size(); ++i) {
      if (!frame->image.valid(i)) continue;
      const Eigen::Vector3d p = frame->image.point(i);
      const double range = p.norm();
      if (!(range > 0.0) || range > config.max_range_m) continue;
      world[i] = frame->T_world_sensor * p;
      in_range[i] = true;
      const CellIndex c = grid.IndexOf(world[i].head<2>());
      const auto [at, made] = lowest.emplace(std::pair(c.x(), c.y()), world[i].cast<float>());
      if (!made && world[i].z() < at->second.z()) at->second = world[i].cast<float>();
    }
    int expected = 0, kept_points = 0;
    std::map<std::pair<int, int>, std::uint32_t> expected_in_cell;
    // Per segment, the most any of its obstacle points stands above a lowest return within
    // reach (its plain height): a persistent obstacle's height is one segment's.
    std::map<int, double> segment_height;
    for (int i = 0; i < frame->image.size(); ++i) {
      const int label = frame->detection.labels[i];
      if (!in_range[i] || label <= 0) continue;
      if (frame->classification.verdicts[label - 1].cls != od::SegmentClass::kKept) continue;
      ++kept_points;
      const Eigen::Vector3f p = world[i].cast<float>();
      float height = -std::numeric_limits<float>::infinity();
      float plain = -std::numeric_limits<float>::infinity();
      for (const auto& [cell, q] : lowest) {
        const float dx = p.x() - q.x(), dy = p.y() - q.y();
        const float dxy2 = dx * dx + dy * dy;
        if (dxy2 > reach2) continue;
        height = std::max(height, p.z() - q.z() - rise * std::sqrt(dxy2));
        plain = std::max(plain, p.z() - q.z());
      }
      if (height >= static_cast<float>(config.obstacle_min_height_m)) {
        ++expected;
        double& most = segment_height.emplace(label, 0.0).first->second;
        most = std::max(most, static_cast<double>(plain));
        const CellIndex c = grid.IndexOf(world[i].head<2>());
        ++expected_in_cell[{c.x(), c.y()}];
      }
    }
    EXPECT_EQ(summary->obstacle_points, expected) << "heading " << heading;
    int cells_differ = 0;
    ForEachCell(grid, [&](const CellIndex& c, const Cell& cell) {
      const auto it = expected_in_cell.find({c.x(), c.y()});
      cells_differ += cell.obstacle_points != (it == expected_in_cell.end() ? 0u : it->second);
    });
    EXPECT_EQ(cells_differ, 0) << "heading " << heading;
    double tallest = 0.0, expected_tallest = 0.0;
    for (const auto& [label, h] : segment_height) expected_tallest = std::max(expected_tallest, h);
    for (const Obstacle& o : map.obstacles()) {
      tallest = std::max(tallest, o.height_m);
      EXPECT_TRUE(std::any_of(segment_height.begin(), segment_height.end(),
                              [&](const auto& s) { return s.second == o.height_m; }))
          << "heading " << heading << ": obstacle " << o.id << " " << o.height_m << " m tall";
    }
    EXPECT_FALSE(map.obstacles().empty()) << "heading " << heading;
    EXPECT_EQ(tallest, expected_tallest) << "heading " << heading;
    obstacle_points += expected;
    foot_points += kept_points - expected;
    ++frames;
  }
  EXPECT_EQ(frames, 3);
  EXPECT_GT(obstacle_points, 300);  // the objects' points
  EXPECT_GT(foot_points, 20);       // their feet
  EXPECT_GT(outside, 50);           // obstacle points out of the window
}

// A rolling window smaller than the frame: the octree takes the free voxels and the ends
// inside the window and nothing outside it, each as the unbounded map takes it.
TEST(TerrainMap, TheRollingOctreeTakesTheVoxelsInsideItsWindow) {
  sim::Scene scene(sim::Terrain::Hills(0.0, {sim::SineWave{0.4, 6.0, 0.3, 0.0}}));
  for (const double x : {3.0, 6.0, 9.0, 12.0}) scene.AddPole(x, 0.5, 0.1, 1.2, true);
  const Expected<SimFrame> frame = test::CameraFrame(
      scene, Camera(), CameraPose({0.0, 0.0, 1.5}, 0.0, 15.0), 0.0, 0, Settings());
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  MapConfig config;
  config.max_range_m = 15.0;
  TerrainMap unbounded = NewMap(config);
  config.window_size_m = 10.0;  // 5 m each way of the sensor
  TerrainMap rolling = NewMap(config);
  const Expected<FrameSummary> all = frame->IntegrateInto(unbounded);
  const Expected<FrameSummary> in = frame->IntegrateInto(rolling);
  ASSERT_TRUE(all.ok() && in.ok());
  const double s = config.cell_size_m;
  const TerrainGrid& grid = rolling.grid();
  const Eigen::Vector2d lo = grid.min_index().cast<double>() * s;
  const Eigen::Vector2d hi = (grid.min_index() + grid.extent()).cast<double>() * s;
  const auto inside = [&](double x, double y) {
    return x >= lo.x() && x < hi.x() && y >= lo.y() && y < hi.y();
  };
  const TerrainOcTree& a = rolling.octree();
  const TerrainOcTree& b = unbounded.octree();
  std::size_t leaves = 0;
  for (auto it = a.begin_leafs(), end = a.end_leafs(); it != end; ++it) {
    ASSERT_TRUE(inside(it.getX(), it.getY())) << it.getX() << ", " << it.getY();
    ++leaves;
  }
  // The unbounded map's voxels inside: the rolling map's, with the same values; its ends
  // inside: those the rolling map counts.
  std::size_t compared = 0, outside = 0;
  double ends_inside = 0.0;
  for (auto it = b.begin_leafs(), end = b.end_leafs(); it != end; ++it) {
    const double half = it.getSize() / 2.0;
    if (!inside(it.getX() - half, it.getY() - half) ||
        !inside(it.getX() + half - 1e-6, it.getY() + half - 1e-6)) {
      outside += !inside(it.getX(), it.getY());
      continue;
    }
    if (it->getLogOdds() > 0.0f) ends_inside += std::pow(it.getSize() / config.voxel_size_m, 3.0);
    const TerrainOcTreeNode* other = a.search(it.getKey(), it.getDepth());
    ASSERT_NE(other, nullptr);
    ASSERT_EQ(other->getLogOdds(), it->getLogOdds());
    ASSERT_EQ(other->obstacle_log_odds(), it->obstacle_log_odds());
    ++compared;
  }
  EXPECT_GT(compared, 1000u);
  EXPECT_GT(outside, 1000u);
  EXPECT_GT(leaves, 1000u);
  EXPECT_EQ(static_cast<double>(in->voxels_occupied), std::round(ends_inside));
  EXPECT_LT(in->voxels_occupied, all->voxels_occupied);
}

TEST(TerrainMap, EveryCostIsTheBruteForceInflationOfTheLethalCells) {
  const BoxScene box;
  // The default inflation radius, and one of a whole number of cells (1.2 / 0.2 rounds to
  // 5.999...), whose last ring is inflated too.
  for (const double inflation : {1.5, 1.2}) {
    MapConfig config;
    config.inflation_radius_m = inflation;
    TerrainMap map = NewMap(config);
    for (const SimFrame& f : box.frames) Integrate(map, f);
    const double s = config.cell_size_m;
    std::vector<CellIndex> lethal;
    ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
      if (cell.lethal) lethal.push_back(c);
    });
    ASSERT_FALSE(lethal.empty());
    int checked = 0, last_ring = 0;
    ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
      // nav2: distance to the nearest lethal cell, centre to centre, then the inflation rule.
      double nearest = std::numeric_limits<double>::infinity();
      for (const CellIndex& l : lethal)
        nearest = std::min(nearest, (c - l).cast<double>().norm() * s);
      Cost expected = cell.lethal ? kLethalCost : !cell.observed ? kUnknownCost : cell.terrain_cost;
      if (nearest > 0.0 && nearest <= config.inflation_radius_m + 1e-9) {
        const double factor =
            std::exp(-config.cost_scaling_factor * (nearest - config.robot_radius_m));
        const Cost inflated =
            nearest <= config.robot_radius_m ? kInscribedCost : static_cast<Cost>(252 * factor);
        if (expected == kUnknownCost) {
          if (inflated >= kInscribedCost) expected = inflated;
        } else {
          last_ring += nearest > config.inflation_radius_m - 1e-9 && inflated > expected;
          expected = std::max(expected, inflated);
        }
      }
      ASSERT_EQ(cell.cost, expected)
          << "inflation " << inflation << ", cell " << c.transpose() << " at " << nearest << " m";
      // Flat, noiseless ground away from the box costs nothing by itself.
      if (nearest > 1.0 && cell.observed) {
        EXPECT_EQ(cell.terrain_cost, 0) << c.transpose();
      }
      ++checked;
    });
    EXPECT_GT(checked, 1000);
    if (inflation == 1.2) {
      EXPECT_GT(last_ring, 0);  // cells exactly 1.2 m from the nearest
    }
    if (inflation != 1.5) continue;
    // nav2's numbers in front of the face (cell x = 17 lethal), along y = 0 (cell y = 0).
    EXPECT_EQ(map.CostAt({3.5, 0.1}), kLethalCost);
    EXPECT_EQ(map.CostAt({3.1, 0.1}), kInscribedCost);  // 0.4 m <= robot radius 0.5 m
    EXPECT_EQ(map.CostAt({2.9, 0.1}), 186);             // 0.6 m: 252 exp(-3 * 0.1) = 186.7
    EXPECT_EQ(map.CostAt({2.5, 0.1}), 56);              // 1.0 m: 252 exp(-3 * 0.5) = 56.2
    EXPECT_EQ(map.CostAt({2.1, 0.1}), 16);              // 1.4 m: 252 exp(-3 * 0.9) = 16.9
  }
}

// Slope, roughness and terrain cost of every cell against the plane fitted directly, by QR on
// the rows (1, dx, dy) of its neighbours with an elevation: on hills, with a rock hiding
// ground behind it, so that many fits have every neighbour and many only some (the edges of
// what was seen, of the shadow and of the rock's cells). The fits of four cells at a time
// (AVX2) equal those of one at a time bit for bit.
TEST(TerrainMap, EverySlopeIsThePlaneFittedToTheNeighboursElevations) {
  const UncapLanesAtEnd uncap;
  if (od::internal::VectorLanes() < 8) {
    std::printf("note: no AVX2 here: the plane fits of four cells at a time were not run\n");
  }
  sim::Scene scene(sim::Terrain::Hills(0.0, {{0.4, 6.0, 0.3, 0.0}, {0.15, 2.5, 2.0, 1.0}}));
  scene.AddRock(4.0, 0.5, {0.5, 0.4, 0.4}, 0.5, 0.3, true, "rock");
  const od::io::DetectSettings settings = Settings();
  std::vector<SimFrame> frames;
  int id = 0;
  for (const Eigen::Isometry3d& T :
       {CameraPose({1.0, 0.0, 2.0}, 0.0, 25.0), CameraPose({1.5, 2.0, 2.0}, -30.0, 25.0)}) {
    Expected<SimFrame> f = test::CameraFrame(scene, Camera(), T, 0.1 * id, id, settings);
    ASSERT_TRUE(f.ok()) << f.error().message;
    frames.push_back(std::move(*f));
    ++id;
  }
  // The default radius, and one of a whole number of cells (0.6 / 0.2 rounds to 2.999...).
  for (const double radius : {0.5, 0.6}) {
    MapConfig config;
    config.plane_fit_radius_m = radius;
    const auto mapped = [&](int lanes) {
      od::internal::CapVectorLanes(lanes);
      TerrainMap built = NewMap(config);
      for (const SimFrame& f : frames) Integrate(built, f);
      return built;
    };
    const TerrainMap map = mapped(0);
    // Four cells at a time (AVX2, where the processor has it) against one at a time, bit for
    // bit.
    const TerrainMap one_at_a_time = mapped(1);
    const std::string where = "radius " + std::to_string(radius) + ", cell ";
    ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
      const Cell& other = one_at_a_time.grid().At(c);
      const auto same = [](float a, float b) { return (std::isnan(a) && std::isnan(b)) || a == b; };
      ASSERT_TRUE(same(cell.slope_rad, other.slope_rad) &&
                  same(cell.roughness_m, other.roughness_m) &&
                  cell.terrain_cost == other.terrain_cost)
          << where << c.transpose() << ": slope " << cell.slope_rad << " against "
          << other.slope_rad;
    });
    const double s = config.cell_size_m;
    int whole = 0, part = 0, too_few = 0;
    ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
      if (!cell.has_elevation()) return;
      // The neighbours whose centres lie within the radius, looked for well beyond it.
      std::vector<Eigen::Vector3d> rows;
      std::vector<double> z;
      int disc = 0;
      const int beyond = static_cast<int>(radius / s) + 2;
      for (int dy = -beyond; dy <= beyond; ++dy) {
        for (int dx = -beyond; dx <= beyond; ++dx) {
          if (std::hypot(dx, dy) * s > radius + 1e-9) continue;
          ++disc;
          const Cell* other = map.grid().Find(c + CellIndex(dx, dy));
          if (other == nullptr || !other->has_elevation()) continue;
          rows.emplace_back(1.0, dx * s, dy * s);
          z.push_back(other->elevation_mean_m);
        }
      }
      const int n = static_cast<int>(rows.size());
      if (n < 3) {
        EXPECT_TRUE(std::isnan(cell.slope_rad)) << where << c.transpose();
        ++too_few;
        return;
      }
      Eigen::MatrixXd A(n, 3);
      Eigen::VectorXd b(n);
      for (int k = 0; k < n; ++k) {
        A.row(k) = rows[k].transpose();
        b(k) = z[k];
      }
      // Collinear cells (det A^T A is 0, else at least s^4 on a grid): no plane.
      if (std::abs((A.transpose() * A).determinant()) < 1e-9 * s * s * s * s) {
        EXPECT_TRUE(std::isnan(cell.slope_rad)) << where << c.transpose();
        return;
      }
      const Eigen::Vector3d plane = A.colPivHouseholderQr().solve(b);
      const double slope = std::atan(std::hypot(plane.y(), plane.z()));
      const double roughness = std::sqrt((A * plane - b).squaredNorm() / n);
      ASSERT_NEAR(cell.slope_rad, slope, 1e-5) << where << c.transpose() << ", " << n;
      ASSERT_NEAR(cell.roughness_m, roughness, 1e-5) << where << c.transpose() << ", " << n;
      const double level =
          std::max(slope / config.slope_cost_max_rad, roughness / config.roughness_cost_max_m);
      EXPECT_NEAR(cell.terrain_cost, 252.0 * std::clamp(level, 0.0, 1.0), 0.5 + 1e-3)
          << where << c.transpose();
      (n == disc ? whole : part) += 1;
    });
    EXPECT_GT(whole, 1000) << where;
    EXPECT_GT(part, 100) << where;
    if (radius == 0.5) {
      EXPECT_GT(too_few, 0) << where;  // a wider disc always finds three
    }
  }
}

// Each return's class, world point and cell (TerrainMap's first pass over a frame) four pixels
// at a time (AVX2) against one at a time, bit for bit, with the count and the cells' bounds, over
// pixels with and without a return: returns in range and far ones cut at max_range; pixels
// marked without a return whose coordinates are finite, some far out (their cells would move
// either bound); returns at the origin and returns with a NaN coordinate (both no return); mask
// bytes other than 1. Seen from tilted poses far from the origin (cells on both sides of zero),
// over every remainder of four pixels.
TEST(TerrainMap, PlacesReturnsAlikeFourAtATimeAndOneAtATime) {
  const UncapLanesAtEnd uncap;
  if (od::internal::VectorLanes() < 8) {
    std::printf("note: no AVX2 here: the returns placed four at a time were not compared\n");
  }
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  int far = 0, in_range = 0, none = 0, odd = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const int n = 1001 + trial;  // every remainder of four
    std::vector<float> x(n), y(n), z(n);
    std::vector<std::uint8_t> has_return(n);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d d =
          Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized();
      const double range = 0.2 + 59.8 * unit(rng);
      x[i] = static_cast<float>(range * d.x());
      y[i] = static_cast<float>(range * d.y());
      z[i] = static_cast<float>(range * d.z());
      has_return[i] = unit(rng) < 0.1 ? 255 : 1;
      const double kind = unit(rng);
      if (kind < 0.1) {  // no return, its coordinates left finite, some far out
        has_return[i] = 0;
        if (kind < 0.03) x[i] = y[i] = static_cast<float>(kind < 0.015 ? 1e5 : -1e5);
      } else if (kind < 0.13) {  // at the origin
        x[i] = y[i] = z[i] = 0.0f;
        ++odd;
      } else if (kind < 0.16) {  // a NaN coordinate
        (kind < 0.14 ? x[i] : kind < 0.15 ? y[i] : z[i]) = kNaN;
        ++odd;
      }
    }
    const double angle = 3.0 * unit(rng);
    const Eigen::Vector3d axis =
        Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
    T.translation() = Eigen::Vector3d(1000.0 * unit(rng) - 500.0, 1000.0 * unit(rng) - 500.0,
                                      10.0 * unit(rng) - 5.0);
    const double max_range = trial % 3 == 0 ? 1000.0 : 5.0 + 30.0 * unit(rng);
    const TerrainGrid grid(trial % 2 == 0 ? 0.2 : 0.35, 0);
    struct Placed {
      std::vector<std::uint8_t> cls;
      std::vector<Eigen::Vector3d> world;
      std::vector<CellIndex> cell;
      int valid = 0;
      CellIndex lo, hi;
    };
    const CellIndex start = grid.IndexOf(T.translation().head<2>());
    const auto place = [&](int lanes) {
      od::internal::CapVectorLanes(lanes);
      Placed p{std::vector<std::uint8_t>(n),
               std::vector<Eigen::Vector3d>(n),
               std::vector<CellIndex>(n),
               0,
               start,
               start};
      internal::PlacePixels(x.data(), y.data(), z.data(), has_return.data(), n, T, max_range, grid,
                            od::internal::VectorLanes(), p.cls.data(), p.world.data(),
                            p.cell.data(), p.valid, p.lo, p.hi);
      return p;
    };
    const Placed one = place(1), wide = place(0);
    int placed = 0;
    CellIndex lo = start, hi = start;
    for (int i = 0; i < n; ++i) {
      // The definition: RangeImage's return, its norm, PlaceReturns' cut and Eigen's pose.
      const Eigen::Vector3d p(x[i], y[i], z[i]);
      const double range = p.norm();
      const bool has = has_return[i] != 0 && range > 0.0;
      const bool is_far = has && range > max_range;
      const std::uint8_t cls = !has ? internal::kNone : is_far ? internal::kFar : internal::kGround;
      Eigen::Vector3d expected = Eigen::Vector3d::Zero();
      CellIndex c = CellIndex::Zero();
      if (has) {
        (is_far ? far : in_range) += 1;
        ++placed;
        expected = is_far ? T * (p * (max_range / range)) : T * p;
        c = grid.IndexOf(expected.head<2>());
        lo = lo.cwiseMin(c);
        hi = hi.cwiseMax(c);
      } else {
        ++none;
      }
      for (const Placed* got : {&one, &wide}) {
        const std::string where = "trial " + std::to_string(trial) + ", " +
                                  (got == &one ? "one" : "four") + " at a time, pixel " +
                                  std::to_string(i);
        ASSERT_EQ(got->cls[i], cls) << where;
        if (!has) continue;  // world and cell unspecified
        ASSERT_TRUE(got->world[i] == expected)
            << where << ": " << got->world[i].transpose() << " against " << expected.transpose();
        ASSERT_EQ(got->cell[i], c) << where;
      }
    }
    for (const Placed* got : {&one, &wide}) {
      EXPECT_EQ(got->valid, placed) << "trial " << trial;
      EXPECT_EQ(got->lo, lo) << "trial " << trial;
      EXPECT_EQ(got->hi, hi) << "trial " << trial;
    }
  }
  EXPECT_GT(far, 1000);
  EXPECT_GT(in_range, 1000);
  EXPECT_GT(none, 1000);
  EXPECT_GT(odd, 1000);
}

// A pole seen in one frame only (a false obstacle, or an object that went away) is cleared
// by the frames that follow: its cells by ground seen where it stood, its voxels by the rays
// that now pass through them.
TEST(TerrainMap, FalseObstacleSeenOnceIsClearedByLaterFrames) {
  sim::Scene with_pole;
  with_pole.AddPole(7.0, 0.0, 0.12, 1.0, true, "ghost");
  const sim::Scene without_pole;
  const od::io::DetectSettings settings = Settings();
  TerrainMap map = NewMap();
  const Eigen::Vector2d ghost(7.0, 0.0);
  const auto lethal_near_ghost = [&] {
    int count = 0;
    ForEachCell(map.grid(), [&](const CellIndex& c, const Cell& cell) {
      if (cell.lethal && (map.grid().CentreOf(c) - ghost).norm() < 0.6) ++count;
    });
    return count;
  };
  const octomap::point3d face(6.9f, 0.0f, 0.5f);  // on the pole's side facing the camera
  int cleared_after = -1;
  for (int k = 0; k < 9; ++k) {
    const Eigen::Isometry3d T = CameraPose({0.5 * k, 0.0, 1.6}, 0.0, 12.0);
    const sim::Scene& scene = k == 0 ? with_pole : without_pole;
    const Expected<SimFrame> frame = test::CameraFrame(scene, Camera(), T, 0.2 * k, k, settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    const Expected<FrameSummary> summary = frame->IntegrateInto(map);
    ASSERT_TRUE(summary.ok()) << summary.error().message;
    if (k == 0) {
      EXPECT_GT(lethal_near_ghost(), 0);
      EXPECT_EQ(map.CostAt({6.9, 0.05}), kLethalCost);  // the face towards the camera
      ASSERT_EQ(map.obstacles().size(), 1u);
      EXPECT_LT((map.obstacles()[0].centroid.head<2>() - ghost).norm(), 0.3);
      const TerrainOcTreeNode* voxel = map.octree().search(face);
      ASSERT_NE(voxel, nullptr);
      EXPECT_TRUE(map.octree().IsObstacle(*voxel));
    } else if (cleared_after < 0 && lethal_near_ghost() == 0) {
      cleared_after = k;
      EXPECT_EQ(summary->obstacles_retired, 1);
    }
  }
  EXPECT_GE(cleared_after, 1);
  EXPECT_LE(cleared_after, 4) << "frames until the false obstacle's cells were cleared";
  EXPECT_TRUE(map.obstacles().empty());
  EXPECT_EQ(map.obstacles_retired(), 1);
  EXPECT_LT(map.CostAt({6.9, 0.05}), kInscribedCost);
  // The voxels of the pole's lit face below the camera are free now.
  int occupied = 0, known = 0;
  for (float z = 0.25f; z <= 0.95f; z += 0.1f) {
    for (float y = -0.08f; y <= 0.081f; y += 0.04f) {
      const TerrainOcTreeNode* voxel = map.octree().search(6.9, y, z);
      if (voxel == nullptr) continue;
      ++known;
      if (map.octree().isNodeOccupied(voxel)) ++occupied;
    }
  }
  EXPECT_GT(known, 20);
  EXPECT_EQ(occupied, 0);
}

// Hills with poles and boxes along a straight drive, mapped twice: in a rolling window whose
// half side exceeds the range kept (so that everything a frame sees lies in the window), and
// unbounded. Inside the window (less a margin where cells outside it still matter) the two
// maps agree exactly; the rolling one stays bounded while the unbounded one grows.
TEST(TerrainMap, RollingWindowMatchesTheUnboundedMapAndStaysBounded) {
  sim::Scene scene(sim::Terrain::Hills(0.0, {sim::SineWave{0.2, 12.0, 0.3, 0.0}}));
  const double poles[][2] = {{6, 2}, {12, -2}, {18, 1.5}, {24, -1}, {30, 2}};
  for (const auto& p : poles) scene.AddPole(p[0], p[1], 0.1, 1.2, true);
  scene.AddBox(15.0, 2.5, {0.8, 0.8, 0.6}, 0.3, true);
  scene.AddBox(27.0, -2.0, {0.8, 1.2, 0.7}, -0.2, true);
  const od::io::DetectSettings settings = Settings();
  const Expected<sim::Drive> drive =
      test::TrueDrive(scene.terrain(), {{0.0, 0.0}, {34.0, 0.0}}, 2.0, 2.5, 10.0 * kDegToRad);
  ASSERT_TRUE(drive.ok()) << drive.error().message;

  MapConfig unbounded_config;
  unbounded_config.max_range_m = 8.0;
  MapConfig rolling_config = unbounded_config;
  rolling_config.window_size_m = 20.0;  // half side 10 m >= 8 m range + ground radius
  TerrainMap rolling = NewMap(rolling_config);
  TerrainMap unbounded = NewMap(unbounded_config);
  std::vector<std::size_t> leaves;
  std::size_t grid_bytes = 0;
  for (const sim::DriveSample& sample : drive->samples) {
    const Expected<SimFrame> frame = test::CameraFrame(scene, Camera(), sample.T_world_sensor,
                                                       sample.stamp_s, sample.index, settings);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    ASSERT_TRUE(frame->IntegrateInto(rolling).ok());
    ASSERT_TRUE(frame->IntegrateInto(unbounded).ok());
    const MapMemory memory = rolling.Memory();
    leaves.push_back(memory.octree_leaves);
    if (grid_bytes == 0) grid_bytes = memory.grid_bytes;
    EXPECT_EQ(memory.grid_bytes, grid_bytes) << "the rolling grid never reallocates";
  }
  ASSERT_GT(leaves.size(), 30u);

  // Cells: every field equal inside the window less the margin.
  const TerrainGrid& grid = rolling.grid();
  const int margin = 2 + 7 + 2;  // plane fit + inflation + slack [cells]
  const CellIndex lo = grid.min_index() + CellIndex::Constant(margin);
  const CellIndex hi = grid.min_index() + grid.extent() - CellIndex::Constant(margin + 1);
  int compared = 0, lethal = 0;
  const auto same = [](float a, float b) { return a == b || (std::isnan(a) && std::isnan(b)); };
  for (int j = lo.y(); j <= hi.y(); ++j) {
    for (int i = lo.x(); i <= hi.x(); ++i) {
      const Cell& a = grid.At({i, j});
      const Cell blank;  // what the unbounded grid holds where nothing was ever seen
      const Cell* b = unbounded.grid().Find({i, j});
      if (b == nullptr) b = &blank;
      const std::string where = "cell " + std::to_string(i) + "," + std::to_string(j);
      ASSERT_TRUE(same(a.elevation_mean_m, b->elevation_mean_m)) << where;
      ASSERT_TRUE(same(a.elevation_min_m, b->elevation_min_m)) << where;
      ASSERT_TRUE(same(a.elevation_max_m, b->elevation_max_m)) << where;
      ASSERT_TRUE(same(a.slope_rad, b->slope_rad)) << where;
      ASSERT_TRUE(same(a.roughness_m, b->roughness_m)) << where;
      ASSERT_EQ(a.ground_points, b->ground_points) << where;
      ASSERT_EQ(a.obstacle_points, b->obstacle_points) << where;
      ASSERT_EQ(a.obstacle_log_odds, b->obstacle_log_odds) << where;
      ASSERT_EQ(a.hits, b->hits) << where;
      ASSERT_EQ(a.misses, b->misses) << where;
      ASSERT_EQ(a.observed, b->observed) << where;
      ASSERT_EQ(a.lethal, b->lethal) << where;
      ASSERT_EQ(a.terrain_cost, b->terrain_cost) << where;
      ASSERT_EQ(a.cost, b->cost) << where;
      ++compared;
      lethal += a.lethal;
    }
  }
  EXPECT_GT(compared, 3000);
  EXPECT_GT(lethal, 5) << "the window holds obstacles";

  // Voxels: every leaf of the rolling tree inside the same box is a leaf of the unbounded
  // tree with the same values.
  const double s = rolling_config.cell_size_m;
  const Eigen::Vector2d box_lo = lo.cast<double>() * s;
  const Eigen::Vector2d box_hi = (hi + CellIndex::Ones()).cast<double>() * s;
  int voxels = 0;
  const TerrainOcTree& a = rolling.octree();
  const TerrainOcTree& b = unbounded.octree();
  for (auto it = a.begin_leafs(), end = a.end_leafs(); it != end; ++it) {
    const double half = it.getSize() / 2.0;
    if (it.getX() - half < box_lo.x() || it.getX() + half > box_hi.x() ||
        it.getY() - half < box_lo.y() || it.getY() + half > box_hi.y()) {
      continue;
    }
    const TerrainOcTreeNode* other = b.search(it.getKey(), it.getDepth());
    ASSERT_NE(other, nullptr);
    ASSERT_FALSE(b.nodeHasChildren(other));
    ASSERT_EQ(other->getLogOdds(), it->getLogOdds());
    ASSERT_EQ(other->obstacle_log_odds(), it->obstacle_log_odds());
    ++voxels;
  }
  EXPECT_GT(voxels, 10000);

  // Bounded: the rolling tree stops growing once the window is full; its leaves lie within
  // the window (plus the slack the pruning leaves); the unbounded tree keeps growing.
  const std::size_t third = leaves.size() / 3;
  const std::size_t middle_max =
      *std::max_element(leaves.begin() + third, leaves.begin() + 2 * third);
  const std::size_t last_max = *std::max_element(leaves.begin() + 2 * third, leaves.end());
  EXPECT_LT(last_max, middle_max * 5 / 4);
  const double slack = (grid.extent().x() / 16 + 1) * s;
  const Eigen::Vector2d window_lo = grid.min_index().cast<double>() * s;
  const Eigen::Vector2d window_hi = (grid.min_index() + grid.extent()).cast<double>() * s;
  for (auto it = a.begin_leafs(), end = a.end_leafs(); it != end; ++it) {
    ASSERT_GT(it.getX(), window_lo.x() - slack);
    ASSERT_LT(it.getX(), window_hi.x() + slack);
    ASSERT_GT(it.getY(), window_lo.y() - slack);
    ASSERT_LT(it.getY(), window_hi.y() + slack);
  }
  EXPECT_GT(unbounded.Memory().octree_leaves, leaves.back() * 3 / 2);
  std::printf("rolling window: %zu octree leaves (unbounded %zu), grid %zu bytes\n", leaves.back(),
              unbounded.Memory().octree_leaves, grid_bytes);
}

TEST(TerrainMap, CostAlongLineVisitsEveryCellTheLineCrosses) {
  const BoxScene box;
  TerrainMap map = NewMap();
  for (const SimFrame& f : box.frames) Integrate(map, f);
  const Eigen::Vector2d a(1.03, 0.11), b(7.01, 0.63);  // through no cell corner
  const LineCost line = map.CostAlongLine(a, b);
  ASSERT_EQ(line.cells.size(), line.costs.size());
  // Through the box, and on into the unknown it hides.
  EXPECT_NE(std::find(line.costs.begin(), line.costs.end(), kLethalCost), line.costs.end());
  EXPECT_EQ(line.max_cost, *std::max_element(line.costs.begin(), line.costs.end()));
  EXPECT_EQ(line.max_cost, kUnknownCost);
  // Dense sampling: the distinct cells met, in order, appear in the traversal in order.
  std::vector<CellIndex> sampled;
  for (int k = 0; k <= 100000; ++k) {
    const CellIndex c = map.grid().IndexOf(a + (b - a) * (k / 100000.0));
    if (sampled.empty() || sampled.back() != c) sampled.push_back(c);
  }
  std::size_t next = 0;
  for (const CellIndex& c : line.cells) {
    if (next < sampled.size() && c == sampled[next]) ++next;
  }
  EXPECT_EQ(next, sampled.size());
  EXPECT_EQ(line.cells.size(), sampled.size()) << "no cell the line does not cross";

  for (std::size_t k = 0; k < line.cells.size(); ++k) {
    EXPECT_EQ(line.costs[k], map.CostAt(map.grid().CentreOf(line.cells[k])));
  }
  // Exactly through cell corners: both cells beside each corner are taken.
  const LineCost diagonal = map.CostAlongLine({0.1, 0.1}, {0.5, 0.5});
  EXPECT_EQ(diagonal.cells.size(), 7u);  // (0,0) (1,0) (0,1) (1,1) (2,1) (1,2) (2,2)
}

TEST(TerrainMap, PatchAroundIsTheGridAroundThePoint) {
  const BoxScene box;
  TerrainMap map = NewMap();
  for (const SimFrame& f : box.frames) Integrate(map, f);
  const GridPatch patch = map.PatchAround({4.05, 0.05}, 1.0);
  ASSERT_EQ(patch.cost.rows(), 11);
  ASSERT_EQ(patch.cost.cols(), 11);
  EXPECT_EQ(patch.min_index, CellIndex(15, -5));
  EXPECT_NEAR(patch.origin.x(), 3.0, 1e-12);
  int lethal = 0;
  for (int j = 0; j < 11; ++j) {
    for (int i = 0; i < 11; ++i) {
      const CellIndex c = patch.min_index + CellIndex(i, j);
      const Cell* cell = map.grid().Find(c);
      ASSERT_NE(cell, nullptr);
      EXPECT_EQ(patch.cost(i, j), cell->cost);
      if (cell->has_elevation()) {
        EXPECT_EQ(patch.elevation_m(i, j), cell->elevation_mean_m);
      } else {
        EXPECT_TRUE(std::isnan(patch.elevation_m(i, j)));
      }
      lethal += patch.cost(i, j) == kLethalCost;
    }
  }
  EXPECT_GE(lethal, 30);
  // Far outside the grid: unknown.
  const GridPatch far = map.PatchAround({500.0, 500.0}, 0.2);
  EXPECT_TRUE((far.cost.array() == kUnknownCost).all());
}

TEST(TerrainMap, RejectsAFrameThatDoesNotMatchItsDetection) {
  const BoxScene box;
  TerrainMap map = NewMap();
  const SimFrame& f = box.frames.front();
  od::Detection wrong_size = f.detection;
  wrong_size.labels.pop_back();
  Expected<FrameSummary> r =
      map.Integrate(f.image, wrong_size, f.classification, f.T_world_sensor, 0.0, 7);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("frame 7"), std::string::npos) << r.error().message;
  od::Classification missing = f.classification;
  missing.verdicts.clear();
  r = map.Integrate(f.image, f.detection, missing, f.T_world_sensor, 0.0, 7);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("verdicts"), std::string::npos) << r.error().message;
  od::Detection bad_label = f.detection;
  bad_label.labels[0] = static_cast<std::int32_t>(bad_label.segments.size()) + 1;
  r = map.Integrate(f.image, bad_label, f.classification, f.T_world_sensor, 0.0, 7);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("label"), std::string::npos) << r.error().message;
  Eigen::Isometry3d nan_pose = f.T_world_sensor;
  nan_pose.translation().x() = std::nan("");
  r = map.Integrate(f.image, f.detection, f.classification, nan_pose, 0.0, 7);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("pose"), std::string::npos) << r.error().message;
  EXPECT_EQ(map.frames_integrated(), 0);
  EXPECT_FALSE(map.ObservedBounds().has_value());
  MapConfig bad;
  bad.cell_size_m = -0.2;
  const Expected<TerrainMap> invalid = TerrainMap::Create(bad);
  ASSERT_FALSE(invalid.ok());
  EXPECT_NE(invalid.error().message.find("'cell_size'"), std::string::npos);
}

// The free-space rays cast by one thread or by several give the same map, voxel for voxel.
TEST(TerrainMap, TheMapDoesNotDependOnTheThreads) {
  sim::Scene scene;
  scene.AddPole(6.0, 0.5, 0.15, 1.2, true, "pole");
  scene.AddBox(8.0, -1.5, {0.6, 0.8, 0.7}, 0.3, true, "box");
  const od::io::DetectSettings settings = Settings();
  std::vector<std::string> trees;
  for (const int threads : {1, 2, 3}) {
    MapConfig config;
    config.threads = threads;
    TerrainMap map = NewMap(config);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Isometry3d T = CameraPose({0.6 * k, 0.1 * k, 1.5}, 5.0 * k, 10.0);
      const Expected<SimFrame> frame =
          test::CameraFrame(scene, Camera(320), T, 0.2 * k, k, settings);
      ASSERT_TRUE(frame.ok()) << frame.error().message;
      Integrate(map, *frame);
    }
    std::ostringstream data;
    map.octree().writeData(data);
    // And the grid: the terrain fit's slope, roughness and cost per cell, and the cost.
    const TerrainGrid& grid = map.grid();
    int fitted = 0;
    for (int j = 0; j < grid.extent().y(); ++j) {
      for (int i = 0; i < grid.extent().x(); ++i) {
        const Cell& cell = grid.At(grid.min_index() + CellIndex(i, j));
        data.write(reinterpret_cast<const char*>(&cell.slope_rad), sizeof(cell.slope_rad));
        data.write(reinterpret_cast<const char*>(&cell.roughness_m), sizeof(cell.roughness_m));
        data.write(reinterpret_cast<const char*>(&cell.terrain_cost), sizeof(cell.terrain_cost));
        data.write(reinterpret_cast<const char*>(&cell.cost), sizeof(cell.cost));
        fitted += std::isfinite(cell.slope_rad) ? 1 : 0;
      }
    }
    EXPECT_GT(fitted, 500) << threads << " threads";
    trees.push_back(data.str());
  }
  EXPECT_GT(trees[0].size(), 10000u);
  EXPECT_EQ(trees[0], trees[1]);
  EXPECT_EQ(trees[0], trees[2]);
}

// --- The octree's free-space update -----------------------------------------------------

// The Morton code of a key (x at bit 3b, y at 3b + 1, z at 3b + 2), bit by bit.
std::uint64_t MortonOf(const octomap::OcTreeKey& k) {
  std::uint64_t code = 0;
  for (int b = 0; b < 16; ++b) {
    for (int axis = 0; axis < 3; ++axis) {
      code |= static_cast<std::uint64_t>((k[axis] >> b) & 1u) << (3 * b + axis);
    }
  }
  return code;
}

// Keys along rays from one origin, as a frame's free space is, with repeats, plus keys at
// the ends of the key range.
std::vector<octomap::OcTreeKey> RayKeys(std::mt19937& rng, int rays) {
  const TerrainOcTree tree(0.1);
  std::uniform_real_distribution<float> u(-15.0f, 15.0f);
  octomap::KeyRay ray;
  std::vector<octomap::OcTreeKey> keys;
  for (int r = 0; r < rays; ++r) {
    if (tree.computeRayKeys(octomap::point3d(0.3f, -0.2f, 1.0f),
                            octomap::point3d(u(rng), u(rng), u(rng) / 5.0f), ray)) {
      keys.insert(keys.end(), ray.begin(), ray.end());
    }
  }
  for (const octomap::key_type a : {0, 1, 7, 8, 65527, 65535}) {
    keys.emplace_back(a, static_cast<octomap::key_type>(65535 - a), static_cast<octomap::key_type>(a));
  }
  return keys;
}

// The ray walk visits what OctoMap's computeRayKeys stores, key for key and in order: rays
// from origins on and off voxel centres, of every length (within one voxel, along an axis,
// along a diagonal through voxel corners, 25 m), at three resolutions, and rays that leave
// the tree.
TEST(RayKeys, TheWalkVisitsTheKeysOfComputeRayKeysInOrder) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  octomap::KeyRay ray;
  std::int64_t keys_compared = 0;
  for (const double resolution : {0.05, 0.1, 0.25}) {
    const TerrainOcTree tree(resolution);
    const auto check = [&](const octomap::point3d& from, const octomap::point3d& to) {
      std::vector<octomap::OcTreeKey> walked;
      const bool walk_ok = internal::ForEachRayKey(
          tree, from, to, [&](const octomap::OcTreeKey& k) { walked.push_back(k); });
      const bool ray_ok = tree.computeRayKeys(from, to, ray);
      ASSERT_EQ(walk_ok, ray_ok) << from << " -> " << to;
      const std::vector<octomap::OcTreeKey> stored(ray.begin(), ray.end());
      ASSERT_EQ(walked, stored) << from << " -> " << to << " at " << resolution << " m";
      keys_compared += static_cast<std::int64_t>(walked.size());
    };
    const float r = static_cast<float>(resolution);
    for (int k = 0; k < 3000; ++k) {
      const octomap::point3d from(u(rng) * 2.0f, u(rng) * 2.0f, 1.0f + u(rng));
      const float length = k % 3 == 0 ? 25.0f : (k % 3 == 1 ? 5.0f : 0.7f * r);
      check(from, from + octomap::point3d(u(rng), u(rng), u(rng) * 0.3f).normalized() * length);
    }
    // Along the axes and diagonals from a voxel centre and from a voxel corner.
    const octomap::point3d centre = tree.keyToCoord(tree.coordToKey(0.0, 0.0, 1.0));
    const octomap::point3d corner = centre + octomap::point3d(r, r, r) * 0.5f;
    for (const octomap::point3d& from : {centre, corner}) {
      for (const octomap::point3d& d :
           {octomap::point3d(1, 0, 0), octomap::point3d(0, -1, 0), octomap::point3d(0, 0, 1),
            octomap::point3d(1, 1, 0), octomap::point3d(-1, 1, 1), octomap::point3d(0, 0, 0)}) {
        check(from, from + d * 7.3f);
      }
    }
    // An end beyond the tree's extent: neither walks.
    check(centre, octomap::point3d(1e7f, 0.0f, 0.0f));
  }
  EXPECT_GT(keys_compared, 1000000);
}

// Rays walked in turn visit what each walks alone: every ray's keys in its order, numbered as
// packed keys and as a box of bits numbers them, for rays from origins on and off voxel centres,
// of every length (within one voxel, along the axes and diagonals, 250 voxels), in blocks that
// leave lanes without rays at the start and at the end, four rays at a time (SSE2) and eight
// (AVX2, where the processor has it); from an origin outside the tree no key.
TEST(RayKeys, RaysInTurnVisitTheKeysOfEachRayInOrder) {
  const UncapLanesAtEnd uncap;
  std::vector<int> widths = {4};
  if (od::internal::VectorLanes() >= 8) widths.push_back(8);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::int64_t keys_compared = 0;
  for (const double resolution : {0.05, 0.1, 0.25}) {
    const TerrainOcTree tree(resolution);
    const float r = static_cast<float>(resolution);
    const octomap::point3d centre = tree.keyToCoord(tree.coordToKey(0.0, 0.0, 1.0));
    for (const octomap::point3d& origin : {octomap::point3d(0.3f, -0.2f, 1.0f), centre}) {
      std::vector<octomap::OcTreeKey> ends;
      for (int k = 0; k < 1500; ++k) {
        const float length = k % 3 == 0 ? 250.0f * r : (k % 3 == 1 ? 5.0f : 0.7f * r);
        const octomap::point3d d(u(rng), u(rng), u(rng) * 0.3f);
        ends.push_back(tree.coordToKey(origin + d.normalized() * length));
      }
      for (const octomap::point3d& d :
           {octomap::point3d(1, 0, 0), octomap::point3d(0, -1, 0), octomap::point3d(0, 0, 1),
            octomap::point3d(1, 1, 0), octomap::point3d(-1, 1, 1), octomap::point3d(0, 0, 0)}) {
        ends.push_back(tree.coordToKey(origin + d * 7.3f));
      }
      octomap::OcTreeKey lo = tree.coordToKey(origin), hi = lo;
      std::vector<std::vector<octomap::OcTreeKey>> alone(ends.size());
      for (std::size_t e = 0; e < ends.size(); ++e) {
        ASSERT_TRUE(internal::ForEachRayKey(tree, origin, tree.keyToCoord(ends[e]),
                                            [&](const octomap::OcTreeKey& k) {
                                              alone[e].push_back(k);
                                              for (int i = 0; i < 3; ++i) {
                                                lo[i] = std::min(lo[i], k[i]);
                                                hi[i] = std::max(hi[i], k[i]);
                                              }
                                            }));
        for (int i = 0; i < 3; ++i) {
          lo[i] = std::min(lo[i], ends[e][i]);
          hi[i] = std::max(hi[i], ends[e][i]);
        }
      }
      internal::KeyLayout packed, boxed;
      internal::KeyBitBox box;
      ASSERT_TRUE(box.Reset(lo, hi));
      box.Layout(boxed.lo, boxed.stride);
      for (const auto& [layout, lanes] :
           {std::pair(packed, 4), std::pair(boxed, 4), std::pair(packed, widths.back()),
            std::pair(boxed, widths.back())}) {
        od::internal::CapVectorLanes(lanes);
        for (const std::size_t count :
             {ends.size(), std::size_t{1}, std::size_t{2}, std::size_t{3}, std::size_t{5},
              std::size_t{7}, std::size_t{9}, std::size_t{13}, std::size_t{64}, std::size_t{65}}) {
          std::vector<std::vector<octomap::OcTreeKey>> in_turn(count);
          internal::ForEachRayKeyInTurn(tree, origin, ends.data(), ends.data() + count, layout,
                                        [&](std::size_t ray, std::int64_t n) {
                                          ASSERT_LT(ray, count);
                                          in_turn[ray].emplace_back(
                                              static_cast<octomap::key_type>(layout.Axis(n, 0)),
                                              static_cast<octomap::key_type>(layout.Axis(n, 1)),
                                              static_cast<octomap::key_type>(layout.Axis(n, 2)));
                                        });
          for (std::size_t e = 0; e < count; ++e) {
            ASSERT_EQ(in_turn[e], alone[e]) << "ray " << e << " of " << count << " at "
                                            << resolution << " m, " << lanes << " lanes";
            keys_compared += static_cast<std::int64_t>(in_turn[e].size());
          }
        }
      }
    }
    // From outside the tree: nothing.
    const octomap::OcTreeKey end = tree.coordToKey(0.0, 0.0, 0.0);
    for (const int lanes : widths) {
      od::internal::CapVectorLanes(lanes);
      int called = 0;
      internal::ForEachRayKeyInTurn(tree, octomap::point3d(1e7f, 0.0f, 0.0f), &end, &end + 1,
                                    internal::KeyLayout{},
                                    [&](std::size_t, std::int64_t) { ++called; });
      EXPECT_EQ(called, 0);
    }
  }
  EXPECT_GT(keys_compared, 1000000);
}

// A tree's nodes as OctoMap's stream holds them: two trees with the same bytes are the same
// tree, node for node.
std::string TreeBytes(const TerrainOcTree& tree) {
  std::ostringstream bytes;
  tree.writeData(bytes);
  return bytes.str();
}

// The least and the greatest key along each axis.
std::pair<octomap::OcTreeKey, octomap::OcTreeKey> BoxOf(
    const std::vector<octomap::OcTreeKey>& keys) {
  octomap::OcTreeKey lo = keys.front(), hi = keys.front();
  for (const octomap::OcTreeKey& k : keys) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], k[i]);
      hi[i] = std::max(hi[i], k[i]);
    }
  }
  return {lo, hi};
}

// A box of bits hands over the keys set in it: the same set as inserting them one by one,
// keys on the box's margin (one beyond the keys it was made for) included; MoveInto empties
// it for the next frame, and so does a Reset after keys were set and not handed over; a box
// too large is refused.
TEST(KeyBitBox, HandsOverTheKeysSetInIt) {
  std::mt19937 rng(23);
  std::vector<octomap::OcTreeKey> keys = RayKeys(rng, 400);
  keys.resize(keys.size() - 6);  // without RayKeys' keys at the ends of the key range
  const auto [lo, hi] = BoxOf(keys);
  const auto shifted = [](const octomap::OcTreeKey& k, int by) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>(k[0] + by),
                              static_cast<octomap::key_type>(k[1] + by),
                              static_cast<octomap::key_type>(k[2] + by));
  };
  keys.push_back(shifted(lo, -1));
  keys.push_back(shifted(hi, 1));
  internal::KeyBitBox box;
  internal::KeyLayout layout;
  const auto morton = [](const internal::KeyBricks& set) {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
    std::vector<std::uint64_t> codes;
    set.ForEachInMortonOrder(
        nullptr, order, [&](const octomap::OcTreeKey& k, bool) { codes.push_back(MortonOf(k)); });
    return codes;
  };
  for (int pass = 0; pass < 3; ++pass) {
    ASSERT_TRUE(box.Reset(lo, hi));
    box.Layout(layout.lo, layout.stride);
    internal::KeyBricks reference, handed;
    reference.Clear();
    handed.Clear();
    for (std::size_t k = pass; k < keys.size(); k += pass + 1) {  // a different subset each pass
      box.Set(layout.Of(keys[k][0], keys[k][1], keys[k][2]));
      reference.Insert(keys[k]);
    }
    if (pass == 2) {  // set and not handed over: the next Reset empties it
      ASSERT_TRUE(box.Reset(lo, hi));
      box.MoveInto(handed);
      EXPECT_EQ(handed.size(), 0u);
      continue;
    }
    box.MoveInto(handed);
    EXPECT_GT(handed.size(), 5000u);
    EXPECT_EQ(morton(handed), morton(reference)) << "pass " << pass;
  }
  EXPECT_FALSE(box.Reset(octomap::OcTreeKey(0, 0, 0), octomap::OcTreeKey(65535, 65535, 65535)));
}

// A set cleared for a box indexes its bricks densely: the same keys, order and Morton walk
// as a hashed set, cleared and reused, and merged with another box set.
TEST(KeyBricks, ADenseBoxHoldsTheSameKeysAsHashing) {
  std::mt19937 rng(17);
  const std::vector<octomap::OcTreeKey> keys = RayKeys(rng, 700);
  const auto [lo, hi] = BoxOf(keys);
  internal::KeyBricks hashed, dense, dense_half, other_half;
  for (int pass = 0; pass < 2; ++pass) {
    hashed.Clear();
    dense.Clear(lo, hi);
    dense_half.Clear(lo, hi);
    other_half.Clear(lo, hi);
    internal::KeyBricks::Inserter insert(dense);
    for (std::size_t k = 0; k < keys.size(); ++k) {
      hashed.Insert(keys[k]);
      insert(keys[k]);
      (k % 2 == 0 ? dense_half : other_half).Insert(keys[k]);
    }
    dense_half.Merge(other_half);
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
    std::vector<std::uint64_t> from_hashed, from_dense, from_merged;
    hashed.ForEachInMortonOrder(nullptr, order, [&](const octomap::OcTreeKey& k, bool) {
      from_hashed.push_back(MortonOf(k));
    });
    dense.ForEachInMortonOrder(&hashed, order, [&](const octomap::OcTreeKey& k, bool in) {
      EXPECT_TRUE(in);
      from_dense.push_back(MortonOf(k));
    });
    dense_half.ForEachInMortonOrder(nullptr, order, [&](const octomap::OcTreeKey& k, bool) {
      from_merged.push_back(MortonOf(k));
    });
    EXPECT_GT(from_hashed.size(), 10000u);
    EXPECT_EQ(from_dense, from_hashed);
    EXPECT_EQ(from_merged, from_hashed);
    EXPECT_EQ(dense.size(), hashed.size());
    for (std::size_t k = 0; k < keys.size(); k += 11) EXPECT_TRUE(dense.Contains(keys[k]));
    // Outside the box, and inside it where nothing was put.
    EXPECT_FALSE(dense.Contains(
        octomap::OcTreeKey(static_cast<octomap::key_type>(hi[0] + 9), lo[1], lo[2])));
    EXPECT_EQ(dense.Contains(lo), hashed.Contains(lo));
  }
}

// The bricks of either of two sets (one indexed in a box, one hashed, as a frame's free voxels
// and ends are), each once, in Morton order, each with the same brick of each set; BrickOf
// finds a set's brick by its code, and none outside the box or where nothing was put.
TEST(KeyBricks, TheBricksOfEitherSetComeOnceInMortonOrder) {
  std::mt19937 rng(23);
  std::vector<octomap::OcTreeKey> keys = RayKeys(rng, 400);
  keys.resize(keys.size() - 6);  // without RayKeys' keys at the ends of the key range
  const auto [lo, hi] = BoxOf(keys);
  internal::KeyBricks mine, theirs;
  mine.Clear(lo, hi);
  theirs.Clear();
  // Brick (Morton code) -> which sets hold a key in it.
  std::map<std::uint64_t, int> reference;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const std::uint64_t code = MortonOf(keys[k]) >> 9;
    if (k % 3 != 2) {
      mine.Insert(keys[k]);
      reference[code] |= 1;
    }
    if (k % 3 != 0 || k % 7 == 0) {
      theirs.Insert(keys[k]);
      reference[code] |= 2;
    }
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  std::map<std::uint64_t, int> seen;
  std::uint64_t last = 0;
  bool first = true, ordered = true;
  mine.ForEachBrickOfEitherInMortonOrder(
      theirs, order,
      [&](std::uint64_t code, const internal::KeyBricks::Brick* a,
          const internal::KeyBricks::Brick* b) {
        ordered = ordered && (first || code > last);
        first = false;
        last = code;
        seen[code] = (a != nullptr ? 1 : 0) | (b != nullptr ? 2 : 0);
        EXPECT_EQ(a, mine.BrickOf(code));
        EXPECT_EQ(b, theirs.BrickOf(code));
        for (const internal::KeyBricks::Brick* brick : {a, b}) {
          if (brick == nullptr) continue;
          EXPECT_EQ(brick->code, code);
          EXPECT_TRUE(std::any_of(std::begin(brick->bits), std::end(brick->bits),
                                  [](std::uint64_t w) { return w != 0; }));
        }
      });
  EXPECT_TRUE(ordered);
  EXPECT_EQ(seen, reference);
  int both = 0, one = 0;
  for (const auto& [code, sets] : reference) (sets == 3 ? both : one) += 1;
  EXPECT_GT(both, 100);
  EXPECT_GT(one, 10);
  const std::uint64_t beyond =
      MortonOf(octomap::OcTreeKey(static_cast<octomap::key_type>(hi[0] + 16), lo[1], lo[2])) >> 9;
  EXPECT_EQ(mine.BrickOf(beyond), nullptr);
  EXPECT_EQ(theirs.BrickOf(beyond), nullptr);
}

TEST(KeyBricks, HoldsEveryKeyOnceAndGivesThemInMortonOrder) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 3; ++trial) {
    const std::vector<octomap::OcTreeKey> keys = RayKeys(rng, 300 + 400 * trial);
    internal::KeyBricks bricks, exclude;
    std::set<std::uint64_t> reference, excluded;
    for (int pass = 0; pass < 2; ++pass) {  // reused after Clear(), as from frame to frame
      bricks.Clear();
      exclude.Clear();
      reference.clear();
      excluded.clear();
      for (std::size_t k = 0; k < keys.size(); ++k) {
        bricks.Insert(keys[k]);
        reference.insert(MortonOf(keys[k]));
        if (k % 7 == 0) {
          exclude.Insert(keys[k]);
          excluded.insert(MortonOf(keys[k]));
        }
      }
      EXPECT_EQ(bricks.size(), reference.size());
      for (std::size_t k = 0; k < keys.size(); k += 13) EXPECT_TRUE(bricks.Contains(keys[k]));
      std::vector<std::uint64_t> expected;
      for (const std::uint64_t code : reference) {
        if (excluded.count(code) == 0) expected.push_back(code);
      }
      std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
      std::vector<std::uint64_t> got, got_all;
      bricks.ForEachInMortonOrder(&exclude, order, [&](const octomap::OcTreeKey& k, bool in) {
        if (!in) got.push_back(MortonOf(k));
      });
      bricks.ForEachInMortonOrder(nullptr, order, [&](const octomap::OcTreeKey& k, bool in) {
        EXPECT_FALSE(in);
        got_all.push_back(MortonOf(k));
      });
      std::set<std::uint64_t> any_order;  // ForEach: the same keys, each once
      std::size_t visits = 0;
      bricks.ForEach([&](const octomap::OcTreeKey& k, bool) {
        any_order.insert(MortonOf(k));
        ++visits;
      });
      EXPECT_EQ(any_order, reference);
      EXPECT_EQ(visits, reference.size());
      // Merge: the union of two sets.
      internal::KeyBricks merged = exclude;
      merged.Merge(bricks);
      EXPECT_EQ(merged.size(), reference.size());
      EXPECT_EQ(got, expected) << "trial " << trial;  // sorted, each once, exclusions flagged
      EXPECT_EQ(got_all, std::vector<std::uint64_t>(reference.begin(), reference.end()));
    }
    // A key never inserted is not held.
    EXPECT_FALSE(bricks.Contains(octomap::OcTreeKey(40000, 3, 9)));
  }
}

// The free updates of a brick at a time (a walk in Morton order) change the tree exactly as
// the walk from the root for each voxel, on a tree with occupied, free and pruned saturated
// regions; and so do the bricks' subtrees updated on several threads (UpdateBricks).
TEST(TerrainOcTree, FreeUpdatesOfABrickEqualThoseFromTheRoot) {
  std::mt19937 rng(5);
  TerrainOcTree a(0.1), b(0.1), c(0.1), d(0.1);
  const std::vector<TerrainOcTree*> trees = {&a, &b, &c, &d};
  std::uniform_int_distribution<int> near(32700, 32835);
  for (int k = 0; k < 4000; ++k) {  // occupied voxels, some obstacles
    const octomap::OcTreeKey key(static_cast<octomap::key_type>(near(rng)),
                                 static_cast<octomap::key_type>(near(rng)),
                                 static_cast<octomap::key_type>(near(rng)));
    for (TerrainOcTree* t : trees) t->Update(t->TouchLeaf(key), true, k % 3 == 0);
  }
  // Saturate the free space of a 32-voxel cube around the rays' origin (which prunes to a
  // few nodes), and some of it again along rays.
  const octomap::OcTreeKey origin = a.coordToKey(0.3, -0.2, 1.0);
  std::vector<octomap::OcTreeKey> keys;
  for (int dx = 0; dx < 32; ++dx) {
    for (int dy = 0; dy < 32; ++dy) {
      for (int dz = 0; dz < 32; ++dz) {
        keys.emplace_back(static_cast<octomap::key_type>((origin[0] & ~31) + dx),
                          static_cast<octomap::key_type>((origin[1] & ~31) + dy),
                          static_cast<octomap::key_type>((origin[2] & ~31) + dz));
      }
    }
  }
  const std::vector<octomap::OcTreeKey> along = RayKeys(rng, 200);
  keys.insert(keys.end(), along.begin(), along.end());
  for (const octomap::OcTreeKey& key : keys) {
    for (int r = 0; r < 8; ++r) {
      for (TerrainOcTree* t : trees) t->UpdateFree(key);
    }
  }
  for (TerrainOcTree* t : trees) {
    t->updateInnerOccupancy();
    t->prune();
  }
  keys = RayKeys(rng, 900);
  std::sort(keys.begin(), keys.end(), [](const octomap::OcTreeKey& x, const octomap::OcTreeKey& y) {
    return MortonOf(x) < MortonOf(y);
  });
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  int changed = 0, obstacles = 0, unchanged = 0;
  for (const octomap::OcTreeKey& key : keys) {
    const TerrainOcTree::FreeUpdate from_root = a.UpdateFree(key);
    changed += from_root.changed;
    unchanged += !from_root.changed;
    obstacles += from_root.was_obstacle;
  }
  // The same keys into b, a brick at a time, in the Morton order of the bricks.
  internal::KeyBricks bricks;
  for (const octomap::OcTreeKey& key : keys) bricks.Insert(key);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  int brick_changed = 0, brick_obstacles = 0;
  std::vector<TerrainOcTree::BrickUpdate> many;
  std::vector<std::array<std::uint64_t, 8>> each_was_obstacle;
  bricks.ForEachBrickInMortonOrder(
      nullptr, order,
      [&](const internal::KeyBricks::Brick& brick, const internal::KeyBricks::Brick*) {
        std::uint64_t was_obstacle[8];
        brick_changed +=
            b.UpdateFreeBrick(internal::KeyBricks::BaseKey(brick), brick.bits, was_obstacle);
        for (const std::uint64_t w : was_obstacle) brick_obstacles += __builtin_popcountll(w);
        each_was_obstacle.push_back({});
        std::copy(std::begin(was_obstacle), std::end(was_obstacle),
                  each_was_obstacle.back().begin());
        TerrainOcTree::BrickUpdate& free = many.emplace_back();
        free.base = internal::KeyBricks::BaseKey(brick);
        std::copy(std::begin(brick.bits), std::end(brick.bits), std::begin(free.free));
        free.was_obstacle[0] = 12345;  // overwritten
      });
  EXPECT_GT(many.size(), 100u);
  // c on two threads, d on one: brick for brick the answers of b, and b's tree.
  for (const auto& [tree, threads] : {std::pair{&c, 2}, std::pair{&d, 1}}) {
    std::vector<TerrainOcTree::BrickUpdate> updated = many;
    tree->UpdateBricks(updated, threads);
    int tree_changed = 0;
    for (std::size_t i = 0; i < updated.size(); ++i) {
      tree_changed += updated[i].changed;
      for (int w = 0; w < 8; ++w) {
        ASSERT_EQ(updated[i].was_obstacle[w], each_was_obstacle[i][static_cast<std::size_t>(w)])
            << "brick " << i << ", " << threads << " threads";
      }
    }
    EXPECT_EQ(tree_changed, brick_changed) << threads << " threads";
    EXPECT_EQ(tree->size(), b.size()) << threads << " threads";
    EXPECT_TRUE(TreeBytes(*tree) == TreeBytes(b)) << threads << " threads";
  }
  EXPECT_EQ(brick_changed, changed);
  EXPECT_EQ(brick_obstacles, obstacles);
  EXPECT_GT(changed, 1000);
  EXPECT_GT(unchanged, 100);  // inside the pruned saturated regions
  EXPECT_GT(obstacles, 0);
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(TreeBytes(a) == TreeBytes(b));
}

// Collapsing only what is saturated free keeps every leaf's values, deletes nodes, and
// leaves a tree that OctoMap's full prune then makes into the tree it makes unhelped; and a
// rolling window's cut leaves the same voxels whether the tree was pruned fully or not.
TEST(TerrainOcTree, PruningWhatIsSaturatedFreeKeepsTheLeavesAndTheFullPrune) {
  std::mt19937 rng(41);
  TerrainOcTree a(0.1), b(0.1);
  std::uniform_int_distribution<int> near(32700, 32835);
  std::vector<octomap::OcTreeKey> occupied;
  for (int k = 0; k < 3000; ++k) {
    occupied.emplace_back(static_cast<octomap::key_type>(near(rng)),
                          static_cast<octomap::key_type>(near(rng)),
                          static_cast<octomap::key_type>(near(rng)));
  }
  // Free space along rays, some voxels saturated (seen free 8 times), some once, and the
  // occupied voxels (some of them obstacles) among them.
  const std::vector<octomap::OcTreeKey> rays = RayKeys(rng, 600);
  const auto fill = [&](TerrainOcTree& t, const std::vector<octomap::OcTreeKey>& seen_twice) {
    for (std::size_t k = 0; k < rays.size(); ++k) {
      for (int r = 0; r < (k % 5 == 0 ? 1 : 8); ++r) t.UpdateFree(rays[k]);
    }
    for (const octomap::OcTreeKey& key : seen_twice) {
      for (int r = 0; r < 2; ++r) t.UpdateFree(key);
    }
    for (std::size_t k = 0; k < occupied.size(); ++k) {
      t.Update(t.TouchLeaf(occupied[k]), true, k % 3 == 0);
    }
  };
  fill(a, {});
  fill(b, {});
  const auto values = [&](const TerrainOcTree& t) {
    std::vector<std::pair<float, float>> v;
    for (const std::vector<octomap::OcTreeKey>* keys :
         {&rays, static_cast<const std::vector<octomap::OcTreeKey>*>(&occupied)}) {
      for (const octomap::OcTreeKey& key : *keys) {
        const TerrainOcTreeNode* n = t.search(key);
        v.emplace_back(n ? n->getLogOdds() : 99.0f, n ? n->obstacle_log_odds() : 99.0f);
      }
    }
    return v;
  };
  const std::size_t nodes_before = a.size();
  const std::size_t deleted = a.PruneSaturatedFree();
  EXPECT_GT(deleted, 1000u);
  EXPECT_EQ(a.size(), nodes_before - deleted);
  EXPECT_EQ(values(a), values(b));
  EXPECT_EQ(a.PruneSaturatedFree(), 0u);  // nothing left to collapse
  const auto same_after_full_prune = [](TerrainOcTree& x, TerrainOcTree& y) {
    for (TerrainOcTree* t : {&x, &y}) {
      t->updateInnerOccupancy();
      t->prune();
    }
    EXPECT_TRUE(TreeBytes(x) == TreeBytes(y)) << "the trees' bytes differ";
    EXPECT_EQ(x.size(), y.size());
  };
  // A rolling window's cut through nodes pruned in one and not in the other (b fully pruned
  // first, as before every 8 frames): the same voxels stay.
  // A block of 32 x 32 x 8 voxels seen free twice (equal, not saturated: OctoMap's prune
  // collapses it into nodes up to 1.6 m wide) among the rays, and the window's border
  // through it on voxel boundaries.
  TerrainOcTree c(0.1), d(0.1);
  const octomap::OcTreeKey corner(32768, 32768, 32768);
  std::vector<octomap::OcTreeKey> block;
  for (int dx = 0; dx < 32; ++dx) {
    for (int dy = 0; dy < 32; ++dy) {
      for (int dz = 0; dz < 8; ++dz) {
        block.emplace_back(static_cast<octomap::key_type>(corner[0] + dx),
                           static_cast<octomap::key_type>(corner[1] + dy),
                           static_cast<octomap::key_type>(corner[2] + dz));
      }
    }
  }
  fill(c, block);
  fill(d, block);
  c.PruneSaturatedFree();
  d.updateInnerOccupancy();
  d.prune();
  const double v = 0.1;
  const octomap::point3d base = c.keyToCoord(corner) - octomap::point3d(0.05f, 0.05f, 0.05f);
  const Eigen::Vector2d lo(base.x() + 13 * v, base.y() - 40 * v);
  const Eigen::Vector2d hi(base.x() + 90 * v, base.y() + 21 * v);
  EXPECT_GT(c.DeleteOutsideXY(lo, hi), 1000u);
  d.DeleteOutsideXY(lo, hi);
  same_after_full_prune(c, d);
  same_after_full_prune(a, b);
}

// Nodes come from chunks of their own, taken and freed by any thread: trees made on one
// thread and destroyed on another, threads that end while holding free blocks, and threads
// making trees at once leave every tree with the values it was given (run in the CI's
// ThreadSanitizer stage too).
TEST(TerrainOcTree, NodesMadeAndFreedOnDifferentThreadsKeepEveryTreeWhole) {
  const auto fill = [](TerrainOcTree& t, int seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    std::uniform_int_distribution<int> near(32600, 32935);
    std::vector<octomap::OcTreeKey> keys;
    for (int k = 0; k < 20000; ++k) {
      keys.emplace_back(static_cast<octomap::key_type>(near(rng)),
                        static_cast<octomap::key_type>(near(rng)),
                        static_cast<octomap::key_type>(near(rng)));
      t.Update(t.TouchLeaf(keys.back()), true, k % 2 == 0);
    }
    return keys;
  };
  const auto whole = [](const TerrainOcTree& t, const std::vector<octomap::OcTreeKey>& keys) {
    int wrong = 0;
    for (const octomap::OcTreeKey& key : keys) {
      const TerrainOcTreeNode* n = t.search(key);
      wrong += n == nullptr || !(n->getLogOdds() > 0.0f);
    }
    return wrong;
  };
  std::unique_ptr<TerrainOcTree> made_there;
  std::vector<octomap::OcTreeKey> there_keys;
  std::thread([&] {
    made_there = std::make_unique<TerrainOcTree>(0.1);
    there_keys = fill(*made_there, 1);
    TerrainOcTree gone(0.1);  // freed on that thread, which then ends holding its nodes
    fill(gone, 2);
  }).join();
  EXPECT_EQ(whole(*made_there, there_keys), 0);
  made_there.reset();  // freed here
  std::vector<std::unique_ptr<TerrainOcTree>> trees(3);
  std::vector<std::vector<octomap::OcTreeKey>> keys(3);
  std::vector<std::thread> threads;
  for (int k = 0; k < 2; ++k) {
    threads.emplace_back([&, k] {
      trees[k] = std::make_unique<TerrainOcTree>(0.1);
      keys[k] = fill(*trees[k], 10 + k);
    });
  }
  trees[2] = std::make_unique<TerrainOcTree>(0.1);
  keys[2] = fill(*trees[2], 12);
  for (std::thread& t : threads) t.join();
  for (int k = 0; k < 3; ++k) EXPECT_EQ(whole(*trees[k], keys[k]), 0) << "tree " << k;
  EXPECT_GT(trees[0]->size(), 20000u);
}

// A frame's free voxels and ends a brick at a time (UpdateBricks, on one and two threads)
// make the tree of all the free updates from the root first and then every end touched from
// the root (TouchLeaf), through pruned nodes saturated free at every level, from one of 128
// voxels a side (above the 64-voxel subtrees UpdateBricks splits by) down to two voxels, pruned
// nodes that are not saturated, existing and new nodes, with the same answers: free voxels
// changed, obstacles seen through.
TEST(TerrainOcTree, BrickUpdatesEqualFreeUpdatesThenTouches) {
  std::mt19937 rng(11);
  TerrainOcTree a(0.1), b(0.1), c(0.1);
  const std::vector<TerrainOcTree*> trees = {&a, &b, &c};
  const octomap::OcTreeKey origin = a.coordToKey(0.3, -0.2, 1.0);
  const auto near = [&](int dx, int dy, int dz) {
    return octomap::OcTreeKey(static_cast<octomap::key_type>((origin[0] & ~127) + dx),
                              static_cast<octomap::key_type>((origin[1] & ~127) + dy),
                              static_cast<octomap::key_type>((origin[2] & ~127) + dz));
  };
  // The 128-voxel cube from near(0, 0, 0) saturated free and pruned to one node: read as
  // OctoMap's stream holds it (each node's two values and a byte of its children), the path
  // to it made of nodes with one child each.
  {
    std::ostringstream stream;
    const float saturated = a.getClampingThresMinLog();
    const unsigned depth = a.getTreeDepth() - 7;
    for (unsigned d = 0; d <= depth; ++d) {
      stream.write(reinterpret_cast<const char*>(&saturated), sizeof(float));
      stream.write(reinterpret_cast<const char*>(&saturated), sizeof(float));
      const char children =
          d == depth
              ? 0
              : static_cast<char>(1u << octomap::computeChildIdx(
                                      near(0, 0, 0), static_cast<int>(a.getTreeDepth() - 1 - d)));
      stream.write(&children, 1);
    }
    for (TerrainOcTree* t : trees) {
      std::istringstream in(stream.str());
      t->readData(in);
    }
    ASSERT_EQ(a.size(), depth + 1);
    ASSERT_TRUE(a.IsSaturatedFree(*a.search(near(5, 100, 77))));
  }
  const auto cube = [&](int x0, int y0, int z0, int side, int misses, bool hit) {
    for (int dx = 0; dx < side; ++dx) {
      for (int dy = 0; dy < side; ++dy) {
        for (int dz = 0; dz < side; ++dz) {
          for (TerrainOcTree* t : trees) {
            const octomap::OcTreeKey k = near(x0 + dx, y0 + dy, dz + z0);
            if (hit) t->Update(t->TouchLeaf(k), true, false);
            for (int r = 0; r < misses; ++r) t->UpdateFree(k);
          }
        }
      }
    }
  };
  // Past it, in a brick seen occupied once, a brick's upper node (4 voxels a side) and a
  // lower node (2 voxels) saturated free; a 16-voxel cube seen occupied once (equal, not
  // saturated: OctoMap's prune collapses it too).
  cube(128, 0, 0, 8, 0, true);
  cube(128, 0, 0, 4, 8, false);
  cube(132, 4, 4, 2, 8, false);
  cube(128, 16, 0, 16, 0, true);
  std::uniform_int_distribution<int> around(-8, 168);
  std::uniform_int_distribution<int> past(128, 167);
  std::vector<octomap::OcTreeKey> occupied;  // past the big cube, which stays pruned
  for (int k = 0; k < 500; ++k) {
    occupied.push_back(near(past(rng), around(rng), around(rng)));
    for (TerrainOcTree* t : trees) t->Update(t->TouchLeaf(occupied.back()), true, k % 3 == 0);
  }
  for (TerrainOcTree* t : trees) {
    t->updateInnerOccupancy();
    t->prune();
  }
  // A frame: ends (some obstacles) and free voxels, none both, in and out of the cubes (the
  // small ones' brick each way), and rays through some of the occupied voxels.
  internal::KeyBricks free_keys, ends, obstacles;
  std::uniform_int_distribution<int> small(0, 7);
  for (int k = 0; k < 6000; ++k) {
    free_keys.Insert(k % 4 == 0 ? near(128 + small(rng), small(rng), small(rng))
                                : near(around(rng), around(rng), around(rng)));
  }
  for (std::size_t k = 0; k < occupied.size(); k += 2) free_keys.Insert(occupied[k]);
  for (int k = 0; k < 1500; ++k) {
    const octomap::OcTreeKey key = k % 4 == 0 ? near(128 + small(rng), small(rng), small(rng))
                                              : near(around(rng), around(rng), around(rng));
    if (free_keys.Contains(key)) continue;
    ends.Insert(key);
    if (k % 3 == 0) obstacles.Insert(key);
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
  int changed = 0, was_obstacle = 0;
  std::vector<octomap::OcTreeKey> free_list, end_list;
  free_keys.ForEachInMortonOrder(nullptr, order, [&](const octomap::OcTreeKey& key, bool) {
    const TerrainOcTree::FreeUpdate u = a.UpdateFree(key);
    changed += u.changed;
    was_obstacle += u.was_obstacle;
    free_list.push_back(key);
  });
  ends.ForEachInMortonOrder(&obstacles, order, [&](const octomap::OcTreeKey& key, bool obstacle) {
    a.Update(a.TouchLeaf(key), true, obstacle);
    end_list.push_back(key);
  });
  EXPECT_GT(free_list.size(), 3000u);
  EXPECT_GT(end_list.size(), 1000u);
  EXPECT_GT(changed, 1000);
  EXPECT_LT(changed, static_cast<int>(free_list.size()));  // some in the saturated cube
  EXPECT_GT(was_obstacle, 0);
  std::vector<TerrainOcTree::BrickUpdate> bricks;
  free_keys.ForEachBrickOfEitherInMortonOrder(
      ends, order,
      [&](std::uint64_t code, const internal::KeyBricks::Brick* free,
          const internal::KeyBricks::Brick* hit) {
        TerrainOcTree::BrickUpdate& u = bricks.emplace_back();
        u.base = internal::KeyBricks::BaseKeyOf(code);
        const internal::KeyBricks::Brick* obstacle = obstacles.BrickOf(code);
        for (int w = 0; w < 8; ++w) {
          u.free[w] = free != nullptr ? free->bits[w] : 0;
          u.hit[w] = hit != nullptr ? hit->bits[w] : 0;
          u.obstacle[w] = obstacle != nullptr ? obstacle->bits[w] : 0;
        }
      });
  EXPECT_GT(bricks.size(), 100u);
  for (const auto& [tree, threads] : {std::pair{&b, 1}, std::pair{&c, 2}}) {
    std::vector<TerrainOcTree::BrickUpdate> updated = bricks;
    tree->UpdateBricks(updated, threads);
    int tree_changed = 0, tree_was_obstacle = 0;
    for (const TerrainOcTree::BrickUpdate& u : updated) {
      tree_changed += u.changed;
      for (const std::uint64_t w : u.was_obstacle) tree_was_obstacle += __builtin_popcountll(w);
    }
    EXPECT_EQ(tree_changed, changed) << threads << " threads";
    EXPECT_EQ(tree_was_obstacle, was_obstacle) << threads << " threads";
    EXPECT_EQ(tree->size(), a.size()) << threads << " threads";
    EXPECT_TRUE(TreeBytes(*tree) == TreeBytes(a)) << threads << " threads";
  }
}

// The gravity step's ground planes (libmap/src/ground_rise.hpp), here because this test runs
// under the CI's sanitizers: ground all round a sensor, cells on every side of it (negative
// cell indices too), gives the plane it lies on, height and gradient; a single scan line has
// no plane across it; the same ground 10 cm higher fits 10 cm down.
TEST(GroundSurface, APlaneIsFoundOnEverySideOfTheSensor) {
  const auto plane = [](double x, double y) { return 0.2 * x - 0.1 * y + 0.3; };
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  T_world_sensor.translation() << 3.0, -2.0, 1.5;
  std::vector<Eigen::Vector3f> points, raised;
  for (double dx = -6.0; dx <= 6.0; dx += 0.13) {
    for (double dy = -6.0; dy <= 6.0; dy += 0.17) {
      const double x = 3.0 + dx, y = -2.0 + dy;
      points.emplace_back(static_cast<float>(dx), static_cast<float>(dy),
                          static_cast<float>(plane(x, y) - 1.5));
      raised.emplace_back(points.back() + Eigen::Vector3f(0.0f, 0.0f, 0.1f));
    }
  }
  internal::GroundRiseFitConfig config;
  config.max_points = 100000;
  const internal::GroundSurface surface(internal::ThinGroundPoints(points, config), T_world_sensor,
                                        config);
  for (const Eigen::Vector2d& q : {Eigen::Vector2d(-1.7, -5.9), Eigen::Vector2d(7.2, 1.3),
                                   Eigen::Vector2d(2.9, -2.1), Eigen::Vector2d(0.4, 2.6)}) {
    const std::optional<internal::GroundSurface::Plane> p = surface.PlaneAt(q.x(), q.y());
    ASSERT_TRUE(p.has_value()) << q.transpose();
    EXPECT_NEAR(p->height_m, plane(q.x(), q.y()), 1e-4) << q.transpose();
    EXPECT_NEAR(p->gradient.x(), 0.2, 1e-4);
    EXPECT_NEAR(p->gradient.y(), -0.1, 1e-4);
  }
  EXPECT_FALSE(surface.PlaneAt(20.0, 0.0).has_value());  // no ground there

  std::vector<Eigen::Vector3f> line;  // one scan line across x
  for (double dx = -3.0; dx <= 3.0; dx += 0.05) {
    line.emplace_back(static_cast<float>(dx), 0.0f,
                      static_cast<float>(plane(3.0 + dx, -2.0) - 1.5));
  }
  const internal::GroundSurface thin(line, T_world_sensor, config);
  EXPECT_FALSE(thin.PlaneAt(3.0, -2.0).has_value());

  const std::optional<internal::GroundRiseFit> fit = internal::FitGroundRise(
      internal::ThinGroundPoints(raised, config), T_world_sensor, surface, config);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->dz_m, -0.1, 1e-4);
  EXPECT_NEAR(fit->gradient.x(), 0.2, 1e-4);
  EXPECT_LT(fit->offset_m.head<2>().norm(), 0.5);  // ground all round: the offsets cancel
}

}  // namespace
}  // namespace cairn::map
