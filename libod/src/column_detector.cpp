#include "cairn/od/column_detector.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "detection_internal.hpp"
#include "simd.hpp"

namespace cairn::od {

ColumnConfig ColumnConfig::From(const DetectorConfig& config) {
  ColumnConfig c;
  c.min_height_m = config.min_height_m;
  c.max_height_m = config.max_height_m;
  c.min_slope_rad = config.min_slope_rad;
  c.min_range_m = config.min_range_m;
  return c;
}

namespace {

DetectorConfig PairParameters(const ColumnConfig& config) {
  DetectorConfig d;
  d.min_height_m = config.min_height_m;
  d.max_height_m = config.max_height_m;
  d.min_slope_rad = config.min_slope_rad;
  d.min_range_m = config.min_range_m;
  return d;
}

}  // namespace

Status ColumnConfig::Validate() const {
  if (Status s = PairParameters(*this).Validate(); !s) {
    return Error{"column config: " + s.message().substr(s.message().find('\'') )};
  }
  if (min_blob_pixels < 0) {
    return Error{"column config: 'min_blob_pixels' must be >= 0 (got " +
                 std::to_string(min_blob_pixels) + ")"};
  }
  return Status::Ok();
}

namespace {

// Per pixel: in a compatible pair within its column (either point), the upper point of one;
// pairs_compatible counts the pairs found, pairs_tested those tested one by one.
struct ColumnPairs {
  std::vector<std::uint8_t> obstacle, raised;
  DetectionStats stats;
};

// One valid point of a binned column: its sort key, the bin (see FindColumnPairs) in the high
// half and the height's bits, made to order as unsigned integers, in the low half; and its
// place among the column's points as gathered.
struct ColumnPoint {
  std::uint64_t key;
  std::int32_t index;
};
// ColumnKeysAvx2 stores them sixteen bytes at a time.
static_assert(sizeof(ColumnPoint) == 16 && offsetof(ColumnPoint, index) == 8);

// Columns are gathered this many at a time, row by row: a column alone strides the image by its
// width, a power of two on LiDAR scans (2048), whose rows then share a handful of cache sets and
// evict one another.
constexpr int kBlockColumns = 16;

std::uint64_t ColumnKey(std::int32_t bin, float z) {
  std::uint32_t bits;
  std::memcpy(&bits, &z, sizeof bits);
  bits ^= (bits >> 31) != 0 ? 0xffffffffu : 0x80000000u;  // negative floats reversed
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(bin) ^ 0x80000000u) << 32) | bits;
}

// The bin of the point (x, y) along the horizontal direction (ux, uy), bins 1 / per_width wide,
// clamped to +-1e9 (FindColumnPairs).
std::int32_t ColumnBin(float x, float y, double ux, double uy, double per_width) {
  const double u = std::clamp((ux * x + uy * y) * per_width, -1e9, 1e9);
  int bin = static_cast<int>(u);
  bin -= static_cast<double>(bin) > u;  // floor
  return bin;
}

// Sorts by key. A column gathered from its bottom row up comes nearly sorted (the ground
// recedes, faces rise), so an insertion sort is linear; past a budget of moves it hands
// over to std::sort, and returns false. With `try_insertion` false it goes to std::sort at
// once (the column before overflowed: neighbouring columns see the same scene).
bool SortColumn(ColumnPoint* points, int m, bool try_insertion) {
  const auto sort = [&] {
    std::sort(points, points + m,
              [](const ColumnPoint& a, const ColumnPoint& b) { return a.key < b.key; });
    return false;
  };
  if (!try_insertion) return sort();
  const long budget = 8L * m + 64;
  long moves = 0;
  for (int k = 1; k < m; ++k) {
    const ColumnPoint v = points[k];
    int j = k;
    for (; j > 0 && points[j - 1].key > v.key; --j) points[j] = points[j - 1];
    points[j] = v;
    moves += k - j;
    if (moves > budget) return sort();
  }
  return true;
}

#if defined(__SSE2__)
// Set bits of four (a table: x86-64 without POPCNT makes __builtin_popcount a call).
constexpr std::uint8_t kBitCount[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};

// Neighbourhoods (a bin and the two beside it) of at most this many points are searched
// four or sixteen points at a time (simd.hpp) without windows; larger ones (dense
// images) by windows.
constexpr int kDirectPoints = 48;
// Columns of at most this many points (a LiDAR column) are searched whole, unsorted, where the
// processor has AVX2 or AVX-512F: each point with something more than HT above it is tested as
// if against every point of the column (only chunks that no window reaches are passed over),
// eight or sixteen at a time, with no keys, sort or bins to pay for. (Four
// lanes test a whole column slower than its bins: KITTI 5.1 -> 7.7 ms, BENCHMARKS.md; eight are
// quicker than four by bins on AMD EPYC: KITTI 5.7 -> 4.4 ms, RELLIS 3.6 -> 2.4.)
constexpr int kWholeColumn = 64;

