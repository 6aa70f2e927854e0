// Internal: TerrainMap's first pass over a frame's pixels (PlaceReturns), apart so that its
// vector path can be checked against the one-pixel path.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>

#include "cairn/map/terrain_grid.hpp"

namespace cairn::map::internal {

/// What one return is, for this frame.
enum PointClass : std::uint8_t {
  kNone = 0,     ///< no return
  kFar = 1,      ///< beyond max_range: free space up to max_range, nothing else
  kGround = 2,   ///< in range, not an obstacle point
  kObstacle = 3  ///< in range, kept segment, above its foot
};

/// The returns of a frame's n pixels placed in the world. Pixel i holds a return where
/// valid[i] is not 0; p = (x[i], y[i], z[i]) in the sensor frame, as RangeImage stores them.
/// Per pixel: its class (kNone without a return or where |p| is not above 0, kFar where |p| is
/// above max_range_m, else kGround), where it lands (T_world_sensor p; a far one cut at
/// max_range_m along its ray) and that point's cell of `grid` (IndexOf). world[i] and cell[i]
/// are unspecified where the class is kNone. The returns placed are added to `valid`, and `lo`
/// and `hi` (started by the caller at some cell) take in their cells. With `lanes` 8 or more
/// (AVX2), four pixels at a time in doubles, with the one-pixel path's operations in its order
/// (no fused multiply-add: the library is built for x86-64's baseline with -ffp-contract=off,
/// so Eigen's arithmetic in the one-pixel path does not fuse either): the same values.
void PlacePixels(const float* x, const float* y, const float* z, const std::uint8_t* valid_mask,
                 int n, const Eigen::Isometry3d& T_world_sensor, double max_range_m,
                 const TerrainGrid& grid, int lanes, std::uint8_t* point_class,
                 Eigen::Vector3d* world, CellIndex* cell, int& valid, CellIndex& lo, CellIndex& hi);

}  // namespace cairn::map::internal
