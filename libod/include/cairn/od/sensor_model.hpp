// Sensor models: how a range image's grid relates to directions in the sensor frame.
//
// A RangeImage is an organised grid; its model tells where each cell looks and where a 3-D
// point projects, which is what the exact cone search needs: a pinhole z-depth camera or a
// spherical LiDAR model (rings x azimuth), dispatched with std::visit. LiDAR models come
// from a sensor preset or are measured on the scan itself (FitRings, FindElevationRings,
// UniformElevationBins), so that scans of unknown sensors still get one row per ring.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::od {

/// Pinhole camera in the optical frame (x right, y down, z forward), z-depth images.
/// Pixel (col c, row r) looks along ((c - cx) / fx, (r - cy) / fy, 1): integer coordinates
/// are pixel centres, so a back-projected depth pixel projects exactly onto its own cell.
struct PinholeModel {
  int width = 0;    ///< columns [px]
  int height = 0;   ///< rows [px]
  double fx = 0.0;  ///< focal length along x [px]
  double fy = 0.0;  ///< focal length along y [px]
  double cx = 0.0;  ///< principal point, column [px]
  double cy = 0.0;  ///< principal point, row [px]

  /// Names the first field that is not usable (non-finite, non-positive size or focal).
  Status Validate() const;

  /// Point in the optical frame for pixel (col, row) at z-depth `z` [m].
  Eigen::Vector3d Unproject(double col, double row, double z) const {
    return {(col - cx) * z / fx, (row - cy) * z / fy, z};
  }
  /// Continuous pixel coordinates (col, row) of a point with z > 0.
  Eigen::Vector2d Project(const Eigen::Vector3d& p) const {
    return {fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy};
  }
};

/// Spinning multi-ring LiDAR in its own frame (x forward, y left, z up): one row per laser
/// ring, ordered from the top beam down, and one column per azimuth step. Column c looks at
/// azimuth azimuth_start_rad - c * 2 pi / width (azimuth = atan2(y, x), so columns sweep
/// clockwise seen from above, as KITTI and Ouster projections do).
///
/// The nominal elevations place points that come without a ring number; real sensors'
/// points scatter around them (beam offsets, motion), which the exact cone search takes
/// from the data rather than from this model.
struct SphericalModel {
  int width = 0;                           ///< azimuth steps per revolution
  std::vector<double> ring_elevation_rad;  ///< one per row, top beam first [rad]
  double azimuth_start_rad = 0.0;          ///< azimuth of column 0's centre [rad]

  int height() const { return static_cast<int>(ring_elevation_rad.size()); }
  double azimuth_step_rad() const;
  /// Names the first bad field (width < 1, no rings, non-finite or unsorted elevations).
  Status Validate() const;
  /// Azimuth of column `col`'s centre [rad].
  double ColumnAzimuth(double col) const;
  /// Column of a point's azimuth, in [0, width).
  int Column(const Eigen::Vector3d& p) const;
  /// The same for a direction's azimuth atan2(y, x) [rad], computed already.
  int ColumnAt(double azimuth_rad) const;
  /// Row of the ring nearest to a point's elevation.
  int NearestRing(const Eigen::Vector3d& p) const;

  /// Nominal models of common sensors with `width` azimuth steps (0: the sensor's own at
  /// 10 Hz, 1800 = 0.2 deg for VLP-16 and VLP-32C, 2048 for HDL-64E and OS1-64): "HDL-64E"
  /// (upper block of 32 lasers 1/3 deg apart from +2 deg, lower block of 32 from -8.83 to
  /// -24.8 deg), "VLP-16" (+15 to -15 deg every 2 deg), "VLP-32C" (its data sheet table,
  /// +15 to -25 deg, densest 1/3 deg around the horizon), "OS1-64" (64 rings evenly over
  /// +-16.6 deg). Names in any case ("os1-64").
  static Expected<SphericalModel> Preset(const std::string& name, int width = 0);
  /// The names Preset() knows, as written above ("HDL-64E", "VLP-16", "VLP-32C", "OS1-64").
  static const std::vector<std::string>& PresetNames();
};

/// Every sensor model a RangeImage may carry.
using SensorModel = std::variant<PinholeModel, SphericalModel>;

// --- Rings measured on a scan ------------------------------------------------------------
//
// These take points in the sensor frame (x forward, y left, z up) [m], in input order; a
// point at the origin or with a non-finite coordinate is a no return and gets row -1.
// Elevation = atan2(z, hypot(x, y)), azimuth = atan2(y, x).

