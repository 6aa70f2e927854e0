// The ground points a tilt step fits (the refiner's and the gravity step's ground rises).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <vector>

namespace cairn::map::internal {

/// The points of `points_sensor` that are finite, not at the origin and within max_range_m
/// of the sensor, thinned evenly by index: every (n / max_points)-th of the n in range, so
/// between max_points and 2 max_points - 1 of them when there are more.
inline std::vector<Eigen::Vector3f> ThinGroundPoints(
    const std::vector<Eigen::Vector3f>& points_sensor, double max_range_m, int max_points) {
  const double max_range2 = max_range_m * max_range_m;
  std::vector<int> in_range;
  for (int i = 0; i < static_cast<int>(points_sensor.size()); ++i) {
    const Eigen::Vector3f& q = points_sensor[i];
    if (q.allFinite() && q.squaredNorm() > 0.0f && q.cast<double>().squaredNorm() <= max_range2) {
      in_range.push_back(i);
    }
  }
  const std::size_t step =
      std::max<std::size_t>(1, in_range.size() / static_cast<std::size_t>(max_points));
  std::vector<Eigen::Vector3f> out;
  out.reserve(in_range.size() / step + 1);
  for (std::size_t k = 0; k < in_range.size(); k += step) out.push_back(points_sensor[in_range[k]]);
  return out;
}

}  // namespace cairn::map::internal
