// Rings and azimuth steps of a LiDAR scan found from its points, for clouds that come
// without laser numbers (MRPT point clouds, unorganised files).
//
// A spinning LiDAR's beams sit at fixed elevations, so the sorted elevations of its returns
// fall in tight groups separated by empty gaps. Where those groups are clear they are the
// rings; where they are not (beam offsets blur near returns, a non-spinning sensor), the
// elevation range is cut into even bins instead, and the layout says so.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::sources {

struct RingOptions {
  /// Two elevations further apart than this, with no return between, separate two rings
  /// [rad] (0.1 deg: below every common sensor's ring spacing, above its beam scatter).
  double min_gap_rad = 0.1 * 3.14159265358979323846 / 180.0;
  /// A group holding fewer than this fraction of the returns is noise, not a ring.
  double min_ring_fraction = 0.002;
  int max_rings = 128;  ///< more groups than this: not ring-structured
  /// Even elevation bins used when no ring structure is found [rad].
  double fallback_bin_rad = 0.4 * 3.14159265358979323846 / 180.0;
  int min_columns = 16, max_columns = 8192;  ///< bounds of the azimuth steps found
};

/// Rows, columns and model of a point list (LiDAR frame, x forward, y left, z up). Points at
/// the origin or non-finite are no return (row and column -1).
struct RingLayout {
  od::SphericalModel model;             ///< rings top first; width from the azimuth step
  std::vector<std::int32_t> rows, cols;  ///< per point
  bool rings_found = false;             ///< false: even elevation bins
  std::string layout;                   ///< for reports
};

/// Fails when fewer than two points have a return.
Expected<RingLayout> FindRings(const std::vector<Eigen::Vector3f>& points,
                               const RingOptions& options = {});

/// Azimuth steps per turn of points whose rows are known: the typical azimuth difference of
/// neighbours within a ring (the median of those below 1.5 times the lower quartile, so that
/// gaps left by rays without return do not count), as a whole number of steps per turn,
/// within the options' bounds. `rows` may hold -1 for no return.
int ColumnsFromAzimuthStep(const std::vector<Eigen::Vector3f>& points,
                           const std::vector<std::int32_t>& rows, int ring_count,
                           const RingOptions& options = {});

}  // namespace cairn::sources