// Lanes k with bit k of `bits` set all ones, the others zero.
__m128 LaneMask(int bits) {
  return _mm_castsi128_ps(
      _mm_set_epi32(-((bits >> 3) & 1), -((bits >> 2) & 1), -((bits >> 1) & 1), -(bits & 1)));
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
// FindColumnPairs' test of one lower point p with the points [r0, r1) of its neighbourhood,
// sixteen at a time (AVX-512F; an AVX2 version, eight at a time, was slower than SSE2's four:
// KITTI 5.1 -> 6.0 ms), with the pair test's float operations in its order: the upper points hit
// get all ones in `upper_hit`; `tested` and `compatible` count the points HT..Hmax above p and the
// hits. Returns whether p has a partner. Reads up to fifteen points past r1 (the padding), which do
// not count.
__attribute__((target("avx512f,popcnt"))) bool DirectAvx512(
    const float* cx, const float* cy, const float* cz, int r0, int r1, const float* p,
    const PairTest& t, std::int32_t* upper_hit, std::int64_t& tested, std::int64_t& compatible) {
  const __m512 px = _mm512_set1_ps(p[0]), py = _mm512_set1_ps(p[1]), pz = _mm512_set1_ps(p[2]);
  const __m512 vht = _mm512_set1_ps(t.min_height), vh = _mm512_set1_ps(t.max_height);
  const __m512 vt = _mm512_set1_ps(t.tan2_theta);
  const __m512i ones = _mm512_set1_epi32(-1);
  int any = 0;
  for (int j = r0; j < r1; j += 16) {
    const auto valid = static_cast<__mmask16>(r1 - j >= 16 ? 0xffff : (1 << (r1 - j)) - 1);
    const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(cz + j), pz);
    const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(cx + j), px);
    const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(cy + j), py);
    const __mmask16 window = static_cast<__mmask16>(
        valid & _mm512_cmp_ps_mask(dz, vht, _CMP_GT_OQ) & _mm512_cmp_ps_mask(dz, vh, _CMP_LT_OQ));
    const __mmask16 bits = static_cast<__mmask16>(
        window & _mm512_cmp_ps_mask(
                     _mm512_mul_ps(dz, dz),
                     _mm512_mul_ps(vt, _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy))),
                     _CMP_GT_OQ));
    tested += __builtin_popcount(window);
    compatible += __builtin_popcount(bits);
    any |= bits;
    _mm512_mask_storeu_epi32(upper_hit + j, bits, ones);
  }
  return any != 0;
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
// FindColumnPairs' window of one bin for the lower point p in a dense column, sixteen at a time
// (AVX-512F), with the pair test's float operations in its order: the points [j0, j_end), which
// ascend in height from the first more than HT above p, up to the first sixteen holding a hit
// (its hits get all ones in `upper_hit`) or to the first point Hmax or more above p. `tested` and
// `compatible` count the points looked at less than Hmax above p and the hits. Returns whether p
// has a partner. Reads up to fifteen points past j_end (the padding), which do not count.
__attribute__((target("avx512f,popcnt"))) bool WindowAvx512(
    const float* cx, const float* cy, const float* cz, int j0, int j_end, const float* p,
    const PairTest& t, std::int32_t* upper_hit, std::int64_t& tested, std::int64_t& compatible) {
  const __m512 px = _mm512_set1_ps(p[0]), py = _mm512_set1_ps(p[1]), pz = _mm512_set1_ps(p[2]);
  const __m512 vh = _mm512_set1_ps(t.max_height), vt = _mm512_set1_ps(t.tan2_theta);
  for (int j = j0; j < j_end; j += 16) {
    const auto valid = static_cast<__mmask16>(j_end - j >= 16 ? 0xffff : (1 << (j_end - j)) - 1);
    const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(cz + j), pz);
    const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(cx + j), px);
    const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(cy + j), py);
    const auto window = static_cast<__mmask16>(valid & _mm512_cmp_ps_mask(dz, vh, _CMP_LT_OQ));
    const auto bits = static_cast<__mmask16>(
        window & _mm512_cmp_ps_mask(
                     _mm512_mul_ps(dz, dz),
                     _mm512_mul_ps(vt, _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy))),
                     _CMP_GT_OQ));
    tested += __builtin_popcount(window);
    if (bits != 0) {
      compatible += __builtin_popcount(bits);
      _mm512_mask_storeu_epi32(upper_hit + j, bits, _mm512_set1_epi32(-1));
      return true;
    }
    if (window != 0xffff) return false;  // past Hmax above p, or the bin's end
  }
  return false;
}

// The whole-column kernels' chunk bounds: lane c of `lo` and `hi` gets the lowest and highest
// of the points [kWidth c, kWidth c + kWidth) of cz[0, m) for each of the `chunks` chunks (the
// padding after m left out: it is in no window), +inf and -inf in the `lanes` - `chunks` lanes
// after them (never met); returns the column's top.
template <int kWidth>
float ChunkBounds(const float* cz, int m, int chunks, int lanes, float* lo, float* hi) {
  for (int c = 0; c < lanes; ++c) {
    lo[c] = std::numeric_limits<float>::infinity();
    hi[c] = -std::numeric_limits<float>::infinity();
  }
  float top = -std::numeric_limits<float>::infinity();
  for (int c = 0; c < chunks; ++c) {
    float chunk_lo = lo[c], chunk_hi = hi[c];  // in registers (lo and hi may alias cz)
    for (int k = kWidth * c; k < std::min(kWidth * c + kWidth, m); ++k) {
      chunk_lo = std::min(chunk_lo, cz[k]);
      chunk_hi = std::max(chunk_hi, cz[k]);
    }
    lo[c] = chunk_lo;
    hi[c] = chunk_hi;
    top = std::max(top, chunk_hi);
  }
  return top;
}

// A whole column of m <= 16 kChunks points, unsorted, padded by the caller to 16 kChunks with
// points infinitely high (x = y = 0), which no window holds (infinity is not less than Hmax):
// each point p with more than HT between it and the column's top meets, sixteen at a time, the
// chunks whose heights' bounds leave room for a window (as WholeColumnAvx2's do), with the pair
// test's float operations in its order; the counts are as if every chunk were tested.
// Bit k of `lower` is set when point k is the lower point of a pair found, of `upper` when the
// upper one; `tested` and `compatible` count the points HT..Hmax above p and the hits.
template <int kChunks>
__attribute__((target("avx512f,popcnt"))) void WholeColumnAvx512(
    const float* cx, const float* cy, const float* cz, int m, const PairTest& t,
    std::uint64_t& lower, std::uint64_t& upper, std::int64_t& tested, std::int64_t& compatible) {
  static_assert(kChunks <= 4);
  alignas(16) float chunk_lo[4], chunk_hi[4];
  const float top = ChunkBounds<16>(cz, m, kChunks, 4, chunk_lo, chunk_hi);
  const __m128 lo_z = _mm_load_ps(chunk_lo), hi_z = _mm_load_ps(chunk_hi);
  const __m128 ht4 = _mm_set1_ps(t.min_height), h4 = _mm_set1_ps(t.max_height);
  const __m512 vht = _mm512_set1_ps(t.min_height), vh = _mm512_set1_ps(t.max_height);
  const __m512 vt = _mm512_set1_ps(t.tan2_theta);
  std::uint64_t lo = 0, up = 0;
  int in_window = 0, hit = 0;
  for (int k = 0; k < m; ++k) {
    if (!(top - cz[k] > t.min_height)) continue;  // nothing more than HT above it
    const __m128 pz4 = _mm_set1_ps(cz[k]);
    auto chunks = static_cast<unsigned>(_mm_movemask_ps(_mm_and_ps(
        _mm_cmpgt_ps(_mm_sub_ps(hi_z, pz4), ht4), _mm_cmplt_ps(_mm_sub_ps(lo_z, pz4), h4))));
    if (chunks == 0) continue;
    const __m512 px = _mm512_set1_ps(cx[k]), py = _mm512_set1_ps(cy[k]);
    const __m512 pz = _mm512_set1_ps(cz[k]);
    std::uint64_t hits = 0;
    for (; chunks != 0; chunks &= chunks - 1) {
      const int c = __builtin_ctz(chunks);
      const __m512 dz = _mm512_sub_ps(_mm512_loadu_ps(cz + 16 * c), pz);
      const __m512 dx = _mm512_sub_ps(_mm512_loadu_ps(cx + 16 * c), px);
      const __m512 dy = _mm512_sub_ps(_mm512_loadu_ps(cy + 16 * c), py);
      const __mmask16 window = static_cast<__mmask16>(_mm512_cmp_ps_mask(dz, vht, _CMP_GT_OQ) &
                                                      _mm512_cmp_ps_mask(dz, vh, _CMP_LT_OQ));
      const __mmask16 bits = static_cast<__mmask16>(
          window & _mm512_cmp_ps_mask(_mm512_mul_ps(dz, dz),
                                      _mm512_mul_ps(vt, _mm512_add_ps(_mm512_mul_ps(dx, dx),
                                                                      _mm512_mul_ps(dy, dy))),
                                      _CMP_GT_OQ));
      in_window += __builtin_popcount(window);
      hits |= static_cast<std::uint64_t>(bits) << (16 * c);
    }
    hit += __builtin_popcountll(hits);
    up |= hits;
    lo |= static_cast<std::uint64_t>(hits != 0) << k;
  }
  lower = lo;
  upper = up;
  tested += in_window;
  compatible += hit;
}

