// Obstacle: one object fused across frames from the kept segments that overlap it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "cairn/map/terrain_grid.hpp"

namespace cairn::map {

/// A persistent obstacle. Segments of successive frames whose cells lie within
/// MapConfig::merge_distance_m of its cells join it (a segment that reaches several merges
/// them into the oldest); it is retired when none of its cells is lethal any more (cleared
/// by later frames, or left the rolling window). World frame (z up) [m], seconds.
struct Obstacle {
  int id = 0;  ///< > 0, never reused within a map
  /// Box of every obstacle point that joined it, over all frames [m].
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  ///< mean of those points [m]
  /// Its height: the most any of its points stood above the lowest return within
  /// MapConfig::ground_radius_m of it in the same frame, over all frames [m].
  double height_m = 0.0;
  std::int64_t point_count = 0;  ///< obstacle points over all frames
  /// Its lethal cells now, and the box of their footprint (world xy, outer edges) [m].
  std::vector<CellIndex> cells;
  Eigen::Vector2d footprint_min = Eigen::Vector2d::Zero();
  Eigen::Vector2d footprint_max = Eigen::Vector2d::Zero();
  double footprint_area_m2 = 0.0;
  double first_seen_s = 0.0;
  double last_seen_s = 0.0;
  std::vector<std::int64_t> frames;  ///< ids of the frames that saw it, in integration order
  std::vector<int> merged_ids;       ///< obstacles merged into this one
};

}  // namespace cairn::map
