#include "pair_search.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <type_traits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cairn/od/parallel.hpp"
#include "simd.hpp"

namespace cairn::od::internal {

namespace {

// FindCandidates' rings: for k = 0..rings, v is dilated (3 x 3, the maximum for kMax, else the
// minimum) k times, and bound becomes the running max of v - need(k) (kMax) or min of
// v + need(k). Leaves v dilated.
template <bool kMax, class Need>
void RingBounds(std::vector<float>& v, int nx, int ny, int rings, const Need& need,
                std::vector<float>& bound) {
  const auto pick = [](float a, float b) { return kMax ? std::max(a, b) : std::min(a, b); };
  std::vector<float> tmp(v.size());
  for (int k = 0; k <= rings; ++k) {
    if (k > 0) {  // along rows into tmp, along columns back
      for (int y = 0; y < ny; ++y) {
        const float* row = &v[static_cast<std::size_t>(y) * nx];
        float* out = &tmp[static_cast<std::size_t>(y) * nx];
        out[0] = nx > 1 ? pick(row[0], row[1]) : row[0];
        for (int x = 1; x + 1 < nx; ++x) out[x] = pick(pick(row[x - 1], row[x]), row[x + 1]);
        if (nx > 1) out[nx - 1] = pick(row[nx - 2], row[nx - 1]);
      }
      for (int y = 0; y < ny; ++y) {
        const float* mid = &tmp[static_cast<std::size_t>(y) * nx];
        const float* above = y > 0 ? mid - nx : mid;
        const float* below = y + 1 < ny ? mid + nx : mid;
        float* out = &v[static_cast<std::size_t>(y) * nx];
        for (int x = 0; x < nx; ++x) out[x] = pick(pick(above[x], mid[x]), below[x]);
      }
    }
    const float d = need(k);
    for (std::size_t j = 0; j < v.size(); ++j) {
      bound[j] = kMax ? std::max(bound[j], v[j] - d) : std::min(bound[j], v[j] + d);
    }
  }
}

}  // namespace

Candidates FindCandidates(const LevelPoints& level, const PairTest& test, int threads) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int n = static_cast<int>(level.z.size());
  Candidates c{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0)};
  // The passes over the points run in kParts parts whatever the threads; everything they
  // gather is a count, a minimum or a maximum, so the result is the same on any threads.
  constexpr int kParts = 8;
  const auto part_begin = [n](int k) { return PartBegin(n, k, kParts); };
  // The valid points' extent, which the level points took as they were stored.
  const float x_lo = level.x_min, x_hi = level.x_max, y_lo = level.y_min, y_hi = level.y_max;
  const int valid = level.valid;
  if (!(x_lo <= x_hi)) return c;
  // Cells of a quarter of the reach, at most 256 a side and at most about 2 sqrt(points) a
  // side (so that a small cloud spread wide does not pay for a grid far larger than itself);
  // rings of cells around a point's cell up to the reach. Any side keeps the filter exact:
  // coarser cells only keep more candidates.
  const double tan_theta = std::sqrt(static_cast<double>(test.tan2_theta));
  const double reach = test.max_height / tan_theta;
  const double extent = std::max<double>(x_hi - x_lo, y_hi - y_lo);
  const double per_side =
      std::min(255.0, std::max(1.0, 2.0 * std::sqrt(static_cast<double>(valid))));
  const double side = std::max(reach / 4.0, extent / per_side) * (1.0 + 1e-6);
  const int nx = static_cast<int>((x_hi - x_lo) / side) + 1;
  const int ny = static_cast<int>((y_hi - y_lo) / side) + 1;
  const int rings = std::max(1, static_cast<int>(std::ceil(reach / side)));
  const std::size_t cells = static_cast<std::size_t>(nx) * ny;
  // Each point's cell (a hole gets cell 0, which always exists here), written by the first pass
  // below, so not filled first.
  std::vector<std::int32_t, DefaultInitAllocator<std::int32_t>> cell(n);
  // Each worker's highest and lowest point per cell, then the workers' together.
  // Rounding may put a point lying on a cell boundary in the neighbouring cell (off by far
  // less than a micrometre): the margin below covers it.
  const double per_m = 1.0 / side;
  const int workers = std::clamp(ThreadCount(threads), 1, kParts);
  std::vector<std::vector<float>> highs(workers), lows(workers);
  ParallelFor(
      kParts, workers,
      [&](int worker, int k) {
        std::vector<float>& high = highs[worker];
        std::vector<float>& low = lows[worker];
        if (high.empty()) {
          high.assign(cells, -kInf);
          low.assign(cells, kInf);
        }
        // Locals, not the captures: the stores (floats to the cells' bounds, integers to
        // cells_of) may alias what a capture refers to, which would then be loaded again for
        // every point.
        const float* x = level.x.data();
        const float* y = level.y.data();
        const float* z = level.z.data();
        std::int32_t* cells_of = cell.data();
        float* hi = high.data();
        float* lo = low.data();
        const float x0 = x_lo, y0 = y_lo;
        const double scale = per_m;
        const int cols = nx, rows = ny;
        const int end = part_begin(k + 1);
        for (int i = part_begin(k); i < end; ++i) {
          const float zi = z[i];
          if (std::isnan(zi)) {
            cells_of[i] = 0;  // any cell: the last pass compares a NaN height as false
            continue;
          }
          const int cx = std::clamp(static_cast<int>((x[i] - x0) * scale), 0, cols - 1);
          const int cy = std::clamp(static_cast<int>((y[i] - y0) * scale), 0, rows - 1);
          const std::int32_t j = cy * cols + cx;
          cells_of[i] = j;
          hi[j] = std::max(hi[j], zi);
          lo[j] = std::min(lo[j], zi);
        }
      },
      1);
  std::vector<float> high, low;
  for (int w = 0; w < workers; ++w) {
    if (highs[w].empty()) continue;  // a worker that took no part
    if (high.empty()) {
      high = std::move(highs[w]);
      low = std::move(lows[w]);
      continue;
    }
    for (std::size_t j = 0; j < cells; ++j) {
      high[j] = std::max(high[j], highs[w][j]);
      low[j] = std::min(low[j], lows[w][j]);
    }
  }
  // Ring k: the highest / lowest point within k cells (Chebyshev), by repeated 3x3
  // dilation; a point there lies at least (k - 1) cells away horizontally, so a partner
  // there must be max(HT, (k - 1) side tan(theta)) above or below. A margin of 1 mm covers
  // the rounding of cells and heights.
  constexpr float kMargin = 1e-3f;
  std::vector<std::uint8_t>& lower = c.lower;
  std::vector<std::uint8_t>& upper = c.upper;
  // Per cell, over the rings: a point there may be a lower point when it lies below
  // `below`, an upper point when above `above`; the first from the highest points, the
  // second from the lowest, side by side.
  std::vector<float> below(high.size(), -kInf), above(high.size(), kInf);
  const auto need = [&](int k) {
    return static_cast<float>(
               std::max<double>(test.min_height, std::max(0, k - 1) * side * tan_theta)) -
           kMargin;
  };
  ParallelFor(
      2, threads,
      [&](int item) {
        if (item == 0) {
          RingBounds<true>(high, nx, ny, rings, need, below);
        } else {
          RingBounds<false>(low, nx, ny, rings, need, above);
        }
      },
      1);
  ParallelFor(
      kParts, threads,
      [&](int k) {
        // Raw pointers and a local bound: the byte stores may alias anything, which would
        // reload the vectors' data and the bound on every step.
        const std::int32_t* cells_of = cell.data();
        const float* z = level.z.data();
        const float* lo = below.data();
        const float* hi = above.data();
        std::uint8_t* is_lower = lower.data();
        std::uint8_t* is_upper = upper.data();
        const int end = part_begin(k + 1);
        // A hole's NaN height makes it neither lower nor upper.
        for (int i = part_begin(k); i < end; ++i) {
          const std::int32_t j = cells_of[i];
          is_lower[i] = z[i] < lo[j];
          is_upper[i] = z[i] > hi[j];
        }
      },
      1);
  return c;
}

// The two parts of a split block's points (PointTree::Split), each in pixel order.
struct PointTree::SplitParts {
  float x[2][kMaxBlockPixels], y[2][kMaxBlockPixels], z[2][kMaxBlockPixels];
  std::int32_t at[2][kMaxBlockPixels];
  int count[2];
  float lo[2][3], hi[2][3];
};

namespace {

#if defined(CAIRN_OD_WIDE_VECTORS)
// From each point's count of points below it (rank[0, m), m <= 64) to its rank: without ties
// the counts are the ranks (each from 0 to m - 1 once); the points of one height all counted the
// same b points below them (points of different heights count differently), and take b, b + 1,
// ... in index order.
void TakeTiesInIndexOrder(int* rank, int m) {
  std::uint64_t seen = 0;
  for (int k = 0; k < m; ++k) seen |= std::uint64_t{1} << rank[k];
  if (seen == (m < 64 ? (std::uint64_t{1} << m) - 1 : ~std::uint64_t{0})) return;
  std::uint8_t taken[PointTree::kMaxLeafPoints] = {};
  for (int k = 0; k < m; ++k) rank[k] += taken[rank[k]]++;
}

// Each point's rank among zs[0, m) by ascending height, ties in index order (m <= 64, zs
// padded to a multiple of eight), as PointTree::Leaf's scalar loop ranks them, eight points at
// a time (AVX2): each point's count of points below it, summed in a register, then the ties
// taken in index order.
__attribute__((target("avx2"))) void RanksAvx2(const float* zs, int m, int* rank) {
  const int chunks = (m + 7) / 8;
  __m256 z[8];
  for (int c = 0; c < chunks; ++c) z[c] = _mm256_loadu_ps(zs + 8 * c);
  for (int k = 0; k < m; ++k) {
    const __m256 zk = _mm256_set1_ps(zs[k]);
    __m256i below = _mm256_setzero_si256();  // all ones (-1) for each point below
    for (int c = 0; c < chunks; ++c) {
      below = _mm256_sub_epi32(below, _mm256_castps_si256(_mm256_cmp_ps(z[c], zk, _CMP_LT_OQ)));
    }
    __m128i sum = _mm_add_epi32(_mm256_castsi256_si128(below), _mm256_extracti128_si256(below, 1));
    sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(1, 0, 3, 2)));
    sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(2, 3, 0, 1)));
    rank[k] = _mm_cvtsi128_si32(sum);
  }
  TakeTiesInIndexOrder(rank, m);
}
// RanksAvx2's ranks sixteen points at a time (AVX-512F; zs padded to a multiple of sixteen,
// `rank` with room for as many): each lane counts the points below its own, one broadcast and
// one masked add per point, with no sum across lanes (on Zen 4 faster than the two compares,
// mask moves and population counts per point it replaces, BENCHMARKS.md); then the ties taken
// in index order.
__attribute__((target("avx512f"))) void RanksAvx512(const float* zs, int m, int* rank) {
  const int chunks = (m + 15) / 16;
  __m512 z[4];
  __m512i below[4];
  for (int c = 0; c < chunks; ++c) {
    z[c] = _mm512_loadu_ps(zs + 16 * c);
    below[c] = _mm512_setzero_si512();
  }
  const __m512i one = _mm512_set1_epi32(1);
  for (int j = 0; j < m; ++j) {
    const __m512 zj = _mm512_set1_ps(zs[j]);
    for (int c = 0; c < chunks; ++c) {
      below[c] =
          _mm512_mask_add_epi32(below[c], _mm512_cmp_ps_mask(zj, z[c], _CMP_LT_OQ), below[c], one);
    }
  }
  for (int c = 0; c < chunks; ++c) _mm512_storeu_si512(rank + 16 * c, below[c]);
  TakeTiesInIndexOrder(rank, m);
}

