#include "cairn/eval/map_score.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "cairn/sim/render.hpp"

namespace cairn::eval {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

double CellDistance(const MapCell& a, const MapCell& b, double cell_size) {
  return std::hypot(a.first - b.first, a.second - b.second) * cell_size;
}

/// The nearest of `to` from any of `from` [m] and which one; infinity when either is empty.
std::pair<double, const MapCell*> Nearest(const std::vector<MapCell>& from,
                                          const std::vector<MapCell>& to, double cell_size) {
  double best = kInfinity;
  const MapCell* nearest = nullptr;
  for (const MapCell& a : from) {
    for (const MapCell& b : to) {
      const double d = CellDistance(a, b, cell_size);
      if (d < best) {
        best = d;
        nearest = &b;
      }
    }
  }
  return {best, nearest};
}

/// Per object id, the observed cells its vertical rays hit and the most it rises above the
/// terrain in each (objects stand less than 6 m tall).
std::map<int, std::map<MapCell, double>> ObjectHeights(const sim::Scene& scene,
                                                       const map::TerrainGrid& grid,
                                                       const map::CellBox& box) {
  const sim::RayCaster caster(scene);
  sim::RenderOptions options;
  options.max_range_m = 12.0;
  std::map<int, std::map<MapCell, double>> out;
  const double s = grid.cell_size();
  for (int j = box.min.y(); j <= box.max.y(); ++j) {
    for (int i = box.min.x(); i <= box.max.x(); ++i) {
      if (!grid.At({i, j}).observed) continue;
      for (int k = 0; k < 16; ++k) {
        const double x = (i + (k % 4 + 0.5) / 4.0) * s, y = (j + (k / 4 + 0.5) / 4.0) * s;
        const double ground = scene.terrain().Height(x, y);
        const sim::Ray ray{{x, y, ground + 6.0}, {0.0, 0.0, -1.0}};
        const std::optional<sim::RayHit> hit = caster.Cast(ray, options);
        if (!hit || hit->id <= 0) continue;
        double& height = out[hit->id][{i, j}];
        height = std::max(height, ray.At(hit->t).z() - ground);
      }
    }
  }
  return out;
}

}  // namespace

Status MapScoreOptions::Validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(obstacle_min_height_m)) return Error{"obstacle_min_height_m: must be > 0"};
  if (!positive(found_within_m)) return Error{"found_within_m: must be > 0"};
  if (!positive(false_lethal_beyond_m)) return Error{"false_lethal_beyond_m: must be > 0"};
  if (near_object_cells < 0) return Error{"near_object_cells: must be >= 0"};
  return Status::Ok();
}

Expected<MapScore> ScoreMap(const sim::Scene& scene, const map::TerrainMap& map,
                            const MapScoreOptions& options) {
  if (Status st = options.Validate(); !st) return Error{"map score: " + st.message()};
  const map::TerrainGrid& grid = map.grid();
  const double s = grid.cell_size();
  const std::optional<map::CellBox> box = map.ObservedBounds();
  if (!box) return Error{"map score: the map observed nothing"};

  MapScore out;
  std::set<MapCell> near_object, obstacle_cells;
  const int r = options.near_object_cells;
  for (const auto& [id, heights] : ObjectHeights(scene, grid, *box)) {
    const sim::Object* object = scene.Find(id);
    MapObjectScore o;
    o.id = id;
    o.name = object->name;
    o.is_obstacle = object->is_obstacle;
    for (const auto& [c, height] : heights) {
      for (int dj = -r; dj <= r; ++dj) {
        for (int di = -r; di <= r; ++di) near_object.insert({c.first + di, c.second + dj});
      }
      o.cells.push_back(c);
      o.centre += grid.CentreOf({c.first, c.second});
      if (o.is_obstacle && height >= options.obstacle_min_height_m) {
        o.obstacle_cells.push_back(c);
        obstacle_cells.insert(c);
      }
    }
    o.centre /= static_cast<double>(o.cells.size());
    out.objects.push_back(std::move(o));
  }
  out.obstacle_cells.assign(obstacle_cells.begin(), obstacle_cells.end());

  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      if (grid.At({i, j}).lethal) out.lethal_cells.push_back({i, j});
    }
  }
  std::sort(out.lethal_cells.begin(), out.lethal_cells.end());
  int both = 0;
  for (const MapCell& c : out.lethal_cells) both += static_cast<int>(obstacle_cells.count(c));
  const int either = static_cast<int>(out.lethal_cells.size() + obstacle_cells.size()) - both;
  out.iou = either > 0 ? both / static_cast<double>(either) : 0.0;
  for (const MapCell& c : out.lethal_cells) {
    out.false_lethal += Nearest({c}, out.obstacle_cells, s).first > options.false_lethal_beyond_m;
  }

  for (MapObjectScore& o : out.objects) {
    const auto [distance, cell] =
        Nearest(o.is_obstacle ? o.obstacle_cells : o.cells, out.lethal_cells, s);
    o.nearest_lethal_m = distance;
    if (cell != nullptr) o.map_obstacle_id = grid.At({cell->first, cell->second}).obstacle_id;
    o.found = distance <= options.found_within_m;
    if (o.scored()) {
      ++out.obstacles;
      out.found += o.found ? 1 : 0;
    } else if (!o.is_obstacle && o.found) {
      ++out.marked_non_obstacles;
    }
  }

  for (const map::Obstacle& obstacle : map.obstacles()) {
    bool matched = false;
    for (const map::CellIndex& c : obstacle.cells) {
      for (const MapObjectScore& o : out.objects) {
        matched = matched || Nearest({{c.x(), c.y()}}, o.cells, s).first <= options.found_within_m;
      }
    }
    if (!matched) out.false_obstacle_ids.push_back(obstacle.id);
  }

  double sum2 = 0.0;
  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      const map::Cell& cell = grid.At({i, j});
      if (!cell.has_elevation() || near_object.count({i, j}) != 0) continue;
      const Eigen::Vector2d c = grid.CentreOf({i, j});
      const double e = cell.elevation_mean_m - scene.terrain().Height(c.x(), c.y());
      sum2 += e * e;
      out.elevation_max_m = std::max(out.elevation_max_m, std::abs(e));
      ++out.elevation_cells;
    }
  }
  out.elevation_rms_m = std::sqrt(sum2 / std::max(1, out.elevation_cells));
  return out;
}

}  // namespace cairn::eval
