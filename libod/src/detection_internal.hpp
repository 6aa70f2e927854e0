// Internal: state shared by the detectors while they run, and the assembly of a Detection
// (labels and segment features) from it.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od::internal {

/// Points in the level frame (z up along gravity), structure of arrays, NaN when invalid.
struct LevelPoints {
  std::vector<float> x, y, z;
  explicit LevelPoints(const RangeImage& image);
};

/// Height bounds of short runs of pixels along each row (tiles of kTileWidth columns), so a
/// scan can skip a run none of whose points lies in the height band of a pair. Exact: a
/// skipped run holds no compatible partner.
struct RowTiles {
  static constexpr int kTileWidth = 8;
  int tiles_per_row = 0;
  std::vector<float> z_min, z_max;  // [row * tiles_per_row + tile]; +inf / -inf when empty

  RowTiles(const LevelPoints& level, int width, int height);
};

/// Union-find over pixels; the root of a set is its smallest index, so the result does not
/// depend on the order in which pairs are found.
class UnionFind {
 public:
  explicit UnionFind(int n);
  int Find(int i);
  void Union(int i, int j);

 private:
  std::vector<std::int32_t> parent_;
};

/// Slope angle atan2(dz, horizontal) for dz >= 0, within 2e-5 rad of std::atan2 (the
/// polynomial of Abramowitz & Stegun 4.4.49 on [0, 1], mirrored for steeper pairs). The
/// detectors compute one per compatible pair, where the library call dominated the run time.
inline float PairSlope(float dz, float horizontal) {
  constexpr float kHalfPi = 1.57079632679f;
  const bool steep = dz > horizontal;
  const float num = steep ? horizontal : dz, den = steep ? dz : horizontal;
  if (den <= 0.0f) return 0.0f;
  const float x = num / den, x2 = x * x;
  const float a =
      x * (0.9998660f + x2 * (-0.3302995f + x2 * (0.1801410f + x2 * (-0.0851330f + x2 * 0.0208351f))));
  return steep ? kHalfPi - a : a;
}

/// Per-pixel sums over the compatible pairs whose lower point is that pixel.
struct PairAccumulator {
  std::vector<double> slope_sum;     // [rad]
  std::vector<float> slope_max;      // [rad]
  std::vector<std::int32_t> count;
  std::vector<std::uint8_t> obstacle;  // pixel has at least one partner

  explicit PairAccumulator(int n) : slope_sum(n, 0.0), slope_max(n, 0.0f), count(n, 0),
                                    obstacle(n, 0) {}
  void Add(int lower, int upper, float dx, float dy, float dz) {
    const float slope = PairSlope(dz, std::sqrt(dx * dx + dy * dy));
    slope_sum[lower] += slope;
    if (slope > slope_max[lower]) slope_max[lower] = slope;
    ++count[lower];
    obstacle[lower] = 1;
    obstacle[upper] = 1;
  }
};

/// Builds the Detection: `component[i]` is a representative pixel of i's segment (equal for
/// pixels of one segment) or -1 when i is in none. Ids follow the row-major order of each
/// segment's first pixel; features follow the definitions in detector.hpp.
Detection BuildDetection(const RangeImage& image, const LevelPoints& level,
                         const std::vector<std::int32_t>& component, const PairAccumulator& pairs,
                         const DetectionStats& stats);

}  // namespace cairn::od::internal