CAIRN_OD_AVX512_KERNELS_BEGIN
// The least and the greatest of sixteen lanes (GCC 12's _mm512_reduce_min_ps warns of an
// uninitialised variable).
template <bool kMax>
__attribute__((target("avx512f"))) inline float Extreme16(__m512 v) {
  __m512 other = _mm512_shuffle_f32x4(v, v, _MM_SHUFFLE(1, 0, 3, 2));  // the other half
  v = kMax ? _mm512_max_ps(v, other) : _mm512_min_ps(v, other);
  other = _mm512_shuffle_f32x4(v, v, _MM_SHUFFLE(2, 3, 0, 1));  // the other quarter
  v = kMax ? _mm512_max_ps(v, other) : _mm512_min_ps(v, other);
  other = _mm512_permute_ps(v, _MM_SHUFFLE(1, 0, 3, 2));  // the other pair of lanes
  v = kMax ? _mm512_max_ps(v, other) : _mm512_min_ps(v, other);
  other = _mm512_permute_ps(v, _MM_SHUFFLE(2, 3, 0, 1));  // the other lane
  v = kMax ? _mm512_max_ps(v, other) : _mm512_min_ps(v, other);
  return _mm512_cvtss_f32(v);
}

// A box of points taken sixteen at a time (AVX-512F): each lane's bounds kept with masked minima
// and maxima in std::min's and std::max's operand order (a NaN never taken, the bound met first
// kept on a tie), then the lanes' together (Extreme16).
struct Box16 {
  __m512 lo[3], hi[3];
  __attribute__((target("avx512f"))) Box16() {
    for (int d = 0; d < 3; ++d) {
      lo[d] = _mm512_set1_ps(std::numeric_limits<float>::infinity());
      hi[d] = _mm512_set1_ps(-std::numeric_limits<float>::infinity());
    }
  }
  // The points of the lanes `take` of q (x, y, z).
  __attribute__((target("avx512f"))) void Add(__mmask16 take, const __m512* q) {
    for (int d = 0; d < 3; ++d) {
      lo[d] = _mm512_mask_min_ps(lo[d], take, q[d], lo[d]);
      hi[d] = _mm512_mask_max_ps(hi[d], take, q[d], hi[d]);
    }
  }
  // The box's bounds (infinite and empty when no point was added).
  __attribute__((target("avx512f"))) void Into(float* box_lo, float* box_hi) const {
    for (int d = 0; d < 3; ++d) {
      box_lo[d] = Extreme16<false>(lo[d]);
      box_hi[d] = Extreme16<true>(hi[d]);
    }
  }
};

// PointTree::Block's gathering of a block, sixteen pixels at a time (AVX-512F). The points of the
// pixels [r0, r1) x [c0, c1) that `mask` holds go, in pixel order, to xs, ys, zs (coordinates)
// and `at` (image indices). Each row's pixels are taken sixteen at a time: a compress of the
// lanes the mask holds, with no branch per pixel (the scalar loop's mispredicts on every pixel
// the mask leaves out). Their box goes to lo and hi: each bound the scalar loop's, but for the
// sign of a zero where +0 and -0 are both there. Returns how many.
__attribute__((target("avx512f,popcnt"))) int GatherBlockAvx512(
    const float* x, const float* y, const float* z, const std::uint8_t* mask, int width, int r0,
    int r1, int c0, int c1, float* xs, float* ys, float* zs, std::int32_t* at, float* lo,
    float* hi) {
  Box16 box;
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  int m = 0;
  for (int r = r0; r < r1; ++r) {
    for (int c = c0; c < c1; c += 16) {
      const int i0 = r * width + c, w = std::min(16, c1 - c);
      // The mask's bytes as bits: sixteen at once when the block's row has sixteen more columns,
      // else eight at once when it has eight, then one at a time. No byte past the block's
      // columns is read: they may be the image's last.
      unsigned bits = 0;
      int k = 0;
      if (w == 16) {
        const __m512i b =
            _mm512_cvtepu8_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(mask + i0)));
        bits = _mm512_test_epi32_mask(b, b);
        k = 16;
      } else if (w >= 8) {
        const __m512i b =
            _mm512_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(mask + i0)));
        bits = _mm512_test_epi32_mask(b, b);  // the upper eight bytes load as zero
        k = 8;
      }
      for (; k < w; ++k) bits |= static_cast<unsigned>(mask[i0 + k] != 0) << k;
      if (bits == 0) continue;
      const auto take = static_cast<__mmask16>(bits);
      // Masked loads: lanes not taken are not read.
      const __m512 q[3] = {_mm512_maskz_loadu_ps(take, x + i0), _mm512_maskz_loadu_ps(take, y + i0),
                           _mm512_maskz_loadu_ps(take, z + i0)};
      box.Add(take, q);
      CompressStore(xs + m, take, q[0]);
      CompressStore(ys + m, take, q[1]);
      CompressStore(zs + m, take, q[2]);
      CompressStore(at + m, take, _mm512_add_epi32(_mm512_set1_epi32(i0), lane));
      m += __builtin_popcount(bits);
    }
  }
  box.Into(lo, hi);
  return m;
}

// PointTree::Split's partition, sixteen points at a time (AVX-512F): the points [0, m) of x, y,
// z, at go, in their order, to part 0 of q when their coordinate `axis` is below `mid` (when
// `by_index`: the first m / 2 of them) and to part 1 otherwise, each part's box with them
// (Box16).
__attribute__((target("avx512f,popcnt"))) void SplitAvx512(const float* x, const float* y,
                                                           const float* z, const std::int32_t* at,
                                                           int m, int axis, float mid,
                                                           bool by_index,
                                                           PointTree::SplitParts& q) {
  Box16 box[2];
  const __m512i lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  q.count[0] = q.count[1] = 0;
  for (int k = 0; k < m; k += 16) {
    const auto valid = static_cast<__mmask16>(m - k >= 16 ? 0xffff : (1u << (m - k)) - 1);
    const __m512 p[3] = {_mm512_maskz_loadu_ps(valid, x + k), _mm512_maskz_loadu_ps(valid, y + k),
                         _mm512_maskz_loadu_ps(valid, z + k)};
    const __m512i index = _mm512_maskz_loadu_epi32(valid, at + k);
    const __mmask16 first =
        by_index ? _mm512_cmplt_epi32_mask(_mm512_add_epi32(_mm512_set1_epi32(k), lane),
                                           _mm512_set1_epi32(m / 2))
                 : _mm512_cmp_ps_mask(p[axis], _mm512_set1_ps(mid), _CMP_LT_OQ);
    const __mmask16 take[2] = {static_cast<__mmask16>(valid & first),
                               static_cast<__mmask16>(valid & ~first)};
    for (int part = 0; part < 2; ++part) {
      const int c = q.count[part];
      CompressStore(q.x[part] + c, take[part], p[0]);
      CompressStore(q.y[part] + c, take[part], p[1]);
      CompressStore(q.z[part] + c, take[part], p[2]);
      CompressStore(q.at[part] + c, take[part], index);
      box[part].Add(take[part], p);
      q.count[part] = c + __builtin_popcount(take[part]);
    }
  }
  box[0].Into(q.lo[0], q.hi[0]);
  box[1].Into(q.lo[1], q.hi[1]);
}
CAIRN_OD_AVX512_KERNELS_END
#endif

}  // namespace

PointTree::PointTree(const LevelPoints& level, const std::vector<std::uint8_t>& mask, int width,
                     int height, int block_rows, int block_cols, bool per_column) {
  block_rows = std::clamp(block_rows, 1, kMaxBlockPixels);
  block_cols = std::clamp(block_cols, 1, kMaxBlockPixels / block_rows);
  const std::size_t n = static_cast<std::size_t>(width) * height;
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) count += mask[i] != 0;
  // Stored in place as the leaves come; the padding after them.
  x.assign(count + kPadding, 0.0f);
  y.assign(count + kPadding, 0.0f);
  z.assign(count + kPadding, std::numeric_limits<float>::infinity());
  pixel.assign(count, 0);
  if (per_column) {
    for (int c = 0; c < width; ++c) {
      roots.push_back(Build(level, mask, width, 0, height, c, c + 1, block_rows, 1));
    }
  } else {
    roots.push_back(Build(level, mask, width, 0, height, 0, width, block_rows, block_cols));
  }
}

// Builds the subtree of pixels [r0, r1) x [c0, c1); returns its node, or -1 when it holds no
// point. A node with one non-empty half is that half.
std::int32_t PointTree::Build(const LevelPoints& level, const std::vector<std::uint8_t>& mask,
                              int width, int r0, int r1, int c0, int c1, int block_rows,
                              int block_cols) {
  const int rows = r1 - r0, cols = c1 - c0;
  if (rows <= block_rows && cols <= block_cols) return Block(level, mask, width, r0, r1, c0, c1);
  // Split the longer side, in units of blocks, at a block boundary. Children first, so that
  // a node with one non-empty half can be that half.
  const bool split_rows =
      (rows + block_rows - 1) / block_rows > (cols + block_cols - 1) / block_cols;
  std::int32_t a, b;
  if (split_rows) {
    const int half = ((rows + block_rows - 1) / block_rows + 1) / 2 * block_rows;
    a = Build(level, mask, width, r0, r0 + half, c0, c1, block_rows, block_cols);
    b = Build(level, mask, width, r0 + half, r1, c0, c1, block_rows, block_cols);
  } else {
    const int half = ((cols + block_cols - 1) / block_cols + 1) / 2 * block_cols;
    a = Build(level, mask, width, r0, r1, c0, c0 + half, block_rows, block_cols);
    b = Build(level, mask, width, r0, r1, c0 + half, c1, block_rows, block_cols);
  }
  if (a < 0 || b < 0) return a >= 0 ? a : b;
  return Join(a, b);
}