// WholeColumnAvx512 eight points at a time (AVX2): a whole column of m <= 8 kChunks points,
// padded by the caller to 8 kChunks with points infinitely high, each chunk read from memory,
// the column's top found here. A point meets only the chunks whose heights' bounds leave room for a
// window: where the highest is HT or less above it, or the lowest Hmax or more, no point of the
// chunk is in its window (the difference is rounded monotonically), so the counts are as if every
// chunk were tested.
template <int kChunks>
__attribute__((target("avx2,popcnt"))) void WholeColumnAvx2(
    const float* cx, const float* cy, const float* cz, int m, const PairTest& t,
    std::uint64_t& lower, std::uint64_t& upper, std::int64_t& tested, std::int64_t& compatible) {
  static_assert(kChunks <= 8);
  const __m256 vht = _mm256_set1_ps(t.min_height), vh = _mm256_set1_ps(t.max_height);
  const __m256 vt = _mm256_set1_ps(t.tan2_theta);
  alignas(32) float chunk_lo[8], chunk_hi[8];
  const float top = ChunkBounds<8>(cz, m, kChunks, 8, chunk_lo, chunk_hi);
  const __m256 lo_z = _mm256_load_ps(chunk_lo), hi_z = _mm256_load_ps(chunk_hi);
  std::uint64_t lo = 0, up = 0;
  int in_window = 0, hit = 0;
  for (int k = 0; k < m; ++k) {
    if (!(top - cz[k] > t.min_height)) continue;  // nothing more than HT above it
    const __m256 pz = _mm256_set1_ps(cz[k]);
    auto chunks = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps(_mm256_sub_ps(hi_z, pz), vht, _CMP_GT_OQ),
                                         _mm256_cmp_ps(_mm256_sub_ps(lo_z, pz), vh, _CMP_LT_OQ))));
    if (chunks == 0) continue;
    const __m256 px = _mm256_set1_ps(cx[k]), py = _mm256_set1_ps(cy[k]);
    std::uint64_t hits = 0;
    for (; chunks != 0; chunks &= chunks - 1) {
      const int c = __builtin_ctz(chunks);
      const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(cz + 8 * c), pz);
      const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(cx + 8 * c), px);
      const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(cy + 8 * c), py);
      const __m256 window =
          _mm256_and_ps(_mm256_cmp_ps(dz, vht, _CMP_GT_OQ), _mm256_cmp_ps(dz, vh, _CMP_LT_OQ));
      const __m256 bits = _mm256_and_ps(
          window, _mm256_cmp_ps(_mm256_mul_ps(dz, dz),
                                _mm256_mul_ps(vt, _mm256_add_ps(_mm256_mul_ps(dx, dx),
                                                                _mm256_mul_ps(dy, dy))),
                                _CMP_GT_OQ));
      in_window += __builtin_popcount(static_cast<unsigned>(_mm256_movemask_ps(window)));
      hits |= static_cast<std::uint64_t>(_mm256_movemask_ps(bits)) << (8 * c);
    }
    hit += __builtin_popcountll(hits);
    up |= hits;
    lo |= static_cast<std::uint64_t>(hits != 0) << k;
  }
  lower = lo;
  upper = up;
  tested += in_window;
  compatible += hit;
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
// The eight rows r[0..7] (eight columns each) as eight columns (eight rows each): out[c] holds
// lane c of every r, r[0]'s first.
__attribute__((target("avx2"))) inline void Transpose8(const __m256 r[8], __m256 out[8]) {
  const __m256 a0 = _mm256_unpacklo_ps(r[0], r[1]), a1 = _mm256_unpackhi_ps(r[0], r[1]);
  const __m256 a2 = _mm256_unpacklo_ps(r[2], r[3]), a3 = _mm256_unpackhi_ps(r[2], r[3]);
  const __m256 a4 = _mm256_unpacklo_ps(r[4], r[5]), a5 = _mm256_unpackhi_ps(r[4], r[5]);
  const __m256 a6 = _mm256_unpacklo_ps(r[6], r[7]), a7 = _mm256_unpackhi_ps(r[6], r[7]);
  const __m256 b0 = _mm256_shuffle_ps(a0, a2, 0x44), b1 = _mm256_shuffle_ps(a0, a2, 0xee);
  const __m256 b2 = _mm256_shuffle_ps(a1, a3, 0x44), b3 = _mm256_shuffle_ps(a1, a3, 0xee);
  const __m256 b4 = _mm256_shuffle_ps(a4, a6, 0x44), b5 = _mm256_shuffle_ps(a4, a6, 0xee);
  const __m256 b6 = _mm256_shuffle_ps(a5, a7, 0x44), b7 = _mm256_shuffle_ps(a5, a7, 0xee);
  out[0] = _mm256_permute2f128_ps(b0, b4, 0x20);
  out[1] = _mm256_permute2f128_ps(b1, b5, 0x20);
  out[2] = _mm256_permute2f128_ps(b2, b6, 0x20);
  out[3] = _mm256_permute2f128_ps(b3, b7, 0x20);
  out[4] = _mm256_permute2f128_ps(b0, b4, 0x31);
  out[5] = _mm256_permute2f128_ps(b1, b5, 0x31);
  out[6] = _mm256_permute2f128_ps(b2, b6, 0x31);
  out[7] = _mm256_permute2f128_ps(b3, b7, 0x31);
}

