// Internal: TerrainMap's first pass over a frame's pixels (PlaceReturns), apart so that its
// vector path can be checked against the scalar one.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>

#include "cairn/map/terrain_grid.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::map::internal {

// What one return is, for this frame.
enum PointClass : std::uint8_t {
  kNone = 0,     // no return
  kFar = 1,      // beyond max_range: free space up to max_range, nothing else
  kGround = 2,   // in range, not an obstacle point
  kObstacle = 3  // in range, kept segment, above its foot
};

// The returns of `image` placed in the world: per pixel i its class (kNone where there is no
// return or its range is not above 0, kFar beyond max_range_m, else kGround), where it lands
// (T_world_sensor p; a far one cut at max_range_m along its ray) and that point's cell of
// `grid` (IndexOf). world[i] and cell[i] are unspecified where the class is kNone. `valid`
// counts the returns placed; `lo` and `hi` take in their cells (the caller starts them at some
// cell). With `lanes` 8 or more (AVX2), four pixels at a time in doubles, with the one-pixel
// path's operations in its order: the same values.
void PlacePixels(const od::RangeImage& image, const Eigen::Isometry3d& T_world_sensor,
                 double max_range_m, const TerrainGrid& grid, int lanes, std::uint8_t* point_class,
                 Eigen::Vector3d* world, CellIndex* cell, int& valid, CellIndex& lo, CellIndex& hi);

}  // namespace cairn::map::internal
