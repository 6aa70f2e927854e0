// The foot band: terrain pixels that the pair definition attaches to an obstacle.
//
// Obstacle points are binned in fine horizontal cells, each remembering its highest and
// lowest point; the cells are grouped in coarse cells as wide as the largest reach
// Hmax / tan(theta). A terrain point t looks at the fine cells of the 3 x 3 coarse cells
// around it. For each, the farthest any of its points can reach is bounded by
// reach(largest |dh| in the cell) - distance(t, cell box): cells that cannot reach t are
// skipped, the extremes (real points) are tested exactly, and only when they fail while
// the bound allows a hit are the cell's other points tested one by one. The result is the
// definition's, point for point.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "cairn/eval/score.hpp"

namespace cairn::eval {
namespace {

struct FineCell {
  std::int64_t ix = 0, iy = 0;     ///< cell indices: box [ix, ix + 1) * size, same for y
  int high = -1, low = -1;         ///< pixel indices of the highest and lowest point
  std::size_t begin = 0, end = 0;  ///< its pixels: members[begin, end)
};

struct CoarseCell {
  std::vector<std::size_t> cells;  ///< indices into the fine cells
  float max_z = -std::numeric_limits<float>::infinity();
  float min_z = std::numeric_limits<float>::infinity();
};

std::int64_t Key(std::int64_t ix, std::int64_t iy) {
  return (ix << 32) ^ static_cast<std::int64_t>(static_cast<std::uint32_t>(iy));
}

std::int64_t Cell(double v, double size) { return static_cast<std::int64_t>(std::floor(v / size)); }

/// Horizontal distance from (x, y) to the box [x0, x0 + size) x [y0, y0 + size).
double BoxDistance(double x, double y, double x0, double y0, double size) {
  const double gx = std::max({x0 - x, 0.0, x - (x0 + size)});
  const double gy = std::max({y0 - y, 0.0, y - (y0 + size)});
  return std::sqrt(gx * gx + gy * gy);
}

}  // namespace

std::vector<std::int32_t> FootBand(const od::RangeImage& image, const FrameTruth& truth,
                                   double max_height_m, double min_slope_rad) {
  const int n = image.size();
  std::vector<std::int32_t> band(static_cast<std::size_t>(n), 0);
  assert(truth.object_id.size() == static_cast<std::size_t>(n));
  const double tan_theta = std::tan(min_slope_rad);
  if (!(max_height_m > 0.0) || !(tan_theta > 0.0) || !std::isfinite(tan_theta)) return band;
  const double reach_max = max_height_m / tan_theta;
  const double fine = std::min(0.05, reach_max / 10.0);
  // A whole number of fine cells, so that every fine cell lies in one coarse cell.
  const double coarse = fine * std::ceil(reach_max / fine);
  const auto reach = [&](double dh) { return std::min(dh, max_height_m) / tan_theta; };

  // Level-frame points (z up).
  const Eigen::Matrix3d R = image.R_level_sensor();
  std::vector<Eigen::Vector3d> level(static_cast<std::size_t>(n), Eigen::Vector3d::Zero());
  for (int i = 0; i < n; ++i) {
    if (image.valid(i)) level[i] = R * image.point(i);
  }

  // Obstacle points binned in fine cells, in pixel order (deterministic).
  const std::vector<std::uint8_t> obstacle = truth.ObstacleMask();
  std::vector<FineCell> fine_cells;
  std::vector<std::size_t> cell_of(static_cast<std::size_t>(n), 0);
  std::unordered_map<std::int64_t, std::size_t> fine_index;
  for (int i = 0; i < n; ++i) {
    if (!obstacle[i] || !image.valid(i)) continue;
    const Eigen::Vector3d& p = level[i];
    const std::int64_t ix = Cell(p.x(), fine), iy = Cell(p.y(), fine);
    const auto [it, inserted] = fine_index.emplace(Key(ix, iy), fine_cells.size());
    if (inserted) {
      FineCell c;
      c.ix = ix;
      c.iy = iy;
      c.high = c.low = i;
      fine_cells.push_back(c);
    }
    FineCell& c = fine_cells[it->second];
    if (p.z() > level[c.high].z()) c.high = i;
    if (p.z() < level[c.low].z()) c.low = i;
    ++c.end;  // a count for now
    cell_of[i] = it->second;
  }
  if (fine_cells.empty()) return band;
  std::size_t total = 0;
  for (FineCell& c : fine_cells) {
    c.begin = total;
    total += c.end;
    c.end = c.begin;
  }
  std::vector<int> members(total);
  for (int i = 0; i < n; ++i) {
    if (obstacle[i] && image.valid(i)) members[fine_cells[cell_of[i]].end++] = i;
  }
  std::unordered_map<std::int64_t, CoarseCell> coarse_cells;
  const auto ratio = static_cast<std::int64_t>(std::llround(coarse / fine));
  const auto floor_div = [](std::int64_t a, std::int64_t b) {
    return a >= 0 ? a / b : -((-a + b - 1) / b);
  };
  for (std::size_t k = 0; k < fine_cells.size(); ++k) {
    const FineCell& f = fine_cells[k];
    CoarseCell& c = coarse_cells[Key(floor_div(f.ix, ratio), floor_div(f.iy, ratio))];
    c.cells.push_back(k);
    c.max_z = std::max(c.max_z, static_cast<float>(level[f.high].z()));
    c.min_z = std::min(c.min_z, static_cast<float>(level[f.low].z()));
  }

  for (int i = 0; i < n; ++i) {
    if (truth.object_id[i] != sim::kTerrainId || !image.valid(i)) continue;
    const Eigen::Vector3d& t = level[i];
    // reach - horizontal distance for obstacle point j (>= 0: t is in its band).
    const auto margin = [&](int j) {
      const Eigen::Vector3d& q = level[j];
      const double dh = std::abs(q.z() - t.z());
      if (!(dh > 0.0)) return -1.0;
      return reach(dh) - std::hypot(q.x() - t.x(), q.y() - t.y());
    };
    const std::int64_t cx = Cell(t.x(), coarse), cy = Cell(t.y(), coarse);
    double best = -1.0;
    std::int32_t best_id = 0;
    const auto take = [&](int j) {
      const double m = margin(j);
      if (m >= 0.0 && m > best) {
        best = m;
        best_id = truth.object_id[j];
      }
    };
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = coarse_cells.find(Key(cx + dx, cy + dy));
        if (it == coarse_cells.end()) continue;
        const CoarseCell& c = it->second;
        const double dh_c = std::max<double>(c.max_z - t.z(), t.z() - c.min_z);
        if (!(dh_c > 0.0)) continue;
        if (BoxDistance(t.x(), t.y(), double(cx + dx) * coarse, double(cy + dy) * coarse, coarse) >
            reach(dh_c)) {
          continue;
        }
        for (const std::size_t k : c.cells) {
          const FineCell& f = fine_cells[k];
          const double dh = std::max(level[f.high].z() - t.z(), t.z() - level[f.low].z());
          if (!(dh > 0.0)) continue;
          const double bound =
              reach(dh) - BoxDistance(t.x(), t.y(), double(f.ix) * fine, double(f.iy) * fine, fine);
          if (bound < 0.0 || bound <= best) continue;  // no point of it can do better
          const double before = best;
          take(f.high);
          take(f.low);
          if (best > before) continue;
          for (std::size_t m = f.begin; m < f.end; ++m) take(members[m]);
        }
      }
    }
    band[i] = best_id;
  }
  return band;
}

}  // namespace cairn::eval