// FindColumnPairs' gathering of the columns [c0, c0 + 8 * kTiles), eight rows at a time (AVX2):
// each eight columns' eight rows turned into the columns' eight points, bottom row first, and
// each column's valid ones (z not NaN) moved to the front and stored after the column's points
// so far. Column b's points go to g[b * stride + k] (x, y, z at gx, gy, gz, row at grow), and
// count[b] counts them. The rows [0, rows % 8), at the top, are left to the caller; each column
// needs room for 7 writes past its last point.
template <int kTiles>
__attribute__((target("avx2,popcnt"))) void GatherColumnsAvx2(const float* x, const float* y,
                                                              const float* z, int width, int rows,
                                                              int c0, std::size_t stride, float* gx,
                                                              float* gy, float* gz,
                                                              std::int32_t* grow, int* count) {
  for (int r = rows - 1; r >= 7; r -= 8) {
    // Lane k of `row` is the row of each column's point k.
    const __m256i row =
        _mm256_sub_epi32(_mm256_set1_epi32(r), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    for (int t = 0; t < kTiles; ++t) {
      __m256 in[8], cx[8], cy[8], cz[8];
      const std::size_t first = static_cast<std::size_t>(r) * width + c0 + 8 * t;
      for (int k = 0; k < 8; ++k)
        in[k] = _mm256_loadu_ps(z + first - static_cast<std::size_t>(k) * width);
      Transpose8(in, cz);
      for (int k = 0; k < 8; ++k)
        in[k] = _mm256_loadu_ps(x + first - static_cast<std::size_t>(k) * width);
      Transpose8(in, cx);
      for (int k = 0; k < 8; ++k)
        in[k] = _mm256_loadu_ps(y + first - static_cast<std::size_t>(k) * width);
      Transpose8(in, cy);
      for (int b = 0; b < 8; ++b) {
        const int column = 8 * t + b;
        const auto valid =
            static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(cz[b], cz[b], _CMP_ORD_Q)));
        const __m256i front = internal::ToFront8(valid);
        const std::size_t at = column * stride + count[column];
        _mm256_storeu_ps(gx + at, _mm256_permutevar8x32_ps(cx[b], front));
        _mm256_storeu_ps(gy + at, _mm256_permutevar8x32_ps(cy[b], front));
        _mm256_storeu_ps(gz + at, _mm256_permutevar8x32_ps(cz[b], front));
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(grow + at),
                            _mm256_permutevar8x32_epi32(row, front));
        count[column] += __builtin_popcount(valid);
      }
    }
  }
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
// FindColumnPairs' keys of a binned column's m points (x, y, z), four at a time in doubles
// (AVX2), with the scalar loop's double operations in its order: for a finite u (every level
// point's) the same key. Point k gets {key, k} in out[k]. Adds the points' x and y to mx and my
// (in another order than one by one, which changes the next column's bins but not what they
// find).
__attribute__((target("avx2"))) void ColumnKeysAvx2(const float* x, const float* y, const float* z,
                                                    int m, double ux, double uy, double per_width,
                                                    ColumnPoint* out, double& mx, double& my) {
  const __m256d vux = _mm256_set1_pd(ux), vuy = _mm256_set1_pd(uy);
  const __m256d vper = _mm256_set1_pd(per_width);
  const __m256d lo = _mm256_set1_pd(-1e9), hi = _mm256_set1_pd(1e9);
  const __m128i sign = _mm_set1_epi32(static_cast<int>(0x80000000u));
  __m256d sx = _mm256_setzero_pd(), sy = _mm256_setzero_pd();
  int k = 0;
  for (; k + 4 <= m; k += 4) {
    const __m256d px = _mm256_cvtps_pd(_mm_loadu_ps(x + k));
    const __m256d py = _mm256_cvtps_pd(_mm_loadu_ps(y + k));
    sx = _mm256_add_pd(sx, px);
    sy = _mm256_add_pd(sy, py);
    // std::clamp's result for a number, then floor (exact in doubles within +-1e9).
    const __m256d u = _mm256_min_pd(
        _mm256_max_pd(
            _mm256_mul_pd(_mm256_add_pd(_mm256_mul_pd(vux, px), _mm256_mul_pd(vuy, py)), vper), lo),
        hi);
    const __m128i bin = _mm_xor_si128(
        _mm256_cvtpd_epi32(_mm256_round_pd(u, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC)), sign);
    // The heights' bits, negative ones reversed (ColumnKey).
    const __m128i bits = _mm_castps_si128(_mm_loadu_ps(z + k));
    const __m128i height = _mm_xor_si128(bits, _mm_or_si128(_mm_srai_epi32(bits, 31), sign));
    const __m128i index = _mm_setr_epi32(k, k + 1, k + 2, k + 3);
    const __m128i keys_lo = _mm_unpacklo_epi32(height, bin),
                  keys_hi = _mm_unpackhi_epi32(height, bin);
    const __m128i index_lo = _mm_unpacklo_epi32(index, _mm_setzero_si128());
    const __m128i index_hi = _mm_unpackhi_epi32(index, _mm_setzero_si128());
    auto* const to = reinterpret_cast<__m128i*>(out + k);
    _mm_storeu_si128(to, _mm_unpacklo_epi64(keys_lo, index_lo));
    _mm_storeu_si128(to + 1, _mm_unpackhi_epi64(keys_lo, index_lo));
    _mm_storeu_si128(to + 2, _mm_unpacklo_epi64(keys_hi, index_hi));
    _mm_storeu_si128(to + 3, _mm_unpackhi_epi64(keys_hi, index_hi));
  }
  alignas(32) double lanes_x[4], lanes_y[4];
  _mm256_store_pd(lanes_x, sx);
  _mm256_store_pd(lanes_y, sy);
  for (int l = 0; l < 4; ++l) {
    mx += lanes_x[l];
    my += lanes_y[l];
  }
  for (; k < m; ++k) {
    out[k] = {ColumnKey(ColumnBin(x[k], y[k], ux, uy, per_width), z[k]), k};
    mx += x[k];
    my += y[k];
  }
}
#endif