/// An angle wrapped into [0, 2 pi) [rad].
double WrapPositive(double a);

/// A stored point is a return when it is finite and not (0, 0, 0), which KITTI, Ouster and
/// PCL write for a ray without one.
bool IsReturn(const Eigen::Vector3f& p);

/// Every point's azimuth atan2(y, x) and elevation atan2(z, hypot(x, y)) [rad], NaN for a
/// point that is no return: computed once for the layout finders below, which take them
/// besides the points.
struct PointAngles {
  std::vector<double> azimuth, elevation;
  explicit PointAngles(const std::vector<Eigen::Vector3f>& points);
};

/// A spherical model measured on a scan, and the row (ring, top first) of every point.
struct RingFit {
  SphericalModel model;            ///< width as asked; elevations measured; azimuth_start 0
  std::vector<std::int32_t> rows;  ///< one per input point, -1 for no return
};

/// Ring elevations from points whose ring is known (a ring field, the storage order):
/// each ring's elevation is the median elevation of its returns, and rings are renumbered
/// top first by it. When the given ring order is already top first (non-increasing
/// medians), every ring is kept and rings without returns get elevations interpolated (or
/// extrapolated) from their neighbours; otherwise rings without returns are dropped.
/// `ring_of_point`: one id in [0, rings) or -1 (ignored) per point. Fails, naming the point,
/// on a size mismatch or an id out of range, and when no point has a ring and a return.
Expected<RingFit> FitRings(const std::vector<Eigen::Vector3f>& points,
                           const std::vector<std::int32_t>& ring_of_point, int rings, int width);
/// The same with the points' angles computed already.
Expected<RingFit> FitRings(const PointAngles& angles,
                           const std::vector<std::int32_t>& ring_of_point, int rings, int width);

/// How FindElevationRings tells rings apart.
struct ElevationRingOptions {
  /// Sorted elevations split where no return lies within this gap: wider than any ring's
  /// own spread, narrower than the closest ring spacing of common sensors (0.1-0.33 deg).
  double min_gap_rad = 0.05 * 3.14159265358979323846 / 180.0;  ///< [rad] (0.05 deg)
  /// Groups smaller than this are stray returns and join the nearest ring.
  int min_ring_points = 3;
  /// A group is a ring when its spread (5th to 95th percentile of elevation) is at most
  /// this fraction of the distance from its median to the nearest other group's median.
  double max_spread_fraction = 0.5;
  /// Rings must hold at least this share of the returns, else the scan has no rings.
  double min_ring_share = 0.95;

  /// Names the first bad field: min_gap > 0, min_ring_points >= 1, fractions in (0, 1].
  Status Validate() const;
};

/// Rings from the elevation histogram alone (for unordered scans of sensors with fixed
/// beam elevations): returns are sorted by elevation and split at gaps, each group one ring.
/// Fails, saying why, when the returns do not fall into separate rings (beams whose
/// elevation seen from the origin varies with range by more than the ring spacing, as the
/// HDL-64E's do up close; tilting 2-D lasers), or on fewer than two returns.
Expected<RingFit> FindElevationRings(const std::vector<Eigen::Vector3f>& points, int width,
                                     const ElevationRingOptions& options = {});

/// No rings: rows are equal elevation bins of `bin_rad` from the highest return down (for
/// tilting 2-D lasers, merged clouds). `bin_rad` <= 0 picks square cells of the azimuth
/// step 2 pi / width. Fails on no returns or more than 65536 rows.
Expected<RingFit> UniformElevationBins(const std::vector<Eigen::Vector3f>& points, int width,
                                       double bin_rad = 0.0);

/// Azimuth steps per revolution measured on rows: the median angle between neighbouring
/// returns of one row (sorted by azimuth, repeated azimuths skipped; gaps over 1.5 times
/// the lower quartile, left by rays without a return, not counted), as 2 pi / step
/// rounded, within 16..65536. Fails when no row has two returns at distinct azimuths.
Expected<int> MeasureAzimuthSteps(const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::int32_t>& rows);

/// Column 0's azimuth that puts column centres on the azimuths the returns share (circular
/// mean of the returns' azimuth phases modulo one step), so that returns fired at regular
/// steps land one per column instead of straddling cell boundaries. 0 when no return.
double FitAzimuthStart(const std::vector<Eigen::Vector3f>& points, int width);
double FitAzimuthStart(const PointAngles& angles, int width);

}  // namespace cairn::od