// The block of pixels [r0, r1) x [c0, c1) as a subtree (Split), or -1 when it holds no point. Not
// inlined: its arrays would sit in every frame of Build's recursion.
__attribute__((noinline)) std::int32_t PointTree::Block(const LevelPoints& level,
                                                        const std::vector<std::uint8_t>& mask,
                                                        int width, int r0, int r1, int c0, int c1) {
  // The block's points in pixel order, and their box.
  float xs[kMaxBlockPixels], ys[kMaxBlockPixels], zs[kMaxBlockPixels];
  std::int32_t at[kMaxBlockPixels];
  constexpr float kInf = std::numeric_limits<float>::infinity();
  float lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  int m = 0;
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (VectorLanes() == 16) {
    m = GatherBlockAvx512(level.x.data(), level.y.data(), level.z.data(), mask.data(), width, r0,
                          r1, c0, c1, xs, ys, zs, at, lo, hi);
  } else
#endif
  {
    for (int r = r0; r < r1; ++r) {
      for (int c = c0; c < c1; ++c) {
        const int i = r * width + c;
        if (!mask[i]) continue;
        const float qx = level.x[i], qy = level.y[i], qz = level.z[i];
        xs[m] = qx;
        ys[m] = qy;
        zs[m] = qz;
        at[m++] = i;
        ExtendBox(lo, hi, qx, qy, qz);
      }
    }
  }
  if (m == 0) return -1;
  SplitParts parts;
  return Split(xs, ys, zs, at, m, lo, hi, parts);
}

// The m points xs, ys, zs, at (in pixel order, box lo..hi) as a subtree: one leaf when they fit
// in one, else two subtrees, split at the middle of the box's longest side. (All of them fall
// on one side only when that side is at most one float step long, as when the points coincide:
// then they are partitioned again, the first half of them and the rest.) `parts` is scratch; the
// points are split in place, so that no level keeps scratch of its own.
std::int32_t PointTree::Split(float* xs, float* ys, float* zs, std::int32_t* at, int m,
                              const float* lo, const float* hi, SplitParts& parts) {
  if (m <= kMaxLeafPoints) return Leaf(xs, ys, zs, at, m, lo, hi);
  int axis = 0;
  for (int d = 1; d < 3; ++d) {
    if (hi[d] - lo[d] > hi[axis] - lo[axis]) axis = d;
  }
  const float* key = axis == 0 ? xs : axis == 1 ? ys : zs;
  const float mid = lo[axis] + 0.5f * (hi[axis] - lo[axis]);
  const auto partition = [&](bool by_index) {
#if defined(CAIRN_OD_WIDE_VECTORS)
    if (VectorLanes() == 16) {
      SplitAvx512(xs, ys, zs, at, m, axis, mid, by_index, parts);
      return;
    }
#endif
    constexpr float kInf = std::numeric_limits<float>::infinity();
    for (int part = 0; part < 2; ++part) {
      int c = 0;
      float* l = parts.lo[part];
      float* h = parts.hi[part];
      for (int d = 0; d < 3; ++d) {
        l[d] = kInf;
        h[d] = -kInf;
      }
      for (int k = 0; k < m; ++k) {
        const bool first = by_index ? k < m / 2 : key[k] < mid;
        if (first != (part == 0)) continue;
        parts.x[part][c] = xs[k];
        parts.y[part][c] = ys[k];
        parts.z[part][c] = zs[k];
        parts.at[part][c++] = at[k];
        ExtendBox(l, h, xs[k], ys[k], zs[k]);
      }
      parts.count[part] = c;
    }
  };
  partition(false);
  if (parts.count[0] == 0 || parts.count[0] == m) partition(true);
  // Back in place, the first part first; the boxes kept for the two calls.
  const int first = parts.count[0];
  std::copy(parts.x[0], parts.x[0] + first, xs);
  std::copy(parts.y[0], parts.y[0] + first, ys);
  std::copy(parts.z[0], parts.z[0] + first, zs);
  std::copy(parts.at[0], parts.at[0] + first, at);
  std::copy(parts.x[1], parts.x[1] + m - first, xs + first);
  std::copy(parts.y[1], parts.y[1] + m - first, ys + first);
  std::copy(parts.z[1], parts.z[1] + m - first, zs + first);
  std::copy(parts.at[1], parts.at[1] + m - first, at + first);
  float box_lo[2][3], box_hi[2][3];
  std::memcpy(box_lo, parts.lo, sizeof box_lo);
  std::memcpy(box_hi, parts.hi, sizeof box_hi);
  const std::int32_t a = Split(xs, ys, zs, at, first, box_lo[0], box_hi[0], parts);
  const std::int32_t b =
      Split(xs + first, ys + first, zs + first, at + first, m - first, box_lo[1], box_hi[1], parts);
  return Join(a, b);
}

// The m <= kMaxLeafPoints points xs, ys, zs, at (in pixel order, box lo..hi) as a leaf: each
// stored at its rank by ascending height (ties in pixel order, as a stable sort has them),
// counted without a branch: cheaper than sorting them, whose every step the processor
// mispredicts.
std::int32_t PointTree::Leaf(const float* xs, const float* ys, const float* zs,
                             const std::int32_t* at, int m, const float* lo, const float* hi) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // The heights padded for the widest loads.
  float heights[kMaxLeafPoints + 15];
  std::copy(zs, zs + m, heights);
  int ranks[kMaxLeafPoints];
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (VectorLanes() == 16) {
    for (int k = m; k < ((m + 15) & ~15); ++k) heights[k] = kInf;
    RanksAvx512(heights, m, ranks);
  } else if (VectorLanes() == 8) {
    for (int k = m; k < ((m + 7) & ~7); ++k) heights[k] = kInf;
    RanksAvx2(heights, m, ranks);
  } else
#endif
  {
    for (int k = 0; k < m; ++k) {
      const float zk = heights[k];
      int rank = 0;
      for (int j = 0; j < k; ++j) rank += heights[j] <= zk;
      for (int j = k + 1; j < m; ++j) rank += heights[j] < zk;
      ranks[k] = rank;
    }
  }
  for (int k = 0; k < m; ++k) {
    const int to = stored_ + ranks[k];
    x[to] = xs[k];
    y[to] = ys[k];
    z[to] = zs[k];
    pixel[to] = at[k];
  }
  Node leaf{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}, stored_, stored_ + m, {-1, -1}, -1};
  stored_ += m;
  nodes.push_back(leaf);
  return static_cast<std::int32_t>(nodes.size()) - 1;
}

// The parent of nodes a and b, stored one after the other.
std::int32_t PointTree::Join(std::int32_t a, std::int32_t b) {
  Node node;
  const Node& na = nodes[a];
  const Node& nb = nodes[b];
  for (int k = 0; k < 3; ++k) {
    node.lo[k] = std::min(na.lo[k], nb.lo[k]);
    node.hi[k] = std::max(na.hi[k], nb.hi[k]);
  }
  node.begin = na.begin;
  node.end = nb.end;
  node.child[0] = a;
  node.child[1] = b;
  node.parent = -1;
  const auto self = static_cast<std::int32_t>(nodes.size());
  nodes.push_back(node);
  nodes[a].parent = nodes[b].parent = self;
  return self;
}

namespace {

enum Verdict { kReject, kMixed, kAccept };

// |gap| between two intervals, computed as the pair test computes |dx| (0 when they meet).
inline float Gap(float a_lo, float a_hi, float b_lo, float b_hi) {
  if (b_lo > a_hi) return b_lo - a_hi;
  if (a_lo > b_hi) return a_lo - b_hi;
  return 0.0f;
}

// Largest |b - a| over the two intervals, as the pair test rounds it.
inline float Reach(float a_lo, float a_hi, float b_lo, float b_hi) {
  return std::max(std::abs(b_hi - a_lo), std::abs(b_lo - a_hi));
}

// The pair test over all (a in box A, b in box B) with b the upper point. Each bound is the
// pair test's float expression at the extreme coordinates; rounding is monotonic, so the
// verdict holds for every pair the boxes contain.
inline Verdict Classify(const float* a_lo, const float* a_hi, const float* b_lo, const float* b_hi,
                        const PairTest& t) {
  const float dz_hi = b_hi[2] - a_lo[2];
  const float dz_lo = b_lo[2] - a_hi[2];
  if (!(dz_hi > t.min_height) || !(dz_lo < t.max_height)) return kReject;
  const float dz_best = std::min(dz_hi, t.max_height);
  const float gx = Gap(a_lo[0], a_hi[0], b_lo[0], b_hi[0]);
  const float gy = Gap(a_lo[1], a_hi[1], b_lo[1], b_hi[1]);
  if (!(dz_best * dz_best > t.tan2_theta * (gx * gx + gy * gy))) return kReject;
  if (!(dz_lo > t.min_height) || !(dz_hi < t.max_height)) return kMixed;
  const float rx = Reach(a_lo[0], a_hi[0], b_lo[0], b_hi[0]);
  const float ry = Reach(a_lo[1], a_hi[1], b_lo[1], b_hi[1]);
  return dz_lo * dz_lo > t.tan2_theta * (rx * rx + ry * ry) ? kAccept : kMixed;
}

#if defined(__SSE2__)
// Classify's rejection, four pairs of boxes at once (lower box a, upper box b, each a lane's
// lo / hi per coordinate; a point is a box with lo = hi), with its float operations in its
// order: the lanes it does not reject.
inline __m128 NotRejected(const __m128* a_lo, const __m128* a_hi, const __m128* b_lo,
                          const __m128* b_hi, const PairTest& t) {
  const __m128 ht = _mm_set1_ps(t.min_height), hmax = _mm_set1_ps(t.max_height);
  const __m128 dz_hi = _mm_sub_ps(b_hi[2], a_lo[2]), dz_lo = _mm_sub_ps(b_lo[2], a_hi[2]);
  const __m128 heights = _mm_and_ps(_mm_cmpgt_ps(dz_hi, ht), _mm_cmplt_ps(dz_lo, hmax));
  const __m128 dz_best = _mm_min_ps(dz_hi, hmax);
  // Gap: the one positive of (b low - a high, a low - b high), else 0.
  const __m128 zero = _mm_setzero_ps();
  const __m128 gx =
      _mm_max_ps(_mm_max_ps(_mm_sub_ps(b_lo[0], a_hi[0]), _mm_sub_ps(a_lo[0], b_hi[0])), zero);
  const __m128 gy =
      _mm_max_ps(_mm_max_ps(_mm_sub_ps(b_lo[1], a_hi[1]), _mm_sub_ps(a_lo[1], b_hi[1])), zero);
  return _mm_and_ps(heights,
                    _mm_cmpgt_ps(_mm_mul_ps(dz_best, dz_best),
                                 _mm_mul_ps(_mm_set1_ps(t.tan2_theta),
                                            _mm_add_ps(_mm_mul_ps(gx, gx), _mm_mul_ps(gy, gy)))));
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
CAIRN_OD_AVX512_KERNELS_BEGIN
// Search::Hits eight (AVX2) and sixteen (AVX-512F) packed points at a time, with its float
// operations in its order: the bits of the points in p's cone, and of those HT..Hmax above p
// (`in_window`). The points are padded to a multiple of sixteen.
__attribute__((target("avx2"))) std::uint64_t HitsAvx2(const float* qx, const float* qy,
                                                       const float* qz, int count, const float* p,
                                                       const PairTest& t,
                                                       std::uint64_t& in_window) {
  const __m256 px = _mm256_set1_ps(p[0]), py = _mm256_set1_ps(p[1]), pz = _mm256_set1_ps(p[2]);
  const __m256 vht = _mm256_set1_ps(t.min_height), vh = _mm256_set1_ps(t.max_height);
  const __m256 vt = _mm256_set1_ps(t.tan2_theta);
  std::uint64_t hits = 0, window_bits = 0;
  for (int k = 0; k < count; k += 8) {
    const __m256 dz = _mm256_sub_ps(_mm256_load_ps(qz + k), pz);
    const __m256 dx = _mm256_sub_ps(_mm256_load_ps(qx + k), px);
    const __m256 dy = _mm256_sub_ps(_mm256_load_ps(qy + k), py);
    const __m256 reach =
        _mm256_mul_ps(vt, _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)));
    const __m256 window =
        _mm256_and_ps(_mm256_cmp_ps(dz, vht, _CMP_GT_OQ), _mm256_cmp_ps(dz, vh, _CMP_LT_OQ));
    const __m256 in =
        _mm256_and_ps(window, _mm256_cmp_ps(_mm256_mul_ps(dz, dz), reach, _CMP_GT_OQ));
    window_bits |= static_cast<std::uint64_t>(_mm256_movemask_ps(window)) << k;
    hits |= static_cast<std::uint64_t>(_mm256_movemask_ps(in)) << k;
  }
  in_window = window_bits;
  return hits;
}

