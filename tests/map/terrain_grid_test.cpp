// The grid's ring buffer (rolling and unbounded) against a reference map of cells, and the
// nav2 cost rules.
#include "cairn/map/terrain_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <utility>

#include "cairn/map/cost.hpp"

namespace cairn::map {
namespace {

using Key = std::pair<int, int>;

// A mark that says which cell a value was written to.
std::uint32_t Mark(const CellIndex& c) {
  return static_cast<std::uint32_t>((c.x() + 5000) * 10007 + (c.y() + 5000));
}

TEST(TerrainGrid, IndexAndCentreFollowTheCellSize) {
  const TerrainGrid grid(0.25, 0);
  EXPECT_EQ(grid.IndexOf({0.0, 0.0}), CellIndex(0, 0));
  EXPECT_EQ(grid.IndexOf({0.2499, -0.0001}), CellIndex(0, -1));
  EXPECT_EQ(grid.IndexOf({-1.0, 1.0}), CellIndex(-4, 4));
  EXPECT_TRUE(grid.CentreOf({-4, 4}).isApprox(Eigen::Vector2d(-0.875, 1.125)));
  for (int i = -50; i <= 50; i += 7) {
    for (int j = -50; j <= 50; j += 9) {
      EXPECT_EQ(grid.IndexOf(grid.CentreOf({i, j})), CellIndex(i, j));
    }
  }
}

// Random moves, small and large: cells that stay keep their values, cells that enter are
// blank, and nothing outside the window is reachable.
TEST(TerrainGrid, RollingWindowKeepsWhatStaysAndBlanksWhatEnters) {
  TerrainGrid grid(0.5, 21);
  std::map<Key, std::uint32_t> reference;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> small(-3.0, 3.0), large(-30.0, 30.0);
  Eigen::Vector2d position(0.0, 0.0);
  int moves = 0;
  for (int step = 0; step < 300; ++step) {
    position += step % 25 == 0 ? Eigen::Vector2d(large(rng), large(rng))
                               : Eigen::Vector2d(small(rng), small(rng));
    moves += grid.MoveTo(position);
    EXPECT_EQ(grid.extent(), Eigen::Vector2i(21, 21));
    EXPECT_EQ(grid.min_index(), grid.IndexOf(position) - CellIndex(10, 10));
    for (int j = 0; j < 21; ++j) {
      for (int i = 0; i < 21; ++i) {
        const CellIndex c = grid.min_index() + CellIndex(i, j);
        const auto it = reference.find({c.x(), c.y()});
        const std::uint32_t expected = it == reference.end() ? 0 : it->second;
        ASSERT_EQ(grid.At(c).ground_points, expected) << "step " << step;
      }
    }
    // Forget what left, mark a few cells of the new window.
    for (auto it = reference.begin(); it != reference.end();) {
      it = grid.Contains({it->first.first, it->first.second}) ? std::next(it) : reference.erase(it);
    }
    for (int k = 0; k < 30; ++k) {
      const CellIndex c =
          grid.min_index() + CellIndex(static_cast<int>(rng() % 21), static_cast<int>(rng() % 21));
      grid.At(c).ground_points = Mark(c);
      reference[{c.x(), c.y()}] = Mark(c);
    }
    EXPECT_EQ(grid.Find(grid.min_index() - CellIndex(1, 0)), nullptr);
    EXPECT_EQ(grid.Find(grid.min_index() + CellIndex(0, 21)), nullptr);
  }
  EXPECT_GT(moves, 250);
  EXPECT_EQ(grid.slot_count(), 21u * 21u);
}

TEST(TerrainGrid, UnboundedGridGrowsKeepingEveryCell) {
  TerrainGrid grid(0.2, 0);
  EXPECT_EQ(grid.extent(), Eigen::Vector2i(0, 0));
  std::map<Key, std::uint32_t> reference;
  std::mt19937 rng(5);
  int reallocations = 0;
  CellIndex lo(0, 0), hi(0, 0);
  for (int step = 0; step < 400; ++step) {
    // A walk that wanders off in every direction.
    const CellIndex centre(static_cast<int>(150 * std::sin(step * 0.05)) + step / 2,
                           static_cast<int>(120 * std::cos(step * 0.031)) - step / 3);
    const CellIndex a = centre - CellIndex(3, 2), b = centre + CellIndex(4, 5);
    reallocations += grid.Reserve(a, b);
    lo = step == 0 ? a : lo.cwiseMin(a);
    hi = step == 0 ? b : hi.cwiseMax(b);
    EXPECT_EQ(grid.min_index(), lo);
    EXPECT_EQ(grid.extent(), hi - lo + CellIndex::Ones());
    for (int k = 0; k < 5; ++k) {
      const CellIndex c = a + CellIndex(static_cast<int>(rng() % 8), static_cast<int>(rng() % 8));
      grid.At(c).ground_points = Mark(c);
      reference[{c.x(), c.y()}] = Mark(c);
    }
  }
  for (int j = lo.y(); j <= hi.y(); ++j) {
    for (int i = lo.x(); i <= hi.x(); ++i) {
      const auto it = reference.find({i, j});
      ASSERT_EQ(grid.At({i, j}).ground_points, it == reference.end() ? 0u : it->second);
    }
  }
  EXPECT_LE(reallocations, 8) << "the buffer at least doubles when it grows";
  EXPECT_FALSE(grid.MoveTo({100.0, 100.0}));
}

// The slot table gives Slot() for every index of a box that lies in the extent and -1 for
// the rest, on rolling windows moved to negative and wrapped positions and on an unbounded
// grid grown in steps.
TEST(TerrainGrid, TheSlotTableGivesSlotInsideTheExtentAndNothingOutside) {
  const auto check = [](const TerrainGrid& grid, const std::string& what) {
    const CellIndex lo = grid.min_index() - CellIndex(5, 3);
    const CellIndex hi = grid.min_index() + grid.extent() + CellIndex(4, 6);
    const TerrainGrid::SlotTable table(grid, lo, hi);
    int inside = 0;
    for (int j = lo.y(); j <= hi.y(); ++j) {
      for (int i = lo.x(); i <= hi.x(); ++i) {
        const CellIndex c(i, j);
        const std::ptrdiff_t expected =
            grid.Contains(c) ? static_cast<std::ptrdiff_t>(grid.Slot(c)) : -1;
        ASSERT_EQ(table(c), expected) << what << " at " << i << ", " << j;
        inside += expected >= 0;
      }
    }
    EXPECT_EQ(inside, grid.extent().x() * grid.extent().y()) << what;
  };
  TerrainGrid rolling(0.2, 40);
  check(rolling, "rolling, at the start");
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(3.3, -1.1), Eigen::Vector2d(-17.0, 9.9),
                                    Eigen::Vector2d(123.4, -56.7)}) {
    rolling.MoveTo(xy);
    check(rolling, "rolling, moved");
  }
  TerrainGrid unbounded(0.1, 0);
  unbounded.Reserve({-7, 2}, {30, 9});
  check(unbounded, "unbounded");
  unbounded.Reserve({-100, -45}, {12, 80});
  check(unbounded, "unbounded, grown");
}

