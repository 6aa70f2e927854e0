#include "cairn/map/map_config.hpp"

#include <cmath>
#include <sstream>
#include <string>

#include "cairn/od/units.hpp"

namespace cairn::map {
namespace {

Error Bad(const char* key, const std::string& what, double value, double scale = 1.0) {
  std::ostringstream message;
  message << "map config: '" << key << "' " << what << " (got " << value * scale << ")";
  return Error{message.str()};
}

}  // namespace

Status MapConfig::Validate() const {
  const std::pair<const char*, double> all[] = {
      {"voxel_size", voxel_size_m},
      {"max_range", max_range_m},
      {"voxel_hit", voxel_hit_probability},
      {"voxel_miss", voxel_miss_probability},
      {"voxel_min", voxel_min_probability},
      {"voxel_max", voxel_max_probability},
      {"cell_size", cell_size_m},
      {"window_size", window_size_m},
      {"cell_hit", cell_hit_probability},
      {"cell_miss", cell_miss_probability},
      {"cell_min", cell_min_probability},
      {"cell_max", cell_max_probability},
      {"obstacle_probability", obstacle_probability},
      {"obstacle_min_height", obstacle_min_height_m},
      {"ground_radius", ground_radius_m},
      {"ground_max_slope", ground_max_slope_rad},
      {"merge_distance", merge_distance_m},
      {"plane_fit_radius", plane_fit_radius_m},
      {"slope_cost_max", slope_cost_max_rad},
      {"roughness_cost_max", roughness_cost_max_m},
      {"robot_radius", robot_radius_m},
      {"inflation_radius", inflation_radius_m},
      {"cost_scaling_factor", cost_scaling_factor},
  };
  for (const auto& [key, value] : all) {
    if (!std::isfinite(value)) return Bad(key, "must be finite", value);
  }
  const std::pair<const char*, double> positive[] = {
      {"voxel_size", voxel_size_m},
      {"max_range", max_range_m},
      {"cell_size", cell_size_m},
      {"plane_fit_radius", plane_fit_radius_m},
      {"roughness_cost_max", roughness_cost_max_m},
  };
  for (const auto& [key, value] : positive) {
    if (value <= 0.0) return Bad(key, "must be > 0", value);
  }
  const std::pair<const char*, double> non_negative[] = {
      {"window_size", window_size_m},
      {"obstacle_min_height", obstacle_min_height_m},
      {"ground_radius", ground_radius_m},
      {"merge_distance", merge_distance_m},
      {"robot_radius", robot_radius_m},
      {"inflation_radius", inflation_radius_m},
      {"cost_scaling_factor", cost_scaling_factor},
  };
  for (const auto& [key, value] : non_negative) {
    if (value < 0.0) return Bad(key, "must be >= 0", value);
  }
  // A hit must raise and a miss lower the log-odds; clamping must keep 0.5 reachable.
  const std::pair<const char*, double> above_half[] = {
      {"voxel_hit", voxel_hit_probability},
      {"voxel_max", voxel_max_probability},
      {"cell_hit", cell_hit_probability},
      {"cell_max", cell_max_probability},
  };
  for (const auto& [key, value] : above_half) {
    if (value <= 0.5 || value >= 1.0) return Bad(key, "must lie in (0.5, 1)", value);
  }
  const std::pair<const char*, double> below_half[] = {
      {"voxel_miss", voxel_miss_probability},
      {"voxel_min", voxel_min_probability},
      {"cell_miss", cell_miss_probability},
      {"cell_min", cell_min_probability},
  };
  for (const auto& [key, value] : below_half) {
    if (value <= 0.0 || value >= 0.5) return Bad(key, "must lie in (0, 0.5)", value);
  }
  if (obstacle_probability <= cell_min_probability ||
      obstacle_probability >= cell_max_probability) {
    return Bad("obstacle_probability", "must lie strictly between cell_min and cell_max",
               obstacle_probability);
  }
  if (voxel_size_m < 0.001 || voxel_size_m > 10.0) {
    return Bad("voxel_size", "must lie in [0.001, 10] m", voxel_size_m);
  }
  if (max_range_m > kMaxRangeM) return Bad("max_range", "must be at most 1000 m", max_range_m);
  if (cell_size_m < 0.001 || cell_size_m > 100.0) {
    return Bad("cell_size", "must lie in [0.001, 100] m", cell_size_m);
  }
  if (window_size_m > 0.0) {
    const double cells = window_size_m / cell_size_m;
    if (cells < 4.0) return Bad("window_size", "must be 0 (unbounded) or >= 4 cells", cells);
    if (cells > kMaxWindowCells) {
      return Bad("window_size", "must be at most 4096 cells a side (kMaxWindowCells)", cells);
    }
  }
  // Per-cell neighbourhoods: their cost grows with the square of their radius in cells.
  if (plane_fit_radius_m / cell_size_m > kMaxRadiusCells) {
    return Bad("plane_fit_radius", "must be at most 64 cells", plane_fit_radius_m / cell_size_m);
  }
  if (inflation_radius_m / cell_size_m > kMaxRadiusCells) {
    return Bad("inflation_radius", "must be at most 64 cells", inflation_radius_m / cell_size_m);
  }
  if (ground_radius_m / cell_size_m > kMaxRadiusCells) {
    return Bad("ground_radius", "must be at most 64 cells", ground_radius_m / cell_size_m);
  }
  if (ground_max_slope_rad < 0.0 || ground_max_slope_rad >= kPi / 2.0) {
    return Bad("ground_max_slope", "must lie in [0, 90) deg", ground_max_slope_rad, kRadToDeg);
  }
  if (slope_cost_max_rad <= 0.0 || slope_cost_max_rad >= kPi / 2.0) {
    return Bad("slope_cost_max", "must lie in (0, 90) deg", slope_cost_max_rad, kRadToDeg);
  }
  if (inflation_radius_m < robot_radius_m) {
    return Bad("inflation_radius", "must be >= robot_radius", inflation_radius_m);
  }
  if (threads < 0 || threads > 256) {
    return Bad("threads", "must be an integer in 0..256 (0: every hardware thread)", threads);
  }
  return Status::Ok();
}

}  // namespace cairn::map