// NotRejected for eight pairs of boxes (lower a, upper b), with Classify's float operations in
// its order: the lanes it does not reject.
__attribute__((target("avx2"))) inline __m256 NotRejected8(const __m256* a_lo, const __m256* a_hi,
                                                           const __m256* b_lo, const __m256* b_hi,
                                                           const PairTest& t) {
  const __m256 ht = _mm256_set1_ps(t.min_height), hmax = _mm256_set1_ps(t.max_height);
  const __m256 dz_hi = _mm256_sub_ps(b_hi[2], a_lo[2]), dz_lo = _mm256_sub_ps(b_lo[2], a_hi[2]);
  const __m256 heights =
      _mm256_and_ps(_mm256_cmp_ps(dz_hi, ht, _CMP_GT_OQ), _mm256_cmp_ps(dz_lo, hmax, _CMP_LT_OQ));
  const __m256 dz_best = _mm256_min_ps(dz_hi, hmax);
  const __m256 zero = _mm256_setzero_ps();
  const __m256 gx = _mm256_max_ps(
      _mm256_max_ps(_mm256_sub_ps(b_lo[0], a_hi[0]), _mm256_sub_ps(a_lo[0], b_hi[0])), zero);
  const __m256 gy = _mm256_max_ps(
      _mm256_max_ps(_mm256_sub_ps(b_lo[1], a_hi[1]), _mm256_sub_ps(a_lo[1], b_hi[1])), zero);
  return _mm256_and_ps(
      heights,
      _mm256_cmp_ps(_mm256_mul_ps(dz_best, dz_best),
                    _mm256_mul_ps(_mm256_set1_ps(t.tan2_theta),
                                  _mm256_add_ps(_mm256_mul_ps(gx, gx), _mm256_mul_ps(gy, gy))),
                    _CMP_GT_OQ));
}

// The least and the greatest of eight lanes.
template <bool kMax>
__attribute__((target("avx2"))) inline float Extreme8(__m256 v) {
  const __m128 high = _mm256_extractf128_ps(v, 1);
  __m128 w = kMax ? _mm_max_ps(_mm256_castps256_ps128(v), high)
                  : _mm_min_ps(_mm256_castps256_ps128(v), high);
  __m128 other = _mm_shuffle_ps(w, w, _MM_SHUFFLE(1, 0, 3, 2));
  w = kMax ? _mm_max_ps(w, other) : _mm_min_ps(w, other);
  other = _mm_shuffle_ps(w, w, _MM_SHUFFLE(2, 3, 0, 1));
  w = kMax ? _mm_max_ps(w, other) : _mm_min_ps(w, other);
  return _mm_cvtss_f32(w);
}

// NearAvx512 eight points at a time (AVX2).
__attribute__((target("avx2"))) std::uint64_t NearAvx2(const float* x, const float* y,
                                                       const float* z, int count, const float* a_lo,
                                                       const float* a_hi, const PairTest& t,
                                                       float* lo, float* hi) {
  const __m256 box_lo[3] = {_mm256_set1_ps(a_lo[0]), _mm256_set1_ps(a_lo[1]),
                            _mm256_set1_ps(a_lo[2])};
  const __m256 box_hi[3] = {_mm256_set1_ps(a_hi[0]), _mm256_set1_ps(a_hi[1]),
                            _mm256_set1_ps(a_hi[2])};
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  const __m256 minus_inf = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
  __m256 x_lo = inf, y_lo = inf, z_lo = inf, x_hi = minus_inf, y_hi = minus_inf, z_hi = minus_inf;
  std::uint64_t near = 0;
  for (int j = 0; j < count; j += 8) {
    const __m256i in_leaf = FirstLanes8(count - j);
    const __m256 q[3] = {_mm256_maskload_ps(x + j, in_leaf), _mm256_maskload_ps(y + j, in_leaf),
                         _mm256_maskload_ps(z + j, in_leaf)};
    const __m256 kept =
        _mm256_and_ps(_mm256_castsi256_ps(in_leaf), NotRejected8(box_lo, box_hi, q, q, t));
    near |= static_cast<std::uint64_t>(_mm256_movemask_ps(kept)) << j;
    x_lo = _mm256_min_ps(x_lo, _mm256_blendv_ps(inf, q[0], kept));
    y_lo = _mm256_min_ps(y_lo, _mm256_blendv_ps(inf, q[1], kept));
    z_lo = _mm256_min_ps(z_lo, _mm256_blendv_ps(inf, q[2], kept));
    x_hi = _mm256_max_ps(x_hi, _mm256_blendv_ps(minus_inf, q[0], kept));
    y_hi = _mm256_max_ps(y_hi, _mm256_blendv_ps(minus_inf, q[1], kept));
    z_hi = _mm256_max_ps(z_hi, _mm256_blendv_ps(minus_inf, q[2], kept));
  }
  lo[0] = Extreme8<false>(x_lo);
  lo[1] = Extreme8<false>(y_lo);
  lo[2] = Extreme8<false>(z_lo);
  hi[0] = Extreme8<true>(x_hi);
  hi[1] = Extreme8<true>(y_hi);
  hi[2] = Extreme8<true>(z_hi);
  return near;
}

// ClassifyAvx512 eight lower points at a time (AVX2).
__attribute__((target("avx2"))) void ClassifyAvx2(const float* x, const float* y, const float* z,
                                                  int count, const float* b_lo, const float* b_hi,
                                                  const PairTest& t, std::uint64_t& keep,
                                                  std::uint64_t& accept) {
  const __m256 ht = _mm256_set1_ps(t.min_height), hmax = _mm256_set1_ps(t.max_height);
  const __m256 tan2 = _mm256_set1_ps(t.tan2_theta);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  const __m256 box_lo[3] = {_mm256_set1_ps(b_lo[0]), _mm256_set1_ps(b_lo[1]),
                            _mm256_set1_ps(b_lo[2])};
  const __m256 box_hi[3] = {_mm256_set1_ps(b_hi[0]), _mm256_set1_ps(b_hi[1]),
                            _mm256_set1_ps(b_hi[2])};
  for (int i = 0; i < count; i += 8) {
    const __m256i valid = FirstLanes8(count - i);
    const __m256 q[3] = {_mm256_maskload_ps(x + i, valid), _mm256_maskload_ps(y + i, valid),
                         _mm256_maskload_ps(z + i, valid)};
    const __m256 dz_hi = _mm256_sub_ps(box_hi[2], q[2]), dz_lo = _mm256_sub_ps(box_lo[2], q[2]);
    const __m256 kept =
        _mm256_and_ps(_mm256_castsi256_ps(valid), NotRejected8(q, q, box_lo, box_hi, t));
    const __m256 inside =
        _mm256_and_ps(_mm256_cmp_ps(dz_lo, ht, _CMP_GT_OQ), _mm256_cmp_ps(dz_hi, hmax, _CMP_LT_OQ));
    const __m256 rx = _mm256_max_ps(_mm256_andnot_ps(sign, _mm256_sub_ps(box_hi[0], q[0])),
                                    _mm256_andnot_ps(sign, _mm256_sub_ps(box_lo[0], q[0])));
    const __m256 ry = _mm256_max_ps(_mm256_andnot_ps(sign, _mm256_sub_ps(box_hi[1], q[1])),
                                    _mm256_andnot_ps(sign, _mm256_sub_ps(box_lo[1], q[1])));
    const __m256 all = _mm256_cmp_ps(
        _mm256_mul_ps(dz_lo, dz_lo),
        _mm256_mul_ps(tan2, _mm256_add_ps(_mm256_mul_ps(rx, rx), _mm256_mul_ps(ry, ry))),
        _CMP_GT_OQ);
    keep |= static_cast<std::uint64_t>(_mm256_movemask_ps(kept)) << i;
    accept |= static_cast<std::uint64_t>(
                  _mm256_movemask_ps(_mm256_and_ps(kept, _mm256_and_ps(inside, all))))
              << i;
  }
}

// PackAvx512 eight points at a time (AVX2): each register's chosen lanes permuted to its front
// and stored whole (the lanes after them are overwritten next; a store at c <= j ends within
// the leaf's 64 points); then sixteen padding points from c, which covers the multiple of
// sixteen (q* hold sixteen more than the points, qpixel none).
__attribute__((target("avx2,popcnt"))) int PackAvx2(const float* x, const float* y, const float* z,
                                                    const std::int32_t* pixel, int size,
                                                    std::uint64_t near, float* qx, float* qy,
                                                    float* qz, std::int32_t* qpixel) {
  int c = 0;
  for (int j = 0; j < size; j += 8) {
    const auto take = static_cast<unsigned>(near >> j) & 0xffu;
    if (take == 0) continue;
    const __m256i in = FirstLanes8(size - j);  // nothing read past the tree's points
    const __m256i to_front = ToFront8(take);
    _mm256_storeu_ps(qx + c, _mm256_permutevar8x32_ps(_mm256_maskload_ps(x + j, in), to_front));
    _mm256_storeu_ps(qy + c, _mm256_permutevar8x32_ps(_mm256_maskload_ps(y + j, in), to_front));
    _mm256_storeu_ps(qz + c, _mm256_permutevar8x32_ps(_mm256_maskload_ps(z + j, in), to_front));
    _mm256_storeu_si256(
        reinterpret_cast<__m256i*>(qpixel + c),
        _mm256_permutevar8x32_epi32(_mm256_maskload_epi32(pixel + j, in), to_front));
    c += __builtin_popcount(take);
  }
  const __m256 zero = _mm256_setzero_ps();
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  for (int k = 0; k < 16; k += 8) {
    _mm256_storeu_ps(qx + c + k, zero);
    _mm256_storeu_ps(qy + c + k, zero);
    _mm256_storeu_ps(qz + c + k, inf);
  }
  return c;
}