TEST(Cost, InflationFollowsNav2) {
  // Lethal at the obstacle, inscribed within the radius, then 252 exp(-k (d - r)) truncated.
  EXPECT_EQ(InflationCost(0.0, 0.5, 3.0), kLethalCost);
  EXPECT_EQ(InflationCost(0.2, 0.5, 3.0), kInscribedCost);
  EXPECT_EQ(InflationCost(0.5, 0.5, 3.0), kInscribedCost);
  EXPECT_EQ(InflationCost(0.6, 0.5, 3.0), 186);
  EXPECT_EQ(InflationCost(1.0, 0.5, 3.0), 56);
  EXPECT_EQ(InflationCost(0.5000001, 0.5, 0.0), 252);
  for (double d = 0.55; d < 3.0; d += 0.05) {
    EXPECT_EQ(InflationCost(d, 0.5, 2.0), static_cast<Cost>(252.0 * std::exp(-2.0 * (d - 0.5))));
    EXPECT_LE(InflationCost(d + 0.05, 0.5, 2.0), InflationCost(d, 0.5, 2.0));
  }
  // Unknown cells take only inscribed or lethal inflation.
  EXPECT_EQ(CombineInflation(kUnknownCost, 200), kUnknownCost);
  EXPECT_EQ(CombineInflation(kUnknownCost, kInscribedCost), kInscribedCost);
  EXPECT_EQ(CombineInflation(40, 100), 100);
  EXPECT_EQ(CombineInflation(140, 100), 140);
}

TEST(Cost, OccupancyIsNav2sTranslationTable) {
  EXPECT_EQ(OccupancyFromCost(0), 0);
  EXPECT_EQ(OccupancyFromCost(1), 1);
  EXPECT_EQ(OccupancyFromCost(252), 98);
  EXPECT_EQ(OccupancyFromCost(253), 99);
  EXPECT_EQ(OccupancyFromCost(254), 100);
  EXPECT_EQ(OccupancyFromCost(255), -1);
  for (int c = 1; c <= 252; ++c) {
    EXPECT_EQ(OccupancyFromCost(static_cast<Cost>(c)), 1 + (97 * (c - 1)) / 251);
    if (c > 1) {
      EXPECT_GE(OccupancyFromCost(static_cast<Cost>(c)),
                OccupancyFromCost(static_cast<Cost>(c - 1)));
    }
  }
}

}  // namespace
}  // namespace cairn::map