// The compatible pairs within each column, fast. Where the processor has AVX2 or AVX-512F
// (simd.hpp), a column of at most kWholeColumn points (a LiDAR column) is searched whole,
// unsorted: each point with something more than HT above it is tested as if against every
// point of the column (chunks that no window reaches are passed over), eight or sixteen at a
// time, the window a mask, and every pair is found. Larger columns, and every column on narrower
// vectors, are cut into bins. A partner q of a lower point p lies less than reach = Hmax /
// tan(theta) from it horizontally, so less than reach along any horizontal direction: the column's
// points are put in bins of that width along the column's mean horizontal direction u, each bin
// sorted by height, and p meets the points of its own and the two neighbouring bins from the first
// more than HT above it (as the pair test rounds the difference, which grows with the upper height)
// to the last less than Hmax above. Where the three bins hold at most kDirectPoints, p meets all of
// them four or sixteen at a time (DirectAvx512), every pair found. Where they hold more (a dense
// image's column, whose faces hold hundreds of points each within Hmax of another), and always
// without SSE2 or with the lanes capped to one, a point needs only one partner each way: p's window
// is searched up to its first hit (four points at a time, sixteen with AVX-512F, every hit among
// them marked), and then each point not yet marked as an upper point searches the window below it,
// nearest first, up to its first hit. The points of a bin stop at the first with no point of those
// bins more than HT above it. The columns are gathered kBlockColumns at a time, row by row, bottom
// row first, into reused buffers (with AVX2, eight rows of eight columns at a time), and only their
// points in a pair are marked.
ColumnPairs FindColumnPairs(const internal::LevelPoints& level, const PairTest& test, int width,
                            int height) {
  const int n = width * height;
  ColumnPairs out{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0), {}};
  // Local pointers and counters: the byte stores below may alias anything in memory, but
  // not these (every one kept in memory would be loaded again after each store).
  std::uint8_t* const obstacle = out.obstacle.data();
  std::uint8_t* const raised = out.raised.data();
  std::int64_t pairs_compatible = 0, pairs_tested = 0;
  struct Bin {
    std::int32_t bin;
    int begin, end;  // its points in the column
    bool searched;   // its lower points searched up to their first hit only
  };
  std::vector<Bin> bins;
  // A block of columns: per column its valid points, bottom row first, side by side (x, y, z
  // and row), with room past the last for the whole-column search's padding. Each pixel is
  // written where the column's next valid point goes, and counted only when valid: holes
  // (four in ten pixels of an OS1 scan) cost no branch.
  [[maybe_unused]] const int lanes = internal::VectorLanes();
#if defined(CAIRN_OD_WIDE_VECTORS)
  // Every column is searched whole (a LiDAR scan of at most kWholeColumn rows): no bins, so no
  // direction to follow.
  const bool all_whole = lanes >= 8 && height <= kWholeColumn;
#endif
  constexpr int kPad = 16;
  const std::size_t block_stride = static_cast<std::size_t>(height) + kPad;
  std::vector<float> block_xyz(3 * kBlockColumns * block_stride);
  std::vector<std::int32_t> block_row(kBlockColumns * block_stride);
  std::array<int, kBlockColumns> gathered_count{};
  const auto gather_block = [&](int c0) {
    const int block = std::min(kBlockColumns, width - c0);
    gathered_count.fill(0);
    float* const gx = block_xyz.data();
    float* const gy = gx + kBlockColumns * block_stride;
    float* const gz = gy + kBlockColumns * block_stride;
    std::int32_t* const grow = block_row.data();
    int rows = height;  // the rows [0, rows) left to gather one pixel at a time
#if defined(CAIRN_OD_WIDE_VECTORS)
    if (lanes >= 8 && block == kBlockColumns) {
      GatherColumnsAvx2<kBlockColumns / 8>(level.x.data(), level.y.data(), level.z.data(), width,
                                           height, c0, block_stride, gx, gy, gz, grow,
                                           gathered_count.data());
      rows = height % 8;
    }
#endif
    for (int r = rows - 1; r >= 0; --r) {
      const int row_first = r * width + c0;
      for (int b = 0; b < block; ++b) {
        const int i = row_first + b;
        const float z = level.z[i];
        const std::size_t k = b * block_stride + gathered_count[b];
        gx[k] = level.x[i];
        gy[k] = level.y[i];
        gz[k] = z;
        grow[k] = r;
        gathered_count[b] += !std::isnan(z);
      }
    }
  };
  // A binned column's points with their keys, sorted.
  std::vector<ColumnPoint> column(static_cast<std::size_t>(height));
  // A binned column's points side by side (x, y, z), in sorted order, with room for reading
  // sixteen from any point and four from three before the first; and per point whether it is the
  // upper point of a pair found (all ones) or the lower one. (A whole column is searched where it
  // was gathered, its marks as bits.)
  const std::size_t stride = static_cast<std::size_t>(height) + 2 * kPad;
  std::vector<float> xyz(3 * stride, 0.0f);
  float* const cx = xyz.data() + kPad;
  float* const cy = cx + stride;
  float* const cz = cy + stride;
  std::vector<std::int32_t> hits(2 * stride, 0);
  std::int32_t* const upper_hit = hits.data() + kPad;
  std::int32_t* const lower_hit = upper_hit + stride;
#if defined(__SSE2__)
  const __m128 kLaneMasks[16] = {LaneMask(0),  LaneMask(1),  LaneMask(2),  LaneMask(3),
                                 LaneMask(4),  LaneMask(5),  LaneMask(6),  LaneMask(7),
                                 LaneMask(8),  LaneMask(9),  LaneMask(10), LaneMask(11),
                                 LaneMask(12), LaneMask(13), LaneMask(14), LaneMask(15)};