__attribute__((target("avx512f"))) std::uint64_t HitsAvx512(const float* qx, const float* qy,
                                                            const float* qz, int count,
                                                            const float* p, const PairTest& t,
                                                            std::uint64_t& in_window) {
  const __m512 px = _mm512_set1_ps(p[0]), py = _mm512_set1_ps(p[1]), pz = _mm512_set1_ps(p[2]);
  const __m512 vht = _mm512_set1_ps(t.min_height), vh = _mm512_set1_ps(t.max_height);
  const __m512 vt = _mm512_set1_ps(t.tan2_theta);
  std::uint64_t hits = 0, window_bits = 0;
  for (int k = 0; k < count; k += 16) {
    const __m512 dz = _mm512_sub_ps(_mm512_load_ps(qz + k), pz);
    const __m512 dx = _mm512_sub_ps(_mm512_load_ps(qx + k), px);
    const __m512 dy = _mm512_sub_ps(_mm512_load_ps(qy + k), py);
    const __m512 reach =
        _mm512_mul_ps(vt, _mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)));
    const __mmask16 window = static_cast<__mmask16>(_mm512_cmp_ps_mask(dz, vht, _CMP_GT_OQ) &
                                                    _mm512_cmp_ps_mask(dz, vh, _CMP_LT_OQ));
    const __mmask16 in = static_cast<__mmask16>(
        window & _mm512_cmp_ps_mask(_mm512_mul_ps(dz, dz), reach, _CMP_GT_OQ));
    window_bits |= static_cast<std::uint64_t>(window) << k;
    hits |= static_cast<std::uint64_t>(in) << k;
  }
  in_window = window_bits;
  return hits;
}

// Search::Pack sixteen points at a time (AVX-512F): the points of bits `near` of x, y, z,
// pixel [0, size) stored side by side from q_*, their count returned; then padding up to a
// multiple of sixteen (x = y = 0, z infinite).
__attribute__((target("avx512f,popcnt"))) int PackAvx512(const float* x, const float* y,
                                                         const float* z, const std::int32_t* pixel,
                                                         int size, std::uint64_t near, float* qx,
                                                         float* qy, float* qz,
                                                         std::int32_t* qpixel) {
  int c = 0;
  for (int j = 0; j < size; j += 16) {
    const auto take = static_cast<__mmask16>(near >> j);
    if (take == 0) continue;
    CompressStore(qx + c, take, _mm512_maskz_loadu_ps(take, x + j));
    CompressStore(qy + c, take, _mm512_maskz_loadu_ps(take, y + j));
    CompressStore(qz + c, take, _mm512_maskz_loadu_ps(take, z + j));
    CompressStore(qpixel + c, take, _mm512_maskz_loadu_epi32(take, pixel + j));
    c += __builtin_popcount(take);
  }
  const auto pad = static_cast<__mmask16>(((1u << ((16 - (c & 15)) & 15)) - 1));
  _mm512_mask_storeu_ps(qx + c, pad, _mm512_setzero_ps());
  _mm512_mask_storeu_ps(qy + c, pad, _mm512_setzero_ps());
  _mm512_mask_storeu_ps(qz + c, pad, _mm512_set1_ps(std::numeric_limits<float>::infinity()));
  return c;
}

// NotRejected for sixteen pairs of boxes (lower a, upper b), with Classify's float operations
// in its order: the lanes it does not reject.
__attribute__((target("avx512f"))) inline __mmask16 NotRejected16(const __m512* a_lo,
                                                                  const __m512* a_hi,
                                                                  const __m512* b_lo,
                                                                  const __m512* b_hi,
                                                                  const PairTest& t) {
  const __m512 ht = _mm512_set1_ps(t.min_height), hmax = _mm512_set1_ps(t.max_height);
  const __m512 dz_hi = _mm512_sub_ps(b_hi[2], a_lo[2]), dz_lo = _mm512_sub_ps(b_lo[2], a_hi[2]);
  const __mmask16 heights = static_cast<__mmask16>(_mm512_cmp_ps_mask(dz_hi, ht, _CMP_GT_OQ) &
                                                   _mm512_cmp_ps_mask(dz_lo, hmax, _CMP_LT_OQ));
  const __m512 dz_best = _mm512_min_ps(dz_hi, hmax);
  const __m512 zero = _mm512_setzero_ps();
  const __m512 gx = _mm512_max_ps(
      _mm512_max_ps(_mm512_sub_ps(b_lo[0], a_hi[0]), _mm512_sub_ps(a_lo[0], b_hi[0])), zero);
  const __m512 gy = _mm512_max_ps(
      _mm512_max_ps(_mm512_sub_ps(b_lo[1], a_hi[1]), _mm512_sub_ps(a_lo[1], b_hi[1])), zero);
  return static_cast<__mmask16>(
      heights &
      _mm512_cmp_ps_mask(_mm512_mul_ps(dz_best, dz_best),
                         _mm512_mul_ps(_mm512_set1_ps(t.tan2_theta),
                                       _mm512_add_ps(_mm512_mul_ps(gx, gx), _mm512_mul_ps(gy, gy))),
                         _CMP_GT_OQ));
}

// Search::NearLower sixteen points at a time: the bits of the points [0, count) of x, y, z
// that the box a_lo..a_hi (the lower leaf's) does not reject, and their box.
__attribute__((target("avx512f"))) std::uint64_t NearAvx512(const float* x, const float* y,
                                                            const float* z, int count,
                                                            const float* a_lo, const float* a_hi,
                                                            const PairTest& t, float* lo,
                                                            float* hi) {
  const __m512 box_lo[3] = {_mm512_set1_ps(a_lo[0]), _mm512_set1_ps(a_lo[1]),
                            _mm512_set1_ps(a_lo[2])};
  const __m512 box_hi[3] = {_mm512_set1_ps(a_hi[0]), _mm512_set1_ps(a_hi[1]),
                            _mm512_set1_ps(a_hi[2])};
  Box16 box;
  std::uint64_t near = 0;
  for (int j = 0; j < count; j += 16) {
    const auto in_leaf = static_cast<__mmask16>(count - j >= 16 ? 0xffff : (1 << (count - j)) - 1);
    const __m512 q[3] = {_mm512_maskz_loadu_ps(in_leaf, x + j),
                         _mm512_maskz_loadu_ps(in_leaf, y + j),
                         _mm512_maskz_loadu_ps(in_leaf, z + j)};
    const auto kept = static_cast<__mmask16>(in_leaf & NotRejected16(box_lo, box_hi, q, q, t));
    near |= static_cast<std::uint64_t>(kept) << j;
    box.Add(kept, q);
  }
  box.Into(lo, hi);
  return near;
}

// Search::ClassifyPoints sixteen lower points at a time: of the points [0, count) of x, y,
// z, `keep` those the box b_lo..b_hi does not reject, `accept` those it accepts.
__attribute__((target("avx512f"))) void ClassifyAvx512(const float* x, const float* y,
                                                       const float* z, int count, const float* b_lo,
                                                       const float* b_hi, const PairTest& t,
                                                       std::uint64_t& keep, std::uint64_t& accept) {
  const __m512 ht = _mm512_set1_ps(t.min_height), hmax = _mm512_set1_ps(t.max_height);
  const __m512 tan2 = _mm512_set1_ps(t.tan2_theta);
  const __m512 box_lo[3] = {_mm512_set1_ps(b_lo[0]), _mm512_set1_ps(b_lo[1]),
                            _mm512_set1_ps(b_lo[2])};
  const __m512 box_hi[3] = {_mm512_set1_ps(b_hi[0]), _mm512_set1_ps(b_hi[1]),
                            _mm512_set1_ps(b_hi[2])};
  for (int i = 0; i < count; i += 16) {
    const auto valid = static_cast<__mmask16>(count - i >= 16 ? 0xffff : (1 << (count - i)) - 1);
    const __m512 q[3] = {_mm512_maskz_loadu_ps(valid, x + i), _mm512_maskz_loadu_ps(valid, y + i),
                         _mm512_maskz_loadu_ps(valid, z + i)};
    const __m512 dz_hi = _mm512_sub_ps(box_hi[2], q[2]), dz_lo = _mm512_sub_ps(box_lo[2], q[2]);
    const auto kept = static_cast<__mmask16>(valid & NotRejected16(q, q, box_lo, box_hi, t));
    const auto inside = static_cast<__mmask16>(_mm512_cmp_ps_mask(dz_lo, ht, _CMP_GT_OQ) &
                                               _mm512_cmp_ps_mask(dz_hi, hmax, _CMP_LT_OQ));
    const __m512 rx = _mm512_max_ps(_mm512_abs_ps(_mm512_sub_ps(box_hi[0], q[0])),
                                    _mm512_abs_ps(_mm512_sub_ps(box_lo[0], q[0])));
    const __m512 ry = _mm512_max_ps(_mm512_abs_ps(_mm512_sub_ps(box_hi[1], q[1])),
                                    _mm512_abs_ps(_mm512_sub_ps(box_lo[1], q[1])));
    const __mmask16 all = _mm512_cmp_ps_mask(
        _mm512_mul_ps(dz_lo, dz_lo),
        _mm512_mul_ps(tan2, _mm512_add_ps(_mm512_mul_ps(rx, rx), _mm512_mul_ps(ry, ry))),
        _CMP_GT_OQ);
    keep |= static_cast<std::uint64_t>(kept) << i;
    accept |= static_cast<std::uint64_t>(kept & inside & all) << i;
  }
}
CAIRN_OD_AVX512_KERNELS_END
#endif

}  // namespace

void ClassifyByBox([[maybe_unused]] int lanes, const float* lx, const float* ly, const float* lz,
                   int count, const float* b_lo, const float* b_hi, const PairTest& test,
                   std::uint64_t& keep, std::uint64_t& accept) {
  int i = 0;
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (lanes == 16) {
    ClassifyAvx512(lx, ly, lz, count, b_lo, b_hi, test, keep, accept);
    return;
  }
  if (lanes == 8) {
    ClassifyAvx2(lx, ly, lz, count, b_lo, b_hi, test, keep, accept);
    return;
  }
#endif
#if defined(__SSE2__)
  // Four at a time, with Classify's float operations in its order.
  if (lanes >= 4) {
    const __m128 ht = _mm_set1_ps(test.min_height), hmax = _mm_set1_ps(test.max_height);
    const __m128 tan2 = _mm_set1_ps(test.tan2_theta);
    const __m128 sign = _mm_set1_ps(-0.0f);
    const __m128 box_lo[3] = {_mm_set1_ps(b_lo[0]), _mm_set1_ps(b_lo[1]), _mm_set1_ps(b_lo[2])};
    const __m128 box_hi[3] = {_mm_set1_ps(b_hi[0]), _mm_set1_ps(b_hi[1]), _mm_set1_ps(b_hi[2])};
    const __m128 bx_lo = box_lo[0], bx_hi = box_hi[0], by_lo = box_lo[1], by_hi = box_hi[1];
    for (; i + 4 <= count; i += 4) {
      const __m128 q[3] = {_mm_loadu_ps(lx + i), _mm_loadu_ps(ly + i), _mm_loadu_ps(lz + i)};
      const __m128 px = q[0], py = q[1];
      const __m128 dz_hi = _mm_sub_ps(box_hi[2], q[2]), dz_lo = _mm_sub_ps(box_lo[2], q[2]);
      const __m128 kept = NotRejected(q, q, box_lo, box_hi, test);
      const __m128 inside = _mm_and_ps(_mm_cmpgt_ps(dz_lo, ht), _mm_cmplt_ps(dz_hi, hmax));
      const __m128 rx = _mm_max_ps(_mm_andnot_ps(sign, _mm_sub_ps(bx_hi, px)),
                                   _mm_andnot_ps(sign, _mm_sub_ps(bx_lo, px)));
      const __m128 ry = _mm_max_ps(_mm_andnot_ps(sign, _mm_sub_ps(by_hi, py)),
                                   _mm_andnot_ps(sign, _mm_sub_ps(by_lo, py)));
      const __m128 all =
          _mm_cmpgt_ps(_mm_mul_ps(dz_lo, dz_lo),
                       _mm_mul_ps(tan2, _mm_add_ps(_mm_mul_ps(rx, rx), _mm_mul_ps(ry, ry))));
      keep |= static_cast<std::uint64_t>(_mm_movemask_ps(kept)) << i;
      accept |=
          static_cast<std::uint64_t>(_mm_movemask_ps(_mm_and_ps(kept, _mm_and_ps(inside, all))))
          << i;
    }
  }
#endif
  for (; i < count; ++i) {
    const float p[3] = {lx[i], ly[i], lz[i]};
    const Verdict v = Classify(p, p, b_lo, b_hi, test);
    keep |= static_cast<std::uint64_t>(v != kReject) << i;
    accept |= static_cast<std::uint64_t>(v == kAccept) << i;
  }
}

