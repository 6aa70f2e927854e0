// TerrainGrid: the 2.5-D grid of a TerrainMap, in world xy (z up), with ring-buffer storage.
//
// Cell (i, j) covers [i s, (i + 1) s) x [j s, (j + 1) s) for the cell size s, so an index is a
// global integer key (like OctoMap's OcTreeKey) and never changes when the grid moves. The
// cells live in a buffer of nx x ny slots, cell (i, j) in slot (i mod nx, j mod ny):
//  - rolling: the extent is a fixed window [min, min + n); moving it resets only the rows
//    and columns that leave (the slots the entering ones reuse), never copies the grid;
//  - unbounded: the extent grows to take every cell touched, doubling the buffer when it
//    must (amortised; the only time cells are copied).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "cairn/map/cost.hpp"

namespace cairn::map {

namespace detail {
struct CheckpointAccess;  // checkpoint.cpp: saves and restores the private state
}  // namespace detail

/// Integer index of a grid cell (global, see above).
using CellIndex = Eigen::Vector2i;

/// What the map knows about one cell. Heights are world z [m]; NaN when unknown.
struct Cell {
  /// Elevation of the ground: mean, min and max of the non-obstacle points (ground, points
  /// of rejected segments and the feet of kept ones) that fell in the cell, over all frames.
  float elevation_mean_m = std::numeric_limits<float>::quiet_NaN();
  float elevation_min_m = std::numeric_limits<float>::quiet_NaN();
  float elevation_max_m = std::numeric_limits<float>::quiet_NaN();
  std::uint32_t ground_points = 0;
  /// Obstacle points (of kept segments, above their foot) that fell in the cell, and the
  /// highest of them.
  std::uint32_t obstacle_points = 0;
  float obstacle_top_m = std::numeric_limits<float>::quiet_NaN();
  /// Obstacle evidence, log-odds, clamped; one hit or miss per frame.
  float obstacle_log_odds = 0.0f;
  std::uint32_t hits = 0;    ///< frames with obstacle points in the cell
  std::uint32_t misses = 0;  ///< frames that saw it as ground or saw through it
  /// From the plane fitted to the elevations around the cell: its slope from the horizontal
  /// [rad] and the RMS residual [m]. NaN when fewer than 3 cells around have an elevation.
  float slope_rad = std::numeric_limits<float>::quiet_NaN();
  float roughness_m = std::numeric_limits<float>::quiet_NaN();
  Cost terrain_cost = kFreeCost;  ///< from slope and roughness alone
  Cost cost = kUnknownCost;       ///< final cost (terrain, lethal, inflation, unknown)
  bool observed = false;          ///< some point fell in the cell
  bool lethal = false;            ///< obstacle evidence above MapConfig::obstacle_probability
  std::int32_t obstacle_id = 0;   ///< persistent obstacle owning the cell, 0 for none

  bool has_elevation() const { return ground_points > 0; }
};

/// The most cells an unbounded grid may hold (its extent, x * y): TerrainMap::Integrate
/// refuses a frame that would grow it further (16.7 M cells, a 820 m square at 0.2 m).
inline constexpr std::size_t kMaxGridCells = std::size_t{1} << 24;
/// Poses farther than this from the world origin are refused by Integrate [m] (cell
/// indices stay far inside int).
inline constexpr double kMaxWorldCoordinateM = 1e6;

class TerrainGrid {
 public:
  /// `window_cells` > 0: a rolling square window of that many cells a side; 0: unbounded.
  TerrainGrid(double cell_size_m, int window_cells);

  double cell_size() const { return cell_size_m_; }
  bool rolling() const { return window_cells_ > 0; }

  CellIndex IndexOf(const Eigen::Vector2d& xy) const;
  Eigen::Vector2d CentreOf(const CellIndex& index) const;

  /// The current extent: cells [min_index, min_index + extent) hold data (rolling: the
  /// window; unbounded: the allocated extent, which holds every cell touched so far).
  const CellIndex& min_index() const { return min_; }
  const Eigen::Vector2i& extent() const { return extent_; }
  bool Contains(const CellIndex& index) const;

  /// The cell, or nullptr outside the extent.
  const Cell* Find(const CellIndex& index) const;
  Cell* Find(const CellIndex& index);
  /// The cell; the index must lie in the extent (asserted).
  const Cell& At(const CellIndex& index) const { return cells_[Slot(index)]; }
  Cell& At(const CellIndex& index) { return cells_[Slot(index)]; }
  /// Position of a cell in the buffer, stable while the extent holds it; for side arrays.
  std::size_t Slot(const CellIndex& index) const;
  std::size_t slot_count() const { return cells_.size(); }
  /// The cell in a slot (< slot_count()).
  const Cell& AtSlot(std::size_t slot) const { return cells_[slot]; }
  Cell& AtSlot(std::size_t slot) { return cells_[slot]; }

  /// The slots of the cells of a box of indices, by row and column: for loops over a box
  /// and each cell's neighbours, a look-up without Slot's two divisions per cell. Valid
  /// while the extent and the buffer stay as they were.
  class SlotTable {
   public:
    SlotTable() = default;
    /// The box [lo, hi] (inclusive); its cells may lie outside the extent.
    SlotTable(const TerrainGrid& grid, const CellIndex& lo, const CellIndex& hi) {
      Reset(grid, lo, hi);
    }
    /// Made afresh for the box [lo, hi], in the buffers it holds (a frame's table without
    /// allocating).
    void Reset(const TerrainGrid& grid, const CellIndex& lo, const CellIndex& hi);
    /// The slot of `index` (which must lie in the box), or -1 outside the extent.
    std::ptrdiff_t operator()(const CellIndex& index) const {
      const std::ptrdiff_t row = row_[index.y() - lo_.y()];
      const std::ptrdiff_t col = col_[index.x() - lo_.x()];
      return row < 0 || col < 0 ? -1 : row + col;
    }

   private:
    CellIndex lo_;
    std::vector<std::ptrdiff_t> row_, col_;  // slot of the row's first column, column offset
  };

  /// Rolling: centres the window on the cell of `xy`; the cells that leave are reset (their
  /// slots take the cells that enter). Returns true when the window moved. Unbounded: does
  /// nothing, returns false.
  bool MoveTo(const Eigen::Vector2d& xy);
  /// Unbounded: grows the extent to hold [lo, hi] (inclusive). Returns true when the buffer
  /// was reallocated, which changes slots. Rolling: does nothing, returns false.
  bool Reserve(const CellIndex& lo, const CellIndex& hi);

  /// Bytes held by the cells.
  std::size_t memory_bytes() const { return cells_.capacity() * sizeof(Cell); }

 private:
  // Checkpoints (checkpoint.hpp) save the extent and the buffer slot by slot, and restore
  // them as they were, so that a resumed map continues exactly like an uninterrupted one.
  friend struct detail::CheckpointAccess;

  double cell_size_m_;
  int window_cells_;
  CellIndex min_ = CellIndex::Zero();
  Eigen::Vector2i extent_ = Eigen::Vector2i::Zero();
  Eigen::Vector2i buffer_ = Eigen::Vector2i::Zero();  // nx, ny slots
  std::vector<Cell> cells_;
};

}  // namespace cairn::map
