// Sensor models: how a range image's grid relates to directions in the sensor frame.
//
// A RangeImage is an organised grid; its model tells where each cell looks and where a 3-D
// point projects, which is what the exact cone search needs. The pinhole z-depth camera is
// implemented; a spherical LiDAR model (rings x azimuth) joins the variant later, so code
// that dispatches on the model uses std::visit.
#pragma once

#include <Eigen/Core>
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
  int width = 0;                             ///< azimuth steps per revolution
  std::vector<double> ring_elevation_rad;    ///< one per row, top beam first [rad]
  double azimuth_start_rad = 0.0;            ///< azimuth of column 0's centre [rad]

  int height() const { return static_cast<int>(ring_elevation_rad.size()); }
  double azimuth_step_rad() const;
  /// Names the first bad field (width < 1, no rings, non-finite or unsorted elevations).
  Status Validate() const;
  /// Azimuth of column `col`'s centre [rad].
  double ColumnAzimuth(double col) const;
  /// Column of a point's azimuth, in [0, width).
  int Column(const Eigen::Vector3d& p) const;
  /// Row of the ring nearest to a point's elevation.
  int NearestRing(const Eigen::Vector3d& p) const;

  /// Nominal models of common sensors with `width` azimuth steps: "HDL-64E" (upper block of
  /// 32 lasers 1/3 deg apart from +2 deg, lower block of 32 from -8.83 to -24.8 deg),
  /// "VLP-16" (+15 to -15 deg every 2 deg), "VLP-32C" (its data sheet table), "OS1-64"
  /// (64 rings evenly over +-16.6 deg).
  static Expected<SphericalModel> Preset(const std::string& name, int width);
};

/// Every sensor model a RangeImage may carry.
using SensorModel = std::variant<PinholeModel, SphericalModel>;

}  // namespace cairn::od