#endif
  const float ht = test.min_height, hmax = test.max_height, tan2 = test.tan2_theta;
  // The bins are wider than the reach by a margin covering the rounding of u. Bin numbers
  // are clamped to +-1e9: a bin that far out holds nothing within reach of the others.
  const double bin_width =
      test.max_height / std::sqrt(static_cast<double>(test.tan2_theta)) * 1.001 + 1e-3;
  const double per_width = 1.0 / bin_width;
  // u is the horizontal direction of the column before (its points' mean); any horizontal
  // direction keeps the bins' argument, one near the column's keeps its bins short. The
  // first column's comes from its own points.
  double ux = 1.0, uy = 0.0;
  const auto direction = [&](double mx, double my) {
    const double norm = std::sqrt(mx * mx + my * my);
    if (norm > 0.0) {
      ux = mx / norm;
      uy = my / norm;
    }
  };
  if (width > 0) {
    double mx = 0.0, my = 0.0;
    for (int i = (height - 1) * width; i >= 0; i -= width) {
      if (std::isnan(level.z[i])) continue;
      mx += level.x[i];
      my += level.y[i];
    }
    direction(mx, my);
  }
  // The pair test of the point k with the point j (k the lower point when `k_lower`), for
  // the scalar paths: whether they are HT..Hmax apart (`window`) and compatible.
  [[maybe_unused]] const auto pair_at = [&](int k, int j, bool k_lower, bool& window) {
    const int lo = k_lower ? k : j, up = k_lower ? j : k;
    const float dz = cz[up] - cz[lo];
    window = dz > ht && dz < hmax;
    const float dx = cx[up] - cx[lo], dy = cy[up] - cy[lo];
    return window && dz * dz > tan2 * (dx * dx + dy * dy);
  };
  bool nearly_sorted = true;  // the last column sorted was sorted by insertion within its budget
  for (int c = 0; c < width; ++c) {
    const int b = c % kBlockColumns;
    if (b == 0) gather_block(c);
    const int m = gathered_count[b];
    float* const gx = block_xyz.data() + b * block_stride;
    float* const gy = gx + kBlockColumns * block_stride;
    float* const gz = gy + kBlockColumns * block_stride;
    const std::int32_t* const grow = block_row.data() + b * block_stride;
#if defined(CAIRN_OD_WIDE_VECTORS)
    if (lanes >= 8 && m <= kWholeColumn) {
      // Few points (a LiDAR column): each tested as if against every point of the column, unsorted
      // and without bins, where it was gathered; only a point with nothing more than HT above it is
      // passed over.
      if (m == 0) continue;  // no point, no direction
      if (!all_whole) {
        // The next column may be binned: its bins follow this column's direction.
        double mx = 0.0, my = 0.0;
        for (int k = 0; k < m; ++k) {
          mx += gx[k];
          my += gy[k];
        }
        direction(mx, my);
      }
      for (int k = m; k < ((m + 15) & ~15); ++k) {
        gx[k] = gy[k] = 0.0f;
        gz[k] = std::numeric_limits<float>::infinity();
      }
      std::uint64_t lower = 0, upper = 0;
      // The top taken from the chunks' bounds.
      if (lanes == 16) {
        const auto whole = m <= 16   ? WholeColumnAvx512<1>
                           : m <= 32 ? WholeColumnAvx512<2>
                           : m <= 48 ? WholeColumnAvx512<3>
                                     : WholeColumnAvx512<4>;
        whole(gx, gy, gz, m, test, lower, upper, pairs_tested, pairs_compatible);
      } else {
        const auto whole = m <= 8    ? WholeColumnAvx2<1>
                           : m <= 16 ? WholeColumnAvx2<2>
                           : m <= 24 ? WholeColumnAvx2<3>
                           : m <= 32 ? WholeColumnAvx2<4>
                           : m <= 40 ? WholeColumnAvx2<5>
                           : m <= 48 ? WholeColumnAvx2<6>
                           : m <= 56 ? WholeColumnAvx2<7>
                                     : WholeColumnAvx2<8>;
        whole(gx, gy, gz, m, test, lower, upper, pairs_tested, pairs_compatible);
      }
      for (std::uint64_t any = lower | upper; any != 0; any &= any - 1) {
        const int k = __builtin_ctzll(any);
        const int i = grow[k] * width + c;
        obstacle[i] = 1;
        raised[i] = static_cast<std::uint8_t>((upper >> k) & 1);
      }
      continue;
    }
#endif
    double mx = 0.0, my = 0.0;
#if defined(CAIRN_OD_WIDE_VECTORS)
    if (lanes >= 8) {
      ColumnKeysAvx2(gx, gy, gz, m, ux, uy, per_width, column.data(), mx, my);
    } else
#endif
    {
      for (int k = 0; k < m; ++k) {
        column[k] = {ColumnKey(ColumnBin(gx[k], gy[k], ux, uy, per_width), gz[k]), k};
        mx += gx[k];
        my += gy[k];
      }
    }
    direction(mx, my);
    if (m < 2) continue;
    // After a column that overflowed, every kBlockColumns-th column tries again.
    nearly_sorted = SortColumn(column.data(), m, nearly_sorted || b == 0);
    for (int k = 0; k < m; ++k) {
      const int j = column[k].index;
      cx[k] = gx[j];
      cy[k] = gy[j];
      cz[k] = gz[j];
    }
    std::fill_n(upper_hit, m, 0);
    std::fill_n(lower_hit, m, 0);
    bins.clear();
    for (int k = 0; k < m; ++k) {
      const auto bin = static_cast<std::int32_t>((column[k].key >> 32) ^ 0x80000000u);
      if (bins.empty() || bins.back().bin != bin) bins.push_back({bin, k, k, false});
      bins.back().end = k + 1;
    }
    const int nb = static_cast<int>(bins.size());
    // The bins within one of g's: consecutive in the column (sorted by bin), [near_begin,
    // near_end) of `bins`.
    const auto near_begin = [&](int g) {
      return g > 0 && bins[g - 1].bin == bins[g].bin - 1 ? g - 1 : g;
    };
    const auto near_end = [&](int g) {
      return g + 1 < nb && bins[g + 1].bin == bins[g].bin + 1 ? g + 2 : g + 1;
    };
    // Each point as the lower one: whether some point of the near bins is compatible with it.
    // With SSE2, where they hold at most kDirectPoints, every one of them is tested, four
    // or sixteen at a time, and every hit marked; else (and always without SSE2 or with
    // the lanes capped to one) each bin's window is searched
    // up to the first hit, and the bin is `searched`: the upper points it leaves unmarked are
    // settled below.
    bool any_searched = false;
    for (int g = 0; g < nb; ++g) {
      const int h0 = near_begin(g), h1 = near_end(g);
      float top = -std::numeric_limits<float>::infinity();
      for (int h = h0; h < h1; ++h) top = std::max(top, cz[bins[h].end - 1]);
#if defined(__SSE2__)
      const int r0 = bins[h0].begin, r1 = bins[h1 - 1].end;
      if (lanes >= 4 && r1 - r0 <= kDirectPoints) {
        // Few points near: each lower point meets all of them 4 or 16 at a time, the window
        // HT..Hmax and the slope as bit masks (the pair test's float operations in its
        // order), without a branch on either.
        const __m128 vht = _mm_set1_ps(ht), vhmax = _mm_set1_ps(hmax), vt = _mm_set1_ps(tan2);
        for (int k = bins[g].begin; k < bins[g].end; ++k) {
          const float pz_scalar = cz[k];
          if (!(top - pz_scalar > ht)) break;  // nothing more than HT above this point or the next
#if defined(CAIRN_OD_WIDE_VECTORS)
          if (lanes == 16) {
            const float p[3] = {cx[k], cy[k], pz_scalar};
            const bool any = DirectAvx512(cx, cy, cz, r0, r1, p, test, upper_hit, pairs_tested,
                                          pairs_compatible);
            lower_hit[k] |= any ? -1 : 0;
            continue;
          }
#endif
          const __m128 px = _mm_set1_ps(cx[k]), py = _mm_set1_ps(cy[k]);
          const __m128 pz = _mm_set1_ps(pz_scalar);
          int any = 0;
          for (int j = r0; j < r1; j += 4) {
            const int valid = r1 - j >= 4 ? 0xf : (1 << (r1 - j)) - 1;
            const __m128 dz = _mm_sub_ps(_mm_loadu_ps(cz + j), pz);
            const __m128 dx = _mm_sub_ps(_mm_loadu_ps(cx + j), px);
            const __m128 dy = _mm_sub_ps(_mm_loadu_ps(cy + j), py);
            const __m128 window = _mm_and_ps(_mm_cmpgt_ps(dz, vht), _mm_cmplt_ps(dz, vhmax));
            const __m128 steep =
                _mm_cmpgt_ps(_mm_mul_ps(dz, dz),
                             _mm_mul_ps(vt, _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy))));
            const __m128 hit = _mm_and_ps(_mm_and_ps(window, steep), kLaneMasks[valid]);
            const int bits = _mm_movemask_ps(hit);
            pairs_tested += kBitCount[_mm_movemask_ps(window) & valid];
            pairs_compatible += kBitCount[bits];
            any |= bits;
            __m128i* marks = reinterpret_cast<__m128i*>(upper_hit + j);
            _mm_storeu_si128(marks, _mm_or_si128(_mm_loadu_si128(marks), _mm_castps_si128(hit)));
          }
          lower_hit[k] |= any;
        }
        continue;
      }