std::uint64_t NearBox([[maybe_unused]] int lanes, const float* ux, const float* uy, const float* uz,
                      int count, const float* a_lo, const float* a_hi, const PairTest& test,
                      float* lo, float* hi) {
  constexpr float kInfinity = std::numeric_limits<float>::infinity();
  std::uint64_t near = 0;
  int j = 0;
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (lanes == 16) return NearAvx512(ux, uy, uz, count, a_lo, a_hi, test, lo, hi);
  if (lanes == 8) return NearAvx2(ux, uy, uz, count, a_lo, a_hi, test, lo, hi);
#endif
#if defined(__SSE2__)
  if (lanes >= 4) {
    // Four at a time, with Classify's float operations in its order; the lanes past the leaf
    // are dropped. The box as four lanes' boxes, a lane not kept adding +-infinity.
    const __m128 box_lo[3] = {_mm_set1_ps(a_lo[0]), _mm_set1_ps(a_lo[1]), _mm_set1_ps(a_lo[2])};
    const __m128 box_hi[3] = {_mm_set1_ps(a_hi[0]), _mm_set1_ps(a_hi[1]), _mm_set1_ps(a_hi[2])};
    const __m128 inf = _mm_set1_ps(kInfinity), minus_inf = _mm_set1_ps(-kInfinity);
    const __m128 lane = _mm_set_ps(3.0f, 2.0f, 1.0f, 0.0f);
    __m128 x_lo = inf, y_lo = inf, z_lo = inf, x_hi = minus_inf, y_hi = minus_inf, z_hi = minus_inf;
    for (; j < count; j += 4) {
      const __m128 q[3] = {_mm_loadu_ps(ux + j), _mm_loadu_ps(uy + j), _mm_loadu_ps(uz + j)};
      const __m128 qx = q[0], qy = q[1], qz = q[2];
      const __m128 in_leaf = _mm_cmplt_ps(lane, _mm_set1_ps(static_cast<float>(count - j)));
      const __m128 kept = _mm_and_ps(NotRejected(box_lo, box_hi, q, q, test), in_leaf);
      near |= static_cast<std::uint64_t>(_mm_movemask_ps(kept)) << j;
      const auto pick = [&kept](__m128 v, __m128 otherwise) {
        return _mm_or_ps(_mm_and_ps(kept, v), _mm_andnot_ps(kept, otherwise));
      };
      x_lo = _mm_min_ps(x_lo, pick(qx, inf));
      y_lo = _mm_min_ps(y_lo, pick(qy, inf));
      z_lo = _mm_min_ps(z_lo, pick(qz, inf));
      x_hi = _mm_max_ps(x_hi, pick(qx, minus_inf));
      y_hi = _mm_max_ps(y_hi, pick(qy, minus_inf));
      z_hi = _mm_max_ps(z_hi, pick(qz, minus_inf));
    }
    const auto least = [](__m128 v) {
      v = _mm_min_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2)));
      return _mm_cvtss_f32(_mm_min_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1))));
    };
    const auto most = [](__m128 v) {
      v = _mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2)));
      return _mm_cvtss_f32(_mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1))));
    };
    lo[0] = least(x_lo);
    lo[1] = least(y_lo);
    lo[2] = least(z_lo);
    hi[0] = most(x_hi);
    hi[1] = most(y_hi);
    hi[2] = most(z_hi);
    return near;
  }
#endif
  for (int k = 0; k < 3; ++k) {
    lo[k] = kInfinity;
    hi[k] = -kInfinity;
  }
  for (; j < count; ++j) {
    const float q[3] = {ux[j], uy[j], uz[j]};
    if (Classify(a_lo, a_hi, q, q, test) == kReject) continue;
    near |= std::uint64_t{1} << j;
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], q[k]);
      hi[k] = std::max(hi[k], q[k]);
    }
  }
  return near;
}

namespace {

enum NodeFlag : std::uint8_t { kFull = 1, kUnified = 2 };

using Node = PointTree::Node;

// An array of findings. Shared by workers (kAtomic), it is read and written with relaxed
// atomics: everything the search writes only grows (a mark is set, two sets are joined), and
// a worker that reads a fact late does more work, never wrong work; the result is read once
// ParallelFor has returned (every worker's calls done). One worker alone keeps plain values, which
// the compiler keeps in registers and reorders freely. The values are a plain vector either way,
// accessed atomically through GCC's and Clang's __atomic built-ins (C++20's std::atomic_ref), so
// that they are filled and handed over without a copy.
template <class T, bool kAtomic>
class Cells {
  static_assert(std::is_integral_v<T> && __atomic_always_lock_free(sizeof(T), 0));

 public:
  // The cells through a pointer of the caller's: held in a local, it is not loaded again after
  // every byte store (which may alias anything in memory, the vector's own pointer too).
  class View {
   public:
    explicit View(T* v) : v_(v) {}
    T operator[](std::size_t i) const {
      if constexpr (kAtomic) {
        return __atomic_load_n(&v_[i], __ATOMIC_RELAXED);
      } else {
        return v_[i];
      }
    }
    void Set(std::size_t i, T value) const {
      if constexpr (kAtomic) {
        __atomic_store_n(&v_[i], value, __ATOMIC_RELAXED);
      } else {
        v_[i] = value;
      }
    }
    // Adds `bits` to element i. A cell that has them already is not written: a store, even of
    // the same value, would take its cache line from the other workers.
    void Add(std::size_t i, T bits) const {
      if ((operator[](i) & bits) == bits) return;
      if constexpr (kAtomic) {
        __atomic_fetch_or(&v_[i], bits, __ATOMIC_RELAXED);
      } else {
        v_[i] |= bits;
      }
    }
    // Sets element i, a mark that holds 0 or 1 only (lower, raised), to 1. One worker alone
    // stores it without looking: no load to wait for, no branch to mispredict.
    void Mark(std::size_t i) const {
      if constexpr (kAtomic) {
        Add(i, 1);
      } else {
        v_[i] = 1;
      }
    }
    // Sets element i to `desired` if it is `expected`; returns whether it did.
    bool CompareExchange(std::size_t i, T expected, T desired) const {
      if constexpr (kAtomic) {
        return __atomic_compare_exchange_n(&v_[i], &expected, desired, false, __ATOMIC_RELAXED,
                                           __ATOMIC_RELAXED);
      } else {
        if (v_[i] != expected) return false;
        v_[i] = desired;
        return true;
      }
    }

   private:
    T* v_;
  };

  explicit Cells(std::size_t n) : v_(n, T{}) {}
  explicit Cells(std::vector<T> values) : v_(std::move(values)) {}
  std::size_t size() const { return v_.size(); }
  View view() { return View(v_.data()); }
  T operator[](std::size_t i) const { return View(const_cast<T*>(v_.data()))[i]; }
  void Set(std::size_t i, T value) { view().Set(i, value); }
  void Add(std::size_t i, T bits) { view().Add(i, bits); }
  bool CompareExchange(std::size_t i, T expected, T desired) {
    return view().CompareExchange(i, expected, desired);
  }
  // The values, once no worker writes any more; the cells are left empty.
  std::vector<T> Take() { return std::move(v_); }

 private:
  std::vector<T> v_;
};

// What the workers find, over the image's pixels (marks, sets) and the two trees' nodes.
// kFull on a lower-tree node: every point has a partner; on an upper-tree node: every point
// is raised. kUnified: every point of the node is in one set. A flag is set before the
// worker that sets it has finished the marks or unions it stands for; until then others may
// skip work that those will do.
template <bool kAtomic>
struct Findings {
  Findings(int pixels, std::size_t lower_nodes, std::size_t upper_nodes, bool unions)
      : parent(Singletons(unions ? pixels : 0)),
        lower(pixels),
        raised(pixels),
        flags_lo(lower_nodes),
        flags_up(upper_nodes) {}
  static std::vector<std::int32_t> Singletons(int pixels) {
    std::vector<std::int32_t> parent(pixels);
    std::iota(parent.begin(), parent.end(), 0);
    return parent;
  }
  Cells<std::int32_t, kAtomic> parent;  ///< union-find; a parent's index is below its child's
  Cells<std::uint8_t, kAtomic> lower, raised;
  Cells<std::uint8_t, kAtomic> flags_lo, flags_up;
};

// One worker over the findings (shared with others when kAtomic); its own statistics, on
// cache lines of its own (the workers sit side by side in a vector, and counting on a line
// that another worker writes costs more than the search).
template <bool kAtomic>
class alignas(64) Search {
  using Flags = Cells<std::uint8_t, kAtomic>;

 public:
  Search(const PointTree& lower, const PointTree& upper, const PairTest& test,
         const PairSearchOptions& options, Findings<kAtomic>& found)
      : lo_(lower),
        up_(upper),
        test_(test),
        unions_(options.unions),
        parent_(found.parent),
        lower_(found.lower),
        raised_(found.raised),
        flags_lo_(found.flags_lo),
        flags_up_(found.flags_up),
        lanes_(VectorLanes()) {}

  void Visit(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    const Verdict v = Classify(A.lo, A.hi, B.lo, B.hi, test_);
    if (v == kReject) return;
    ++stats_.node_pairs;
    if (v == kAccept) {
      Accept(a, b);
      return;
    }
    if (Settled(a, b)) return;
    const bool a_leaf = Leaf(A), b_leaf = Leaf(B);
    if (a_leaf && b_leaf) {
      Leaves(a, b);
      return;
    }
    if (SplitLower(A, B, a_leaf, b_leaf)) {
      Visit(A.child[0], b);
      Visit(A.child[1], b);
    } else {
      Visit(a, B.child[0]);
      Visit(a, B.child[1]);
    }
  }

