// Internal: state shared by the detectors while they run, and the assembly of a Detection
// (labels and segment features) from it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <utility>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od::internal {

/// An allocator whose elements are default-initialised, so left as they are for numbers:
/// std::vector<T, DefaultInitAllocator<T>>(n) allocates without the fill that std::vector<T>(n)
/// does, for arrays that every element of is written before it is read.
template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  using std::allocator<T>::allocator;
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0) {
      ::new (static_cast<void*>(p)) U;
    } else {
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
  }
};

/// Points in the level frame (z up along gravity), structure of arrays, NaN when invalid.
/// Computed on up to `threads` threads (0: all).
struct LevelPoints {
  /// Written whole by the constructor, in parts on its threads: not filled beforehand.
  std::vector<float, DefaultInitAllocator<float>> x, y, z;
  /// The valid points' extent in x and y (+inf / -inf when there are none) and their count,
  /// taken as the points are stored.
  float x_min = std::numeric_limits<float>::infinity(), x_max = -x_min;
  float y_min = x_min, y_max = -x_min;
  int valid = 0;
  /// With min_range_m > 0, returns nearer than it to the sensor are NaN too, as
  /// RangeImage::DropReturnsNearerThan would have left them (the same test), without a copy
  /// of the image.
  explicit LevelPoints(const RangeImage& image, int threads = 1, double min_range_m = 0.0);
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
  /// Per pixel its set's smallest pixel (the root), or -1 for a pixel alone in its set (no
  /// partner).
  std::vector<std::int32_t> Components();

 private:
  std::vector<std::int32_t> parent_;
};

/// Inclination's constants, shared by its vector versions (features.cpp): tan(pi/8), pi/4, and
/// the odd polynomial's coefficients in z = t^2, the highest power first (Horner's order).
constexpr double kInclinationTanPi8 = 0.41421356237309503, kInclinationPi4 = 0.78539816339744831;
constexpr double kInclinationPoly[6] = {-0.058377893120734145, 0.10480595274350676,
                                        -0.1422416064933773,   0.19997023132834191,
                                        -0.33333271105929246,  0.99999999627057046};

/// The box lo..hi (x, y, z) grown to hold the point (x, y, z).
inline void ExtendBox(float* lo, float* hi, float x, float y, float z) {
  lo[0] = std::min(lo[0], x);
  lo[1] = std::min(lo[1], y);
  lo[2] = std::min(lo[2], z);
  hi[0] = std::max(hi[0], x);
  hi[1] = std::max(hi[1], y);
  hi[2] = std::max(hi[2], z);
}

/// atan2(horizontal, vertical) for horizontal, vertical >= 0, not both 0: the angle from
/// the vertical axis in [0, pi/2]. Each of the three pieces [0, pi/8], [pi/8, 3pi/8] and
/// [3pi/8, pi/2] takes one division and an odd polynomial of degree 11 in t with |t| <=
/// tan(pi/8), whose coefficients were fitted for this project (least squares of atan over
/// Chebyshev nodes of [0, tan(pi/8)], reweighted toward the least maximum error, which is
/// 1.2e-10 rad): within 2e-10 rad of std::atan2
/// (`Inclination.IsAtan2` in tests/search_region_test.cpp) at a fraction of its cost,
/// which was a sixth of the column baseline's time.
inline double Inclination(double horizontal, double vertical) {
  constexpr double kTanPi8 = kInclinationTanPi8, kPi4 = kInclinationPi4;
  // Selects rather than branches, so that a loop of them runs two at a time in SSE2.
  const bool low = horizontal <= vertical * kTanPi8;
  const bool high = !low && vertical <= horizontal * kTanPi8;
  const double num = low ? horizontal : (high ? vertical : horizontal - vertical);
  const double den = low ? vertical : (high ? horizontal : horizontal + vertical);
  const double offset = low ? 0.0 : (high ? 2.0 * kPi4 : kPi4);
  const double t = (high ? -num : num) / den;
  const double z = t * t;
  double p = kInclinationPoly[0];
  for (int c = 1; c < 6; ++c) p = p * z + kInclinationPoly[c];
  return offset + t * p;
}

/// out[j] = Inclination(sqrt(squares[j]), verticals[j]) for j < n, bit for bit: eight at a
/// time with AVX-512F, four with AVX2 where the processor has them (simd.hpp), else two at a
/// time in SSE2 (the same operations in the same order, the pieces chosen by masks).
void Inclinations(const double* squares, const double* verticals, double* out, int n);

/// Builds the Detection (its labels in `component`'s storage): `component[i]` is -1 when i is in no
/// segment, i itself when i is its segment's first pixel (in row-major order), and otherwise a
/// pixel of i's segment before i (its first, say, or its parent in a union-find whose roots are the
/// sets' smallest pixels). Ids follow the row-major order of each segment's first pixel; features
/// follow the definitions in detector.hpp. `raised[i]` is 1 where i is the upper point of some
/// compatible pair; with `min_height` (HT) it decides the feet (Detection::foot). On up to
/// `threads` threads (0: all), with the same result on any: the sums run over parts of the
/// segments' points that the points alone decide.
Detection BuildDetection(const RangeImage& image, const LevelPoints& level,
                         std::vector<std::int32_t> component,
                         const std::vector<std::uint8_t>& raised, float min_height,
                         const DetectionStats& stats, int threads = 1);

/// With min_range_m > 0 and returns nearer than it: a copy of `image` without them; else
/// nullopt (the image is used as it is). DetectorConfig::min_range_m.
inline std::optional<RangeImage> WithoutNearReturns(const RangeImage& image, double min_range_m) {
  if (!(min_range_m > 0.0)) return std::nullopt;
  // Look before copying (most frames, and every masked one, have none), with the test
  // DropReturnsNearerThan and LevelPoints make, in their double arithmetic.
  const double range2 = min_range_m * min_range_m;
  bool any = false;
  for (int i = 0; i < image.size() && !any; ++i) {
    const double x = image.x()[i], y = image.y()[i], z = image.z()[i];
    any = image.valid(i) && x * x + y * y + z * z < range2;
  }
  if (!any) return std::nullopt;
  RangeImage masked = image;
  masked.DropReturnsNearerThan(min_range_m);
  return masked;
}

}  // namespace cairn::od::internal