#endif
      // Many points near (a dense image's column): each bin's window, from the first point
      // more than HT above the current lower point (which only moves up, as the lower points
      // of g do) to the last less than Hmax above, up to the first hit.
      bins[g].searched = any_searched = true;
      int first[3];
      for (int h = h0; h < h1; ++h) first[h - h0] = bins[h].begin;
      for (int k = bins[g].begin; k < bins[g].end; ++k) {
        const float pz = cz[k];
        if (!(top - pz > ht)) break;  // nothing more than HT above this point or the next
#if defined(__SSE2__)
        const __m128 vpx = _mm_set1_ps(cx[k]), vpy = _mm_set1_ps(cy[k]), vpz = _mm_set1_ps(pz);
        const __m128 vhmax = _mm_set1_ps(hmax), vt = _mm_set1_ps(tan2);
#endif
        bool found = false;
        for (int h = h0; h < h1 && !found; ++h) {
          int& j0 = first[h - h0];
          const int j_end = bins[h].end;
          while (j0 < j_end && !(cz[j0] - pz > ht)) ++j0;
#if defined(CAIRN_OD_WIDE_VECTORS)
          if (lanes == 16) {
            const float p[3] = {cx[k], cy[k], pz};
            found = WindowAvx512(cx, cy, cz, j0, j_end, p, test, upper_hit, pairs_tested,
                                 pairs_compatible);
            continue;
          }
#endif
#if defined(__SSE2__)
          if (lanes >= 4) {
            // Four at a time (heights ascend: past the first point Hmax or more above, none is
            // less); the hits of the four marked.
            for (int j = j0; j < j_end; j += 4) {
              const int valid = j_end - j >= 4 ? 0xf : (1 << (j_end - j)) - 1;
              const __m128 dz = _mm_sub_ps(_mm_loadu_ps(cz + j), vpz);
              const __m128 dx = _mm_sub_ps(_mm_loadu_ps(cx + j), vpx);
              const __m128 dy = _mm_sub_ps(_mm_loadu_ps(cy + j), vpy);
              const __m128 window = _mm_and_ps(_mm_cmplt_ps(dz, vhmax), kLaneMasks[valid]);
              const __m128 steep =
                  _mm_cmpgt_ps(_mm_mul_ps(dz, dz),
                               _mm_mul_ps(vt, _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy))));
              const __m128 hit = _mm_and_ps(window, steep);
              const int in_window = _mm_movemask_ps(window);
              const int bits = _mm_movemask_ps(hit);
              pairs_tested += kBitCount[in_window];
              if (bits != 0) {
                pairs_compatible += kBitCount[bits];
                __m128i* marks = reinterpret_cast<__m128i*>(upper_hit + j);
                _mm_storeu_si128(marks,
                                 _mm_or_si128(_mm_loadu_si128(marks), _mm_castps_si128(hit)));
                found = true;
                break;
              }
              if (in_window != 0xf) break;
            }
          } else  // one at a time (lanes capped to 1)
#endif
          {
            for (int j = j0; j < j_end; ++j) {
              bool window;
              const bool compatible = pair_at(k, j, true, window);
              if (!window) break;
              ++pairs_tested;
              if (compatible) {
                ++pairs_compatible;
                upper_hit[j] = -1;
                found = true;
                break;
              }
            }
          }
        }
        if (found) lower_hit[k] = -1;
      }
    }
    // Each point not yet marked as an upper point, where a bin near it was searched: whether
    // some point of the searched bins near it is compatible with it as the lower point,
    // nearest in height first (the window from the last point more than HT below it down to
    // the first less than Hmax below), up to the first hit. (A bin tested whole has marked
    // every upper point of its lower points already.)
    for (int g = 0; g < nb && any_searched; ++g) {
      const int h0 = near_begin(g), h1 = near_end(g);
      bool settled = true;
      float bottom = std::numeric_limits<float>::infinity();
      for (int h = h0; h < h1; ++h) {
        if (!bins[h].searched) continue;
        settled = false;
        bottom = std::min(bottom, cz[bins[h].begin]);
      }
      if (settled) continue;
      int lo[3], hi[3];
      for (int h = h0; h < h1; ++h) lo[h - h0] = hi[h - h0] = bins[h].begin;
      for (int k = bins[g].begin; k < bins[g].end; ++k) {
        if (upper_hit[k] != 0) continue;
        const float qz = cz[k];
        if (!(qz - bottom > ht))
          continue;  // nothing more than HT below it (nor below those before)
#if defined(__SSE2__)
        const __m128 vqx = _mm_set1_ps(cx[k]), vqy = _mm_set1_ps(cy[k]), vqz = _mm_set1_ps(qz);
        const __m128 vt = _mm_set1_ps(tan2);
#endif
        bool found = false;
        for (int h = h0; h < h1 && !found; ++h) {
          if (!bins[h].searched) continue;
          int &j_lo = lo[h - h0], &j_hi = hi[h - h0];
          const int j_end = bins[h].end;
          while (j_lo < j_end && !(qz - cz[j_lo] < hmax)) ++j_lo;
          j_hi = std::max(j_hi, j_lo);
          while (j_hi < j_end && qz - cz[j_hi] > ht) ++j_hi;
#if defined(__SSE2__)
          if (lanes >= 4) {
            for (int j = j_hi - 4; j > j_lo - 4; j -= 4) {
              // Lanes below j_lo are out of the window (past it, in the padding or another bin).
              const int valid = j >= j_lo ? 0xf : 0xf & (0xf << (j_lo - j));
              const __m128 dz = _mm_sub_ps(vqz, _mm_loadu_ps(cz + j));
              const __m128 dx = _mm_sub_ps(vqx, _mm_loadu_ps(cx + j));
              const __m128 dy = _mm_sub_ps(vqy, _mm_loadu_ps(cy + j));
              const __m128 steep =
                  _mm_cmpgt_ps(_mm_mul_ps(dz, dz),
                               _mm_mul_ps(vt, _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy))));
              const int bits = _mm_movemask_ps(_mm_and_ps(steep, kLaneMasks[valid]));
              pairs_tested += kBitCount[valid];
              if (bits != 0) {
                pairs_compatible += kBitCount[bits];
                found = true;
                break;
              }
            }
          } else  // one at a time (lanes capped to 1)
#endif
          {
            for (int j = j_hi - 1; j >= j_lo; --j) {
              bool window;
              ++pairs_tested;
              if (pair_at(k, j, false, window)) {
                ++pairs_compatible;
                found = true;
                break;
              }
            }
          }
        }
        if (found) upper_hit[k] = -1;
      }
    }
    for (int k = 0; k < m; ++k) {
      if ((upper_hit[k] | lower_hit[k]) == 0) continue;
      const int i = grow[column[k].index] * width + c;
      obstacle[i] = 1;
      raised[i] = upper_hit[k] != 0;
    }
  }
  out.stats.pairs_compatible = pairs_compatible;
  out.stats.pairs_tested = pairs_tested;
  return out;
}