  const DetectionStats& stats() const { return stats_; }

 private:
  static int Size(const Node& n) { return n.end - n.begin; }
  static bool Leaf(const Node& n) { return n.child[0] < 0; }

  static bool SplitLower(const Node& A, const Node& B, bool a_leaf, bool b_leaf) {
    if (a_leaf) return false;
    if (b_leaf) return true;
    return Size(A) >= Size(B);
  }

  // Path halving: a node is pointed to its grandparent, still one of its ancestors however
  // the workers interleave (only roots are ever linked).
  int Find(int i) {
    for (int p = parent_[i]; p != i; p = parent_[i]) {
      const int grand = parent_[p];
      if (grand != p) parent_.Set(i, grand);
      i = grand;
    }
    return i;
  }
  // Whether i and j are in one set; two points with one parent are, without the walks.
  bool SameSet(int i, int j) { return parent_[i] == parent_[j] || Find(i) == Find(j); }
  // Joins the sets of i and j; returns the root of the joined set (as it was when joined).
  // The larger root is linked under the smaller, and only while it is still a root.
  int Union(int i, int j) {
    for (;;) {
      i = Find(i);
      j = Find(j);
      if (i == j) return i;
      if (i < j) std::swap(i, j);
      if (parent_.CompareExchange(i, i, j)) return j;
    }
  }

  bool Settled(int a, int b) {
    if (!(flags_lo_[a] & kFull) || !(flags_up_[b] & kFull)) return false;
    if (!unions_) return true;
    if (!(flags_lo_[a] & kUnified) || !(flags_up_[b] & kUnified)) return false;
    return SameSet(lo_.pixel[lo_.nodes[a].begin], up_.pixel[up_.nodes[b].begin]);
  }

  void Accept(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    ++stats_.blocks_accepted;
    stats_.pairs_compatible += static_cast<std::int64_t>(Size(A)) * Size(B);
    Mark(lo_, flags_lo_, a, lower_);
    Mark(up_, flags_up_, b, raised_);
    if (unions_) {
      Unify(lo_, flags_lo_, a);
      Unify(up_, flags_up_, b);
      Union(lo_.pixel[A.begin], up_.pixel[B.begin]);
    }
  }

  // The lower points [begin, end) against the box b_lo..b_hi (ClassifyByBox).
  void ClassifyPoints(const float* b_lo, const float* b_hi, int begin, int end, std::uint64_t& keep,
                      std::uint64_t& accept) const {
    ClassifyByBox(lanes_, lo_.x.data() + begin, lo_.y.data() + begin, lo_.z.data() + begin,
                  end - begin, b_lo, b_hi, test_, keep, accept);
  }

  // Bit j - B.begin for each point j of upper leaf B that A's box does not reject (NearBox): a
  // point without its bit is no partner of any lower point of A. `lo` and `hi` get the box of
  // those points (empty when there are none).
  std::uint64_t NearLower(const Node& A, const Node& B, float* lo, float* hi) const {
    return NearBox(lanes_, up_.x.data() + B.begin, up_.y.data() + B.begin, up_.z.data() + B.begin,
                   B.end - B.begin, A.lo, A.hi, test_, lo, hi);
  }

  // An upper leaf's points near the lower leaf, packed side by side (padded to a multiple of
  // sixteen with points infinitely high, for Hits' widest loads), in the leaf's order: by height,
  // which the test's count of points tested relies on (the hits do not; unsorted leaves were slower
  // all the same, BENCHMARKS.md).
  struct Packed {
    alignas(64) float x[PointTree::kMaxLeafPoints + 16];
    alignas(64) float y[PointTree::kMaxLeafPoints + 16];
    alignas(64) float z[PointTree::kMaxLeafPoints + 16];
    std::int32_t pixel[PointTree::kMaxLeafPoints];  ///< the point's image index
    int count = 0;
  };
  void Pack(const Node& B, std::uint64_t near, Packed& q) const {
#if defined(CAIRN_OD_WIDE_VECTORS)
    if (lanes_ == 16) {
      q.count =
          PackAvx512(up_.x.data() + B.begin, up_.y.data() + B.begin, up_.z.data() + B.begin,
                     up_.pixel.data() + B.begin, B.end - B.begin, near, q.x, q.y, q.z, q.pixel);
      return;
    }
    if (lanes_ == 8) {
      q.count = PackAvx2(up_.x.data() + B.begin, up_.y.data() + B.begin, up_.z.data() + B.begin,
                         up_.pixel.data() + B.begin, B.end - B.begin, near, q.x, q.y, q.z, q.pixel);
      return;
    }
#endif
    int c = 0;
    for (; near != 0; near &= near - 1) {
      const int j = B.begin + __builtin_ctzll(near);
      q.x[c] = up_.x[j];
      q.y[c] = up_.y[j];
      q.z[c] = up_.z[j];
      q.pixel[c++] = up_.pixel[j];
    }
    q.count = c;
    for (int k = c; k < ((c + 15) & ~15); ++k) {
      q.x[k] = q.y[k] = 0.0f;
      q.z[k] = std::numeric_limits<float>::infinity();
    }
  }

