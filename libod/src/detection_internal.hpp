// Internal: state shared by the detectors while they run, and the assembly of a Detection
// (labels and segment features) from it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od::internal {

/// Points in the level frame (z up along gravity), structure of arrays, NaN when invalid.
/// Computed on up to `threads` threads (0: all).
struct LevelPoints {
  std::vector<float> x, y, z;
  explicit LevelPoints(const RangeImage& image, int threads = 1);
};

/// Bounds of short runs of pixels along each row (tiles of kTileWidth columns): the range of
/// their level-frame x, y and z. A scan skips a run when no point in that box can be a
/// partner: too low, too high, or too far sideways for the slope. The bound is evaluated
/// with the pair test's own float operations, which are monotonic, so it is exact: a
/// skipped run holds no compatible partner.
struct RowTiles {
  static constexpr int kTileWidth = 8;
  int tiles_per_row = 0;
  // [row * tiles_per_row + tile]; min = +inf and max = -inf when the tile has no point.
  std::vector<float> x_min, x_max, y_min, y_max, z_min, z_max;

  RowTiles(const LevelPoints& level, int width, int height);

  bool MayHoldPartner(std::size_t tile, float px, float py, float pz, const PairTest& test) const {
    const float dz_hi = std::min(z_max[tile] - pz, test.max_height);
    if (!(dz_hi > test.min_height) || !(z_min[tile] - pz < test.max_height)) return false;
    const float dx = x_min[tile] > px ? x_min[tile] - px : (px > x_max[tile] ? px - x_max[tile] : 0.0f);
    const float dy = y_min[tile] > py ? y_min[tile] - py : (py > y_max[tile] ? py - y_max[tile] : 0.0f);
    return dz_hi * dz_hi > test.tan2_theta * (dx * dx + dy * dy);
  }
};

/// Union-find over pixels; the root of a set is its smallest index, so the result does not
/// depend on the order in which pairs are found (nor on how threads split the work).
class UnionFind {
 public:
  explicit UnionFind(int n);
  int Find(int i);
  void Union(int i, int j);
  /// Adds every union of `other` (over the same pixels) to this one.
  void Merge(UnionFind& other);
  /// Representative per pixel, or -1 for a pixel alone in its set (no partner).
  std::vector<std::int32_t> Components();

 private:
  std::vector<std::int32_t> parent_;
};

/// Builds the Detection: `component[i]` is a representative pixel of i's segment (equal for
/// pixels of one segment) or -1 when i is in none. Ids follow the row-major order of each
/// segment's first pixel; features follow the definitions in detector.hpp.
/// `raised[i]` is 1 where i is the upper point of some compatible pair; with `min_height`
/// (HT) it decides the feet (Detection::foot). On up to `threads` threads (0: all), with the
/// same result on any: the sums run over parts of the segments' points that the points
/// alone decide.
Detection BuildDetection(const RangeImage& image, const LevelPoints& level,
                         const std::vector<std::int32_t>& component,
                         const std::vector<std::uint8_t>& raised, float min_height,
                         const DetectionStats& stats, int threads = 1);

/// With min_range_m > 0 and returns nearer than it: a copy of `image` without them; else
/// nullopt (the image is used as it is). DetectorConfig::min_range_m.
inline std::optional<RangeImage> WithoutNearReturns(const RangeImage& image, double min_range_m) {
  if (!(min_range_m > 0.0)) return std::nullopt;
  bool any = false;  // look before copying: most frames (and every masked one) have none
  for (int i = 0; i < image.size() && !any; ++i) any = image.valid(i) && image.range(i) < min_range_m;
  if (!any) return std::nullopt;
  RangeImage masked = image;
  if (masked.DropReturnsNearerThan(min_range_m) == 0) return std::nullopt;
  return masked;
}

}  // namespace cairn::od::internal
