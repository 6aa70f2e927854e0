#include "cairn/map/terrain_grid.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace cairn::map {
namespace {

int PositiveMod(int a, int n) {
  const int m = a % n;
  return m < 0 ? m + n : m;
}

}  // namespace

TerrainGrid::TerrainGrid(double cell_size_m, int window_cells)
    : cell_size_m_(cell_size_m), window_cells_(window_cells) {
  assert(cell_size_m > 0.0 && window_cells >= 0);
  if (window_cells_ > 0) {
    extent_ = buffer_ = Eigen::Vector2i::Constant(window_cells_);
    min_ = CellIndex::Constant(-window_cells_ / 2);
    cells_.assign(static_cast<std::size_t>(window_cells_) * window_cells_, Cell{});
  }
}

CellIndex TerrainGrid::IndexOf(const Eigen::Vector2d& xy) const {
  return {static_cast<int>(std::floor(xy.x() / cell_size_m_)),
          static_cast<int>(std::floor(xy.y() / cell_size_m_))};
}

Eigen::Vector2d TerrainGrid::CentreOf(const CellIndex& index) const {
  return (index.cast<double>() + Eigen::Vector2d::Constant(0.5)) * cell_size_m_;
}

bool TerrainGrid::Contains(const CellIndex& index) const {
  const CellIndex d = index - min_;
  return d.x() >= 0 && d.y() >= 0 && d.x() < extent_.x() && d.y() < extent_.y();
}

std::size_t TerrainGrid::Slot(const CellIndex& index) const {
  assert(Contains(index));
  return static_cast<std::size_t>(PositiveMod(index.y(), buffer_.y())) * buffer_.x() +
         PositiveMod(index.x(), buffer_.x());
}

void TerrainGrid::SlotTable::Reset(const TerrainGrid& grid, const CellIndex& lo,
                                   const CellIndex& hi) {
  lo_ = lo;
  row_.clear();
  col_.clear();
  const CellIndex from = grid.min_;
  const CellIndex to = grid.min_ + grid.extent_;  // exclusive
  for (int j = lo.y(); j <= hi.y(); ++j) {
    row_.push_back(j >= from.y() && j < to.y()
                       ? static_cast<std::ptrdiff_t>(PositiveMod(j, grid.buffer_.y())) *
                             grid.buffer_.x()
                       : -1);
  }
  for (int i = lo.x(); i <= hi.x(); ++i) {
    col_.push_back(i >= from.x() && i < to.x() ? PositiveMod(i, grid.buffer_.x()) : -1);
  }
}

const Cell* TerrainGrid::Find(const CellIndex& index) const {
  return Contains(index) ? &cells_[Slot(index)] : nullptr;
}

Cell* TerrainGrid::Find(const CellIndex& index) {
  return Contains(index) ? &cells_[Slot(index)] : nullptr;
}

bool TerrainGrid::MoveTo(const Eigen::Vector2d& xy) {
  if (!rolling()) return false;
  const int n = window_cells_;
  const CellIndex target = IndexOf(xy) - CellIndex::Constant(n / 2);
  if (target == min_) return false;
  const CellIndex delta = target - min_;
  if (std::abs(delta.x()) >= n || std::abs(delta.y()) >= n) {
    std::fill(cells_.begin(), cells_.end(), Cell{});
    min_ = target;
    return true;
  }
  // Columns that leave: their slots are the ones the entering columns take.
  const auto reset_columns = [&](int first, int last) {  // [first, last)
    for (int i = first; i < last; ++i) {
      for (int j = min_.y(); j < min_.y() + n; ++j) cells_[Slot({i, j})] = Cell{};
    }
  };
  if (delta.x() > 0) reset_columns(min_.x(), min_.x() + delta.x());
  if (delta.x() < 0) reset_columns(min_.x() + n + delta.x(), min_.x() + n);
  min_.x() = target.x();
  const auto reset_rows = [&](int first, int last) {
    for (int j = first; j < last; ++j) {
      for (int i = min_.x(); i < min_.x() + n; ++i) cells_[Slot({i, j})] = Cell{};
    }
  };
  if (delta.y() > 0) reset_rows(min_.y(), min_.y() + delta.y());
  if (delta.y() < 0) reset_rows(min_.y() + n + delta.y(), min_.y() + n);
  min_.y() = target.y();
  return true;
}

bool TerrainGrid::Reserve(const CellIndex& lo, const CellIndex& hi) {
  if (rolling()) return false;
  assert(lo.x() <= hi.x() && lo.y() <= hi.y());
  CellIndex new_min = lo;
  CellIndex new_max = hi;
  if (extent_.x() > 0) {
    new_min = new_min.cwiseMin(min_);
    new_max = new_max.cwiseMax(min_ + extent_ - CellIndex::Ones());
  }
  const Eigen::Vector2i new_extent = new_max - new_min + CellIndex::Ones();
  if (new_min == min_ && new_extent == extent_) return false;
  if (new_extent.x() <= buffer_.x() && new_extent.y() <= buffer_.y()) {
    // Slots of the buffer outside the old extent were never touched: still default cells.
    min_ = new_min;
    extent_ = new_extent;
    return false;
  }
  // Grow the buffer (at least doubling, so growth is amortised) and move every cell of the
  // old extent to its slot in the new one.
  Eigen::Vector2i new_buffer = new_extent.cwiseMax(2 * buffer_).cwiseMax(64);
  if (static_cast<double>(new_buffer.x()) * new_buffer.y() > static_cast<double>(kMaxGridCells)) {
    new_buffer = new_extent;  // near the limit, no room to spare
  }
  std::vector<Cell> cells(static_cast<std::size_t>(new_buffer.x()) * new_buffer.y());
  for (int j = min_.y(); j < min_.y() + extent_.y(); ++j) {
    for (int i = min_.x(); i < min_.x() + extent_.x(); ++i) {
      const std::size_t to =
          static_cast<std::size_t>(PositiveMod(j, new_buffer.y())) * new_buffer.x() +
          PositiveMod(i, new_buffer.x());
      cells[to] = cells_[Slot({i, j})];
    }
  }
  cells_ = std::move(cells);
  buffer_ = new_buffer;
  min_ = new_min;
  extent_ = new_extent;
  return true;
}

}  // namespace cairn::map
