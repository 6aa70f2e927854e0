// Sensor models: how a range image's grid relates to directions in the sensor frame.
//
// A RangeImage is an organised grid; its model tells where each cell looks and where a 3-D
// point projects, which is what the exact cone search needs. The pinhole z-depth camera is
// implemented; a spherical LiDAR model (rings x azimuth) joins the variant later, so code
// that dispatches on the model uses std::visit.
#pragma once

#include <Eigen/Core>
#include <variant>

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

/// Every sensor model a RangeImage may carry (a spherical LiDAR model comes next).
using SensorModel = std::variant<PinholeModel>;

}  // namespace cairn::od