  // Bit k for each packed point k that the pair test puts in p's cone (more than HT and less
  // than Hmax above p, steeper than theta), with the pair test's float operations in its
  // order: all of them at once, with no window to find and no stop to mispredict, as many at
  // a time as the processor tests (simd.hpp). `tested` gets the number HT..Hmax above p.
  std::uint64_t Hits(const Packed& q, const float* p, std::int64_t& tested) const {
    const float ht = test_.min_height, hmax = test_.max_height, tan2 = test_.tan2_theta;
    std::uint64_t hits = 0, in_window = 0;
    switch (lanes_) {
#if defined(CAIRN_OD_WIDE_VECTORS)
      case 16:
        hits = HitsAvx512(q.x, q.y, q.z, q.count, p, test_, in_window);
        break;
      case 8:
        hits = HitsAvx2(q.x, q.y, q.z, q.count, p, test_, in_window);
        break;
#endif
#if defined(__SSE2__)
      case 4: {
        const __m128 px = _mm_set1_ps(p[0]), py = _mm_set1_ps(p[1]), pz = _mm_set1_ps(p[2]);
        const __m128 vht = _mm_set1_ps(ht), vh = _mm_set1_ps(hmax), vt = _mm_set1_ps(tan2);
        for (int k = 0; k < q.count; k += 4) {
          const __m128 dz = _mm_sub_ps(_mm_load_ps(q.z + k), pz);
          const __m128 dx = _mm_sub_ps(_mm_load_ps(q.x + k), px);
          const __m128 dy = _mm_sub_ps(_mm_load_ps(q.y + k), py);
          const __m128 reach = _mm_mul_ps(vt, _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)));
          const __m128 window = _mm_and_ps(_mm_cmpgt_ps(dz, vht), _mm_cmplt_ps(dz, vh));
          const __m128 in = _mm_and_ps(window, _mm_cmpgt_ps(_mm_mul_ps(dz, dz), reach));
          in_window |= static_cast<std::uint64_t>(_mm_movemask_ps(window)) << k;
          hits |= static_cast<std::uint64_t>(_mm_movemask_ps(in)) << k;
        }
        break;
      }
#endif
      default:
        for (int k = 0; k < q.count; ++k) {
          const float dx = q.x[k] - p[0], dy = q.y[k] - p[1], dz = q.z[k] - p[2];
          const bool window = dz > ht && dz < hmax;
          in_window |= static_cast<std::uint64_t>(window) << k;
          hits |= static_cast<std::uint64_t>(window && dz * dz > tan2 * (dx * dx + dy * dy)) << k;
        }
    }
    // The packed points ascend in height, so those in the window are one run of bits: its
    // length without a population count (a library call on x86-64's baseline).
    if (in_window != 0) tested += 64 - __builtin_clzll(in_window) - __builtin_ctzll(in_window);
    return hits;
  }

  // Two leaves, point by point, over the upper points near the lower leaf: a lower point
  // rejected by their box has no partner here, one accepted by it (when they are the whole
  // upper leaf) pairs with all of them, once a point has a partner, the near points
  // raised and in its set already can change nothing, and a point that pairs with near
  // points the earlier points took joins their set once.
  void Leaves(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    // Raw pointers: the flag stores below may alias anything, which would reload the
    // vectors' data on every step.
    const std::int32_t* lpix = lo_.pixel.data();
    const float* lx = lo_.x.data();
    const float* ly = lo_.y.data();
    const float* lz = lo_.z.data();
    const auto lower = lower_.view();
    const auto raised = raised_.view();
    const auto parent = parent_.view();
    const float hmax = test_.max_height;
    const bool unions = unions_;  // in a register (the mark stores may alias the member)
    const bool b_done = (flags_up_[b] & kFull) && (!unions || (flags_up_[b] & kUnified));
    const int b_first = up_.pixel[B.begin];
    // B's points that some point of A may pair with, and their box: the others are never
    // looked at. When they are all of B, their box is B's.
    float near_lo[3], near_hi[3];
    const std::uint64_t near = NearLower(A, B, near_lo, near_hi);
    if (near == 0) return;
    const int size = Size(B);
    const bool all_near = near == (size < 64 ? ~(~std::uint64_t{0} << size) : ~std::uint64_t{0});
    // The lower leaf is sorted by height: the points that the near box's heights reject
    // (Classify's first test: nothing more than HT above, or all of it Hmax above or more)
    // are its two ends, whose bounds the same float differences find. Sixteen at a time, the
    // box test rejects them as fast as this walk finds them.
    int i_begin = A.begin, i_end = A.end;
    if (lanes_ < 16) {
      while (i_begin < i_end && !(near_lo[2] - lz[i_begin] < hmax)) ++i_begin;
      while (i_end > i_begin && !(near_hi[2] - lz[i_end - 1] > test_.min_height)) --i_end;
    }
    // Packed points known to be raised and in the set of `done_root` (a root when taken; its
    // set only grows): those the earlier points of A paired with, or DoneBits' answer. A point
    // of A that pairs with one of them joins that set once, instead of taking each as its
    // partner again.
    int done_root = -1;
    std::uint64_t done_bits = 0;
    // Each point's verdict against the near box, all at once: `keep` those not rejected;
    // `accept` (compatible with all of B) only when the near box is B's.
    std::uint64_t keep = 0, accept = 0;
    ClassifyPoints(near_lo, near_hi, i_begin, i_end, keep, accept);
    if (!all_near) accept = 0;
    Packed packed;
    if ((keep & ~accept) != 0) Pack(B, near, packed);
    const std::uint64_t packed_bits =
        packed.count < 64 ? ~(~std::uint64_t{0} << packed.count) : ~std::uint64_t{0};
    bool found = false;  // some pair of the two leaves
    for (; keep != 0; keep &= keep - 1) {
      const int k = __builtin_ctzll(keep);
      const int i = i_begin + k;
      const float p[3] = {lx[i], ly[i], lz[i]};
      const int pi = lpix[i];
      if (b_done && lower[pi] && (!unions || SameSet(pi, b_first))) continue;
      if ((accept >> k) & 1) {
        found = true;
        lower.Add(pi, 1);
        stats_.pairs_compatible += Size(B);
        Mark(up_, flags_up_, b, raised_);
        if (unions) {
          Unify(up_, flags_up_, b);
          Union(pi, b_first);
        }
        continue;
      }
      // A point with a partner already meets, among B's points raised in its set, none that
      // can change anything: only the others are taken as partners, and when none is left it
      // is not tested at all.
      const bool has_partner = unions && lower[pi];
      int root = 0;
      if (has_partner) {
        root = Find(pi);
        if (root != done_root) {
          // The same set when the two were joined since; else the known points are taken
          // for p's set.
          if (done_root < 0 || Find(done_root) != root) done_bits = DoneBits(packed, root);
          done_root = root;
        }
        if ((packed_bits & ~done_bits) == 0) continue;
      }
      std::uint64_t hits = Hits(packed, p, stats_.pairs_tested);
      if (hits == 0) continue;
      found = true;
      lower.Add(pi, 1);
      // Whether p's set is done_root's: then the hits among the known points need nothing
      // more (p pairing with one of them is p joining their set).
      bool in_done = has_partner;
      if (unions && !has_partner) {
        root = Find(pi);
        if ((hits & done_bits) != 0) {
          root = Union(root, done_root);
          in_done = true;
        }
      }
      if (in_done) hits &= ~done_bits;
      // One partner (upper point, image index pj): raised, joined; true when the rest of B can
      // change nothing.
      const auto partner = [&](int pj) {
        raised.Mark(pj);
        // A partner whose parent is `root` (p's root when found, in p's set however the
        // workers link since: sets only grow) is in p's set already: most are, and skip the
        // walk to their root.
        if (unions && parent[pj] != root) {
          const int rj = Find(pj);
          if (rj != root) root = Union(root, rj);
        }
        return b_done && (!unions || parent[b_first] == root || root == Find(b_first));
      };
      // Counted here: the member would be loaded and stored again around every mark.
      int partners = 0;
      std::uint64_t taken = 0;  // the partners taken, now raised and in p's set
      bool all_done = false;    // all of B is, in p's set
      for (; hits != 0; hits &= hits - 1) {
        ++partners;
        const int bit = __builtin_ctzll(hits);
        taken |= std::uint64_t{1} << bit;
        if (partner(packed.pixel[bit])) {
          all_done = true;
          break;
        }
      }
      stats_.pairs_compatible += partners;
      if (!unions) continue;
      if (all_done) {
        done_bits = packed_bits;
      } else if (in_done) {
        done_bits |= taken;
      } else {
        done_bits = taken;
      }
      done_root = root;
    }
    // The leaves' flags are hints (work skipped when set): a pair of leaves that found no pair
    // leaves them unset, for a later pair that finds one to set, if there is one.
    if (!found) return;
    UpdateLeaf(lo_, flags_lo_, a, lower_);
    UpdateLeaf(up_, flags_up_, b, raised_);
  }

  // Bit k for each packed point k raised and in the set of `root`: a pair of one with a lower
  // point of that set that has a partner changes nothing. Facts only grow, so bits taken
  // earlier stay true.
  std::uint64_t DoneBits(const Packed& q, int root) {
    // Those whose parent is the root at once, without a branch; the walk to the root for the
    // other raised ones.
    std::uint64_t bits = 0, walk = 0;
    for (int k = 0; k < q.count; ++k) {
      const int pj = q.pixel[k];
      const bool raised = raised_[pj] != 0, child = parent_[pj] == root;
      bits |= static_cast<std::uint64_t>(raised & child) << k;
      walk |= static_cast<std::uint64_t>(raised & !child) << k;
    }
    for (; walk != 0; walk &= walk - 1) {
      const int k = __builtin_ctzll(walk);
      bits |= static_cast<std::uint64_t>(Find(q.pixel[k]) == root) << k;
    }
    return bits;
  }

  // Sets kFull on a leaf when every point has `point_flag`, and then tries to see the leaf
  // as one set.
  void UpdateLeaf(const PointTree& t, Flags& flags, int n, const Flags& point_flag) {
    const Node& node = t.nodes[n];
    if (!(flags[n] & kFull)) {
      for (int i = node.begin; i < node.end; ++i) {
        if (!point_flag[t.pixel[i]]) return;
      }
      flags.Add(n, kFull);
      PropagateUp(t, flags, node.parent, kFull);
    }
    if (unions_ && !(flags[n] & kUnified)) {
      const int root = Find(t.pixel[node.begin]);
      for (int i = node.begin + 1; i < node.end; ++i) {
        if (parent_[t.pixel[i]] != root && Find(t.pixel[i]) != root) return;
      }
      flags.Add(n, kUnified);
      PropagateUp(t, flags, node.parent, kUnified);
    }
  }

  // A node gets `flag` when both children have it (kUnified: and are in one set).
  void PropagateUp(const PointTree& t, Flags& flags, int n, NodeFlag flag) {
    for (; n >= 0 && !(flags[n] & flag); n = t.nodes[n].parent) {
      const Node& node = t.nodes[n];
      if (!(flags[node.child[0]] & flag) || !(flags[node.child[1]] & flag)) return;
      if (flag == kUnified &&
          !SameSet(t.pixel[t.nodes[node.child[0]].begin], t.pixel[t.nodes[node.child[1]].begin])) {
        return;
      }
      flags.Add(n, flag);
    }
  }

  // Every point of node n gets `point_flag` (lower or raised).
  void Mark(const PointTree& t, Flags& flags, int n, Flags& point_flag) {
    if (flags[n] & kFull) return;
    MarkDown(t, flags, n, point_flag);
    PropagateUp(t, flags, t.nodes[n].parent, kFull);
  }
  void MarkDown(const PointTree& t, Flags& flags, int n, Flags& point_flag) {
    if (flags[n] & kFull) return;
    flags.Add(n, kFull);
    const Node& node = t.nodes[n];
    if (Leaf(node)) {
      for (int i = node.begin; i < node.end; ++i) point_flag.Add(t.pixel[i], 1);
      return;
    }
    MarkDown(t, flags, node.child[0], point_flag);
    MarkDown(t, flags, node.child[1], point_flag);
  }

  // Every point of node n in one set.
  void Unify(const PointTree& t, Flags& flags, int n) {
    if (flags[n] & kUnified) return;
    UnifyDown(t, flags, n);
    PropagateUp(t, flags, t.nodes[n].parent, kUnified);
  }
  void UnifyDown(const PointTree& t, Flags& flags, int n) {
    if (flags[n] & kUnified) return;
    flags.Add(n, kUnified);
    const Node& node = t.nodes[n];
    if (Leaf(node)) {
      int root = Find(t.pixel[node.begin]);
      for (int i = node.begin + 1; i < node.end; ++i) root = Union(root, t.pixel[i]);
      return;
    }
    UnifyDown(t, flags, node.child[0]);
    UnifyDown(t, flags, node.child[1]);
    Union(t.pixel[t.nodes[node.child[0]].begin], t.pixel[t.nodes[node.child[1]].begin]);
  }

  const PointTree& lo_;
  const PointTree& up_;
  const PairTest& test_;
  const bool unions_;
  Cells<std::int32_t, kAtomic>& parent_;
  Flags& lower_;
  Flags& raised_;
  Flags& flags_lo_;
  Flags& flags_up_;
  const int lanes_;  // the width of Hits and the box tests (simd.hpp)
  DetectionStats stats_;
};

struct Task {
  std::int32_t lower, upper;
};

// Lower nodes that split the work, each with its tree's upper root: every lower point lies
// in exactly one, so each ordered pair is searched by exactly one task. The node with the
// most points is split until there are `wanted`; the largest come first, so that the
// workers, taking them in turn, end together.
std::vector<Task> Tasks(const PointTree& lower, const PointTree& upper, std::size_t wanted) {
  const auto points = [&](const Task& t) {
    const Node& n = lower.nodes[t.lower];
    return n.end - n.begin;
  };
  const auto fewer = [&](const Task& a, const Task& b) { return points(a) < points(b); };
  std::vector<Task> tasks, leaves;  // tasks: a heap by points
  for (std::size_t t = 0; t < lower.roots.size(); ++t) {
    if (lower.roots[t] >= 0 && upper.roots[t] >= 0) tasks.push_back({lower.roots[t], upper.roots[t]});
  }
  std::make_heap(tasks.begin(), tasks.end(), fewer);
  while (!tasks.empty() && tasks.size() + leaves.size() < wanted) {
    std::pop_heap(tasks.begin(), tasks.end(), fewer);
    const Task t = tasks.back();
    tasks.pop_back();
    const Node& n = lower.nodes[t.lower];
    if (n.child[0] < 0) {
      leaves.push_back(t);
      continue;
    }
    for (const std::int32_t child : n.child) {
      tasks.push_back({child, t.upper});
      std::push_heap(tasks.begin(), tasks.end(), fewer);
    }
  }
  tasks.insert(tasks.end(), leaves.begin(), leaves.end());
  std::sort(tasks.begin(), tasks.end(),
            [&](const Task& a, const Task& b) { return points(a) > points(b); });
  return tasks;
}

template <bool kAtomic>
PairSearchResult Run(const PointTree& lower, const PointTree& upper, int pixels,
                     const PairTest& test, const PairSearchOptions& options,
                     const std::vector<Task>& tasks, int threads) {
  Findings<kAtomic> found(pixels, lower.nodes.size(), upper.nodes.size(), options.unions);
  std::vector<Search<kAtomic>> workers;
  workers.reserve(threads);
  for (int t = 0; t < threads; ++t) workers.emplace_back(lower, upper, test, options, found);
  ParallelFor(
      static_cast<int>(tasks.size()), threads,
      [&](int worker, int k) { workers[worker].Visit(tasks[k].lower, tasks[k].upper); }, 1);
  // Every worker's calls have returned: the findings are final.
  PairSearchResult r;
  r.lower = found.lower.Take();
  r.raised = found.raised.Take();
  if (options.unions) r.parent = found.parent.Take();
  for (const Search<kAtomic>& w : workers) {
    r.stats.pairs_tested += w.stats().pairs_tested;
    r.stats.pairs_compatible += w.stats().pairs_compatible;
    r.stats.node_pairs += w.stats().node_pairs;
    r.stats.blocks_accepted += w.stats().blocks_accepted;
  }
  return r;
}

}  // namespace

PairSearchResult SearchPairs(const PointTree& lower, const PointTree& upper, int pixels,
                             const PairTest& test, const PairSearchOptions& options) {
  const int threads = std::max(1, options.threads);
  // On one thread too: 256 lower subtrees searched in turn, largest first, visit fewer pairs
  // of nodes than the two roots searched at once (BENCHMARKS.md, 2026-12-04 afternoon).
  const std::vector<Task> tasks =
      Tasks(lower, upper, std::max<std::size_t>(256, 32 * static_cast<std::size_t>(threads)));
  if (threads == 1 || tasks.size() == 1)
    return Run<false>(lower, upper, pixels, test, options, tasks, 1);
  return Run<true>(lower, upper, pixels, test, options, tasks, threads);
}

}  // namespace cairn::od::internal
