#include "cairn/map/cost.hpp"

#include <cmath>

namespace cairn::map {

Cost InflationCost(double distance_m, double inscribed_radius_m, double cost_scaling_factor) {
  if (distance_m <= 0.0) return kLethalCost;
  if (distance_m <= inscribed_radius_m) return kInscribedCost;
  const double factor = std::exp(-cost_scaling_factor * (distance_m - inscribed_radius_m));
  // nav2 truncates (static_cast<unsigned char>) rather than rounds.
  return static_cast<Cost>((kInscribedCost - 1) * factor);
}

std::int8_t OccupancyFromCost(Cost cost) {
  switch (cost) {
    case kFreeCost:
      return 0;
    case kInscribedCost:
      return 99;
    case kLethalCost:
      return 100;
    case kUnknownCost:
      return -1;
    default:
      return static_cast<std::int8_t>(1 + (97 * (cost - 1)) / 251);
  }
}

}  // namespace cairn::map
