// A map against the truth of the world it was made in: the one scorer of a TerrainMap
// (`cairn map --truth`, the map study of `cairn eval --maps`, the map tests).
//
// Truth is per map cell, seen from above: over every observed cell of the map, 4 x 4
// vertical rays are cast down through the scene (libsim's ray caster); an object covers the
// cells its rays hit, and an obstacle's own cells are those where it rises
// `obstacle_min_height_m` or more above the terrain (the low rim of a mound is no obstacle by
// the detector's definition, so it is not asked for). Distances are between cell centres.
#pragma once

#include <Eigen/Core>
#include <string>
#include <utility>
#include <vector>

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::eval {

/// A map cell by its (x, y) index.
using MapCell = std::pair<int, int>;

struct MapScoreOptions {
  double obstacle_min_height_m = 0.15;  ///< an obstacle's cells rise this much or more [m]
  double found_within_m = 0.3;          ///< found: a lethal cell this close to its cells [m]
  double false_lethal_beyond_m = 0.5;   ///< false: farther from every obstacle cell [m]
  int near_object_cells = 3;            ///< elevation leaves out cells this close to an object
  Status Validate() const;
};

/// One object of the world that covers observed cells of the map.
struct MapObjectScore {
  int id = 0;
  std::string name;
  bool is_obstacle = false;
  std::vector<MapCell> cells;           ///< observed cells it covers, sorted
  std::vector<MapCell> obstacle_cells;  ///< of which it rises obstacle_min_height_m there
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  ///< of `cells`, world xy [m]
  /// From its obstacle cells (an obstacle) or any of its cells (anything else) to the nearest
  /// lethal cell [m]; infinity when the map has none.
  double nearest_lethal_m = 0.0;
  int map_obstacle_id = 0;  ///< the map obstacle owning that lethal cell (0: none)
  bool found = false;       ///< nearest_lethal_m <= found_within_m
  /// An obstacle that rises high enough in some observed cell: one the map is asked for.
  bool scored() const { return is_obstacle && !obstacle_cells.empty(); }
};

struct MapScore {
  std::vector<MapObjectScore> objects;  ///< by id
  std::vector<MapCell> obstacle_cells;  ///< every obstacle's cells, sorted
  std::vector<MapCell> lethal_cells;    ///< the map's, sorted
  double iou = 0.0;                     ///< of lethal_cells and obstacle_cells
  int false_lethal =
      0;  ///< lethal cells farther than false_lethal_beyond_m from every obstacle cell
  int obstacles = 0, found = 0;  ///< scored obstacles; of which found
  int marked_non_obstacles = 0;  ///< objects that are no obstacle with a lethal cell near
  /// Map obstacles none of whose cells is within found_within_m of any object's cell.
  std::vector<int> false_obstacle_ids;
  /// The grid's elevation against the terrain, over cells with ground farther than
  /// near_object_cells from every object [m].
  double elevation_rms_m = 0.0, elevation_max_m = 0.0;
  int elevation_cells = 0;
};

/// Scores `map` against `scene`. Fails when the map observed nothing or the options are
/// out of range.
Expected<MapScore> ScoreMap(const sim::Scene& scene, const map::TerrainMap& map,
                            const MapScoreOptions& options = {});

}  // namespace cairn::eval
