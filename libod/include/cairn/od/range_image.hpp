// RangeImage: an organised grid of 3-D points with a validity mask and its sensor model.
//
// Storage is structure-of-arrays, row-major (index = row * width + col), points in the
// sensor frame [m]. Invalid cells (no return) hold NaN coordinates and valid = 0. The up
// vector (unit, sensor frame) gives every point its height; it comes from config, an IMU
// or a pose, and is replaced, not patched, when a refined tilt is known.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::od {

class RangeImage {
 public:
  RangeImage() = default;

  /// From a z-depth image [m] (row-major, width*height values; 0, negative or non-finite
  /// means no return) and gravity's up vector in the optical frame. Fails on a size
  /// mismatch, an invalid model or a zero / non-finite up vector.
  static Expected<RangeImage> FromDepth(const std::vector<float>& depth_m,
                                        const PinholeModel& model,
                                        const Eigen::Vector3d& up_sensor);

  /// From LiDAR points in the sensor frame (x forward, y left, z up) [m]. `rows` and `cols`
  /// give each point's cell when the data knows it (ring field, organised scans); either may
  /// be empty, and is then computed from the model (nearest nominal ring; azimuth step).
  /// A point at the origin or non-finite is no return. Where several points fall in one
  /// cell the nearest is stored; cell_of_point() maps every input point to its cell, so
  /// per-cell results go back to every point. Fails on size mismatches, out-of-range cells,
  /// an invalid model or a zero / non-finite up vector.
  static Expected<RangeImage> FromPoints(const std::vector<Eigen::Vector3f>& points,
                                         const SphericalModel& model,
                                         const Eigen::Vector3d& up_sensor,
                                         const std::vector<std::int32_t>& rows = {},
                                         const std::vector<std::int32_t>& cols = {});

  /// For images made by FromPoints: the cell (row * width + col) of each input point, -1
  /// for no return. Empty for images made from depth.
  const std::vector<std::int32_t>& cell_of_point() const { return cell_of_point_; }

  int width() const { return width_; }
  int height() const { return height_; }
  int size() const { return width_ * height_; }
  const SensorModel& model() const { return model_; }

  /// Unit up vector in the sensor frame.
  const Eigen::Vector3d& up() const { return up_; }
  /// Replaces the tilt (e.g. with a refined estimate). Fails on a zero / non-finite vector.
  Status SetUp(const Eigen::Vector3d& up_sensor);
  /// R_level_sensor: maps sensor-frame points into the level frame (see leveling.hpp).
  const Eigen::Matrix3d& R_level_sensor() const { return R_level_sensor_; }

  bool valid(int index) const { return valid_[index] != 0; }
  Eigen::Vector3d point(int index) const { return {x_[index], y_[index], z_[index]}; }
  /// Euclidean distance from the sensor origin [m] (NaN when invalid).
  double range(int index) const { return point(index).norm(); }

  const std::vector<float>& x() const { return x_; }
  const std::vector<float>& y() const { return y_; }
  const std::vector<float>& z() const { return z_; }
  const std::vector<std::uint8_t>& valid_mask() const { return valid_; }
  int valid_count() const;

  /// Turns every return nearer than `range_m` to the sensor origin into no return (the
  /// vehicle's own body, the sensor's blind zone); returns how many were dropped. Cells of
  /// cell_of_point() stay: their points then have no result (a farther point that shared
  /// the cell with a dropped one is not brought back).
  int DropReturnsNearerThan(double range_m);

 private:
  int width_ = 0;
  int height_ = 0;
  SensorModel model_;
  Eigen::Vector3d up_ = Eigen::Vector3d(0.0, -1.0, 0.0);
  Eigen::Matrix3d R_level_sensor_ = Eigen::Matrix3d::Identity();
  std::vector<float> x_, y_, z_;
  std::vector<std::uint8_t> valid_;
  std::vector<std::int32_t> cell_of_point_;

  void Allocate(int width, int height);
};

}  // namespace cairn::od