// The definition: every pair of valid points of each column, tested with the same float
// arithmetic.
ColumnPairs FindColumnPairsBruteForce(const internal::LevelPoints& level, const PairTest& test,
                                      int width, int height) {
  const int n = width * height;
  ColumnPairs out{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0), {}};
  for (int c = 0; c < width; ++c) {
    for (int i = c; i < n; i += width) {
      if (std::isnan(level.z[i])) continue;
      for (int j = i + width; j < n; j += width) {
        if (std::isnan(level.z[j])) continue;
        ++out.stats.pairs_tested;
        const bool j_above = level.z[j] > level.z[i];
        const int lo = j_above ? i : j, up = j_above ? j : i;
        if (!test(level.x[up] - level.x[lo], level.y[up] - level.y[lo],
                  level.z[up] - level.z[lo])) {
          continue;
        }
        ++out.stats.pairs_compatible;
        out.obstacle[lo] = out.obstacle[up] = 1;
        out.raised[up] = 1;
      }
    }
  }
  return out;
}

// Bit j set when mask[j] is not 0, for j < count <= 64 (the bits above are 0).
std::uint64_t MaskBits(const std::uint8_t* mask, int count) {
  std::uint64_t bits = 0;
  int j = 0;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  for (; j + 16 <= count; j += 16) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(mask + j));
    const auto clear = static_cast<std::uint64_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, zero)));
    bits |= (~clear & 0xffff) << j;
  }
#endif
  for (; j < count; ++j) bits |= static_cast<std::uint64_t>(mask[j] != 0) << j;
  return bits;
}

// Blob colouring of the obstacle mask (8-connected), blob-area rejection, then the same
// assembly as the cone detector. The mask is coloured by runs: each row's runs of obstacle
// pixels are joined to the runs of the row above that touch them, corners included. A
// blob's representative is its first pixel in row-major order (the first pixel of its
// first run), as a pixel-wise union-find with the smallest root gives.
Detection Blobs(const RangeImage& image, const internal::LevelPoints& level,
                const ColumnPairs& pairs, const ColumnConfig& config, float min_height) {
  const int n = image.size(), width = image.width(), height = image.height();
  const std::vector<std::uint8_t>& obstacle = pairs.obstacle;
  struct Run {
    int begin, end;  // pixels, in one row
  };
  std::vector<Run> runs;
  std::vector<int> row_start(height + 1, 0);  // row r's runs: [row_start[r], row_start[r + 1])
  // Each row 64 pixels at a time as the bits of a word, a run's ends where a bit differs
  // from the one before it: no branch per pixel.
  for (int row = 0; row < height; ++row) {
    const int first = row * width;
    const std::uint8_t* mask = obstacle.data() + first;
    int begin = -1;          // the open run's first column, or -1
    std::uint64_t last = 0;  // the bit before the word
    for (int c0 = 0; c0 < width; c0 += 64) {
      const std::uint64_t bits = MaskBits(mask + c0, std::min(64, width - c0));
      for (std::uint64_t ends = bits ^ ((bits << 1) | last); ends != 0; ends &= ends - 1) {
        const int c = c0 + __builtin_ctzll(ends);
        if (begin < 0) {
          begin = c;
        } else {
          runs.push_back({first + begin, first + c});
          begin = -1;
        }
      }
      last = bits >> 63;
    }
    if (begin >= 0) runs.push_back({first + begin, first + width});
    row_start[row + 1] = static_cast<int>(runs.size());
  }
  // Runs of the row above touch a run when they reach from its column begin - 1 to end.
  internal::UnionFind blobs(static_cast<int>(runs.size()));  // roots: each blob's first run
  for (int row = 1; row < height; ++row) {
    const int above = (row - 1) * width, here = row * width;
    int a = row_start[row - 1];
    for (int r = row_start[row]; r < row_start[row + 1]; ++r) {
      const int begin = runs[r].begin - here, end = runs[r].end - here;
      while (a < row_start[row] && runs[a].end - above < begin) ++a;
      for (int b = a; b < row_start[row] && runs[b].begin - above <= end; ++b) blobs.Union(r, b);
    }
  }
  std::vector<std::int32_t> component(n, -1), area(runs.size(), 0);
  for (int r = 0; r < static_cast<int>(runs.size()); ++r) {
    area[blobs.Find(r)] += runs[r].end - runs[r].begin;
  }
  for (int r = 0; r < static_cast<int>(runs.size()); ++r) {
    const int root = blobs.Find(r);
    if (area[root] < config.min_blob_pixels) continue;
    std::fill(component.begin() + runs[r].begin, component.begin() + runs[r].end,
              runs[root].begin);
  }
  return internal::BuildDetection(image, level, std::move(component), pairs.raised, min_height,
                                  pairs.stats);
}

// DetectColumns (fast = true) and DetectColumnsBruteForce.
Expected<Detection> Columns(const RangeImage& image, const ColumnConfig& config, bool fast) {
  if (Status s = config.Validate(); !s) return s.error();
  // Returns nearer than min_range are holes from here on: only the level points are read
  // (and the image's ranges of segment points, which are none of them).
  const internal::LevelPoints level(image, 1, config.min_range_m);
  const PairTest test(PairParameters(config));
  const ColumnPairs pairs = fast ? FindColumnPairs(level, test, image.width(), image.height())
                                 : FindColumnPairsBruteForce(level, test, image.width(),
                                                             image.height());
  return Blobs(image, level, pairs, config, test.min_height);
}

}  // namespace

Expected<Detection> DetectColumns(const RangeImage& image, const ColumnConfig& config) {
  return Columns(image, config, true);
}

Expected<Detection> DetectColumnsBruteForce(const RangeImage& image, const ColumnConfig& config) {
  return Columns(image, config, false);
}

}  // namespace cairn::od
