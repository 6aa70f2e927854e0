// Portable random draws for the sensor models, internal to cairn_sim: the same seed gives
// the same noise on every platform (std::normal_distribution does not promise that).
#pragma once

#include <cmath>
#include <cstdint>

#include "cairn/sim/random_scene.hpp"

namespace cairn::sim::detail {

/// Standard normal draw (Box-Muller on two uniform draws).
inline double StandardNormal(Random& rng) {
  const double u1 = 1.0 - rng.Uniform(0.0, 1.0);  // (0, 1]: log stays finite
  const double u2 = rng.Uniform(0.0, 1.0);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

/// splitmix64 of a seed and a stream index: independent-looking seeds for frames and sensors.
inline std::uint64_t Mix(std::uint64_t seed, std::uint64_t index) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

}  // namespace cairn::sim::detail
