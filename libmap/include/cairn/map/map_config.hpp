// MapConfig: every setting of the multi-frame map (TerrainMap), with its unit and default.
//
// World frame z up, metres, radians (degrees only in files). Probabilities are per update
// (one per frame and voxel or cell), as OctoMap's sensor model has them; they are turned
// into log-odds inside. The defaults suit a ground vehicle about 1 m wide with a range
// camera or a LiDAR; config/default.yaml's `map:` section documents the same keys.
#pragma once

#include "cairn/od/expected.hpp"

namespace cairn::map {

/// Limits that protect memory and time (MapConfig::Validate enforces them): a rolling
/// window of at most kMaxWindowCells a side (16.7 M cells), neighbourhoods (plane fit,
/// inflation, ground radius) of at most kMaxRadiusCells, returns up to kMaxRangeM away.
/// An unbounded grid is limited by TerrainGrid's kMaxGridCells.
inline constexpr double kMaxWindowCells = 4096.0;
inline constexpr double kMaxRadiusCells = 64.0;
inline constexpr double kMaxRangeM = 1000.0;

struct MapConfig {
  // --- 3-D occupancy (OctoMap) ---
  double voxel_size_m = 0.1;  ///< OctoMap leaf size [m]
  /// Returns farther than this from the sensor clear space along their ray up to this range
  /// and mark nothing occupied (OctoMap's maxrange); they are left out of the grid [m].
  double max_range_m = 20.0;
  double voxel_hit_probability = 0.7;   ///< a return ends in the voxel
  double voxel_miss_probability = 0.4;  ///< a ray passes through the voxel
  double voxel_min_probability = 0.12;  ///< clamping, so that a voxel can change again
  double voxel_max_probability = 0.97;

  // --- 2.5-D grid ---
  double cell_size_m = 0.2;  ///< side of a grid cell [m]
  /// Side of the square rolling window centred on the sensor, which the grid and the octree
  /// keep (everything outside is dropped); 0 keeps everything (offline, unbounded) [m].
  double window_size_m = 0.0;
  /// Obstacle evidence of a cell, one update per frame: a hit when obstacle points fall in
  /// it, a miss when it is seen as ground or a ray passes through an obstacle voxel above it.
  double cell_hit_probability = 0.7;
  double cell_miss_probability = 0.4;
  double cell_min_probability = 0.12;
  double cell_max_probability = 0.97;
  /// A cell is lethal while its obstacle probability is above this.
  double obstacle_probability = 0.5;
  /// A point p of a kept segment counts as an obstacle point only when some return q of the
  /// same frame lies within ground_radius_m of it (horizontally) and below it by at least
  /// obstacle_min_height_m + tan(ground_max_slope_rad) |p - q|_xy: p stands above the
  /// ground around it even if that ground rises at ground_max_slope. Other points of the
  /// segment are the obstacle's foot (terrain the cone detector pairs with its base) and
  /// count as ground. q is taken among the lowest returns of the cells within reach.
  double obstacle_min_height_m = 0.15;               ///< [m]
  double ground_radius_m = 0.6;                      ///< [m]
  double ground_max_slope_rad = 0.5235987755982988;  ///< 30 deg
  /// A frame's segment joins a persistent obstacle when one of its cells lies within this
  /// distance of one of the obstacle's cells (0: the cells must overlap) [m].
  double merge_distance_m = 0.2;
  /// Slope and roughness of a cell: a plane fitted to the elevations of the cells whose
  /// centres lie within this distance [m].
  double plane_fit_radius_m = 0.5;

  // --- cost (nav2's convention: 0 free .. 252, 253 inscribed, 254 lethal, 255 unknown) ---
  /// Terrain cost rises linearly with slope and with roughness (the larger of the two) and
  /// reaches 252 at these values.
  double slope_cost_max_rad = 0.5235987755982988;  ///< 30 deg
  double roughness_cost_max_m = 0.1;               ///< RMS residual of the plane fit [m]
  /// The robot's inscribed radius: a cell this close to a lethal cell costs 253 [m].
  double robot_radius_m = 0.5;
  /// nav2's inflation: cells within inflation_radius_m of a lethal cell cost
  /// 252 exp(-cost_scaling_factor (d - robot_radius_m)) at least [m], [1/m].
  double inflation_radius_m = 1.5;
  double cost_scaling_factor = 3.0;

  // --- work ---
  /// Threads casting the free-space rays (0: every hardware thread). Never changes the map.
  int threads = 0;

  /// Names the first bad field by its config-file key ("map config: 'cell_size' ..."):
  /// sizes > 0, probabilities in (0, 1) with miss < 0.5 < hit and min < 0.5 < max,
  /// robot_radius <= inflation_radius, window_size 0 or 4..kMaxWindowCells cells,
  /// voxel_size in [0.001, 10] m, cell_size in [0.001, 100] m, max_range <= kMaxRangeM,
  /// radii <= kMaxRadiusCells cells, angles in [0, 90) deg, everything finite, threads in
  /// 0..256.
  Status Validate() const;
};

}  // namespace cairn::map
