// Cost values in nav2's convention and the rules that make them.
//
//   0             free
//   1 .. 252      traversable at a cost (terrain slope and roughness, inflation)
//   253           inscribed: the robot's centre here puts its footprint on an obstacle
//   254           lethal: an obstacle
//   255           unknown: never observed
//
// Inflation follows nav2's InflationLayer: a cell whose centre lies at distance d from the
// centre of the nearest lethal cell costs 254 at d = 0, 253 for d <= the inscribed radius,
// else (253 - 1) exp(-cost_scaling_factor (d - inscribed radius)), truncated, out to the
// inflation radius; an unknown cell takes an inflated cost only when it is 253 or more.
#pragma once

#include <cstdint>

namespace cairn::map {

using Cost = std::uint8_t;

inline constexpr Cost kFreeCost = 0;
inline constexpr Cost kMaxTerrainCost = 252;
inline constexpr Cost kInscribedCost = 253;
inline constexpr Cost kLethalCost = 254;
inline constexpr Cost kUnknownCost = 255;

/// nav2's inflation cost at `distance_m` from the nearest lethal cell (centre to centre) [m].
/// The caller applies the inflation radius.
Cost InflationCost(double distance_m, double inscribed_radius_m, double cost_scaling_factor);

/// Combines an inflation cost into a cell's cost as nav2 does: the larger of the two, but an
/// unknown cell stays unknown unless the inflation cost is inscribed or lethal.
inline Cost CombineInflation(Cost cell, Cost inflation) {
  if (cell == kUnknownCost) return inflation >= kInscribedCost ? inflation : cell;
  return inflation > cell ? inflation : cell;
}

/// nav2's costmap -> nav_msgs/OccupancyGrid translation: 0 -> 0, 1..252 -> 1 + 97 (c - 1) / 251
/// (integer division, so 1..98), 253 -> 99, 254 -> 100, 255 -> -1 (unknown).
std::int8_t OccupancyFromCost(Cost cost);

}  // namespace cairn::map
