#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <variant>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cairn/od/parallel.hpp"
#include "detection_internal.hpp"
#include "simd.hpp"

namespace cairn::od::internal {

LevelPoints::LevelPoints(const RangeImage& image, int threads, double min_range_m)
    : x(image.size()), y(image.size()), z(image.size()) {
  const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();
  constexpr float kInfinity = std::numeric_limits<float>::infinity();
  constexpr int kParts = 8;
  const int n = image.size();
  // Each part's extent and count of valid points, taken from the values as they are stored
  // (near returns dropped already): a < b ? a : b, lane by lane as _mm_min_ps(a, b) is, so that
  // a NaN (an invalid point) never replaces a bound.
  struct Extent {
    float x_lo = kInfinity, x_hi = -kInfinity, y_lo = kInfinity, y_hi = -kInfinity;
    int valid = 0;
  };
  std::array<Extent, kParts> extents;
#if defined(__SSE2__)
  struct Lanes {
    __m128 x_lo = _mm_set1_ps(kInfinity), x_hi = _mm_set1_ps(-kInfinity);
    __m128 y_lo = _mm_set1_ps(kInfinity), y_hi = _mm_set1_ps(-kInfinity);
    __m128i minus_valid = _mm_setzero_si128();  // each lane's valid points as -1s
    void Add(__m128 px, __m128 py, __m128 pz) {
      minus_valid = _mm_add_epi32(minus_valid, _mm_castps_si128(_mm_cmpeq_ps(pz, pz)));
      x_lo = _mm_min_ps(px, x_lo);
      x_hi = _mm_max_ps(px, x_hi);
      y_lo = _mm_min_ps(py, y_lo);
      y_hi = _mm_max_ps(py, y_hi);
    }
    void Into(Extent& e) const {
      alignas(16) float v[4][4];
      alignas(16) std::int32_t counts[4];
      _mm_store_ps(v[0], x_lo);
      _mm_store_ps(v[1], x_hi);
      _mm_store_ps(v[2], y_lo);
      _mm_store_ps(v[3], y_hi);
      _mm_store_si128(reinterpret_cast<__m128i*>(counts), minus_valid);
      for (int l = 0; l < 4; ++l) {
        e.x_lo = v[0][l] < e.x_lo ? v[0][l] : e.x_lo;
        e.x_hi = v[1][l] > e.x_hi ? v[1][l] : e.x_hi;
        e.y_lo = v[2][l] < e.y_lo ? v[2][l] : e.y_lo;
        e.y_hi = v[3][l] > e.y_hi ? v[3][l] : e.y_hi;
        e.valid -= counts[l];
      }
    }
  };
#endif
  const auto add = [](Extent& e, float px, float py, float pz) {
    e.valid += pz == pz;
    e.x_lo = px < e.x_lo ? px : e.x_lo;
    e.x_hi = px > e.x_hi ? px : e.x_hi;
    e.y_lo = py < e.y_lo ? py : e.y_lo;
    e.y_hi = py > e.y_hi ? py : e.y_hi;
  };
  ParallelFor(
      kParts, threads,
      [&](int k) {
        Extent e;  // in registers, stored once (the stores below may alias a member)
        const float r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
        const float r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
        const float r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
        const float* sx = image.x().data();
        const float* sy = image.y().data();
        const float* sz = image.z().data();
        float* lx = x.data();
        float* ly = y.data();
        float* lz = z.data();
        const int begin = PartBegin(n, k, kParts), end = PartBegin(n, k + 1, kParts);
        int i = begin;
        // Returns nearer than min_range dropped (NaN) as they are stored, by
        // DropReturnsNearerThan's test in its double arithmetic (a NaN return compares false
        // and stays NaN).
        const bool drop = min_range_m > 0.0;
        const double range2 = min_range_m * min_range_m;
        constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
#if defined(__SSE2__)
        const auto row = [&](float a, float b, float c, __m128 px, __m128 py, __m128 pz) {
          return _mm_add_ps(
              _mm_add_ps(_mm_mul_ps(_mm_set1_ps(a), px), _mm_mul_ps(_mm_set1_ps(b), py)),
              _mm_mul_ps(_mm_set1_ps(c), pz));
        };
        // Four at a time: each pair of floats widened to doubles, the two halves' "nearer"
        // masks packed into four float lanes.
        const __m128d vrange2 = _mm_set1_pd(range2);
        const __m128 vnan = _mm_set1_ps(kNaN);
        const auto near2 = [&](__m128 px, __m128 py, __m128 pz) {
          const __m128d dx = _mm_cvtps_pd(px), dy = _mm_cvtps_pd(py), dz = _mm_cvtps_pd(pz);
          return _mm_cmplt_pd(
              _mm_add_pd(_mm_add_pd(_mm_mul_pd(dx, dx), _mm_mul_pd(dy, dy)), _mm_mul_pd(dz, dz)),
              vrange2);
        };
        Lanes lanes;
        for (; i + 4 <= end; i += 4) {
          const __m128 px = _mm_loadu_ps(sx + i), py = _mm_loadu_ps(sy + i),
                       pz = _mm_loadu_ps(sz + i);
          __m128 qx = row(r00, r01, r02, px, py, pz), qy = row(r10, r11, r12, px, py, pz);
          __m128 qz = row(r20, r21, r22, px, py, pz);
          if (drop) {
            const __m128d lo = near2(px, py, pz);
            const __m128d hi =
                near2(_mm_movehl_ps(px, px), _mm_movehl_ps(py, py), _mm_movehl_ps(pz, pz));
            // Each double lane's mask is all ones or zeros: its low 32 bits stand for it.
            const __m128 near =
                _mm_shuffle_ps(_mm_castpd_ps(lo), _mm_castpd_ps(hi), _MM_SHUFFLE(2, 0, 2, 0));
            qx = _mm_or_ps(_mm_and_ps(near, vnan), _mm_andnot_ps(near, qx));
            qy = _mm_or_ps(_mm_and_ps(near, vnan), _mm_andnot_ps(near, qy));
            qz = _mm_or_ps(_mm_and_ps(near, vnan), _mm_andnot_ps(near, qz));
          }
          _mm_storeu_ps(lx + i, qx);
          _mm_storeu_ps(ly + i, qy);
          _mm_storeu_ps(lz + i, qz);
          lanes.Add(qx, qy, qz);
        }
        lanes.Into(e);
#endif
        for (; i < end; ++i) {
          // R p as (r0 x + r1 y) + r2 z, as the four at a time above; NaN stays NaN.
          lx[i] = r00 * sx[i] + r01 * sy[i] + r02 * sz[i];
          ly[i] = r10 * sx[i] + r11 * sy[i] + r12 * sz[i];
          lz[i] = r20 * sx[i] + r21 * sy[i] + r22 * sz[i];
          if (drop) {
            const double r2 = static_cast<double>(sx[i]) * sx[i] +
                              static_cast<double>(sy[i]) * sy[i] +
                              static_cast<double>(sz[i]) * sz[i];
            if (r2 < range2) lx[i] = ly[i] = lz[i] = kNaN;
          }
          add(e, lx[i], ly[i], lz[i]);
        }
        extents[k] = e;
      },
      1);
  for (const Extent& e : extents) {
    x_min = std::min(x_min, e.x_lo);
    x_max = std::max(x_max, e.x_hi);
    y_min = std::min(y_min, e.y_lo);
    y_max = std::max(y_max, e.y_hi);
    valid += e.valid;
  }
}

RowTiles::RowTiles(const LevelPoints& level, int width, int height)
    : tiles_per_row((width + kTileWidth - 1) / kTileWidth) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const std::size_t n = static_cast<std::size_t>(tiles_per_row) * height;
  for (auto* v : {&x_min, &y_min, &z_min}) v->assign(n, kInf);
  for (auto* v : {&x_max, &y_max, &z_max}) v->assign(n, -kInf);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const int i = r * width + c;
      if (std::isnan(level.z[i])) continue;
      const std::size_t t = static_cast<std::size_t>(r) * tiles_per_row + c / kTileWidth;
      x_min[t] = std::min(x_min[t], level.x[i]);
      x_max[t] = std::max(x_max[t], level.x[i]);
      y_min[t] = std::min(y_min[t], level.y[i]);
      y_max[t] = std::max(y_max[t], level.y[i]);
      z_min[t] = std::min(z_min[t], level.z[i]);
      z_max[t] = std::max(z_max[t], level.z[i]);
    }
  }
}

UnionFind::UnionFind(int n) : parent_(n) {
  for (int i = 0; i < n; ++i) parent_[i] = i;
}

int UnionFind::Find(int i) {
  while (parent_[i] != i) {
    parent_[i] = parent_[parent_[i]];  // path halving
    i = parent_[i];
  }
  return i;
}

void UnionFind::Union(int i, int j) {
  i = Find(i);
  j = Find(j);
  if (i == j) return;
  if (i < j) {
    parent_[j] = i;
  } else {
    parent_[i] = j;
  }
}

void UnionFind::Merge(UnionFind& other) {
  for (int i = 0; i < static_cast<int>(parent_.size()); ++i) {
    const int root = other.Find(i);
    if (root != i) Union(i, root);
  }
}

std::vector<std::int32_t> UnionFind::Components() {
  const int n = static_cast<int>(parent_.size());
  std::vector<std::int32_t> size(n, 0), root(n);
  for (int i = 0; i < n; ++i) ++size[root[i] = Find(i)];
  for (int i = 0; i < n; ++i) {
    if (size[root[i]] == 1) root[i] = -1;
  }
  return root;
}

namespace {

#if defined(CAIRN_OD_WIDE_VECTORS)
CAIRN_OD_AVX512_KERNELS_BEGIN
// Inclinations eight at a time (AVX-512F), with the SSE2 loop's operations in its order; the
// pieces chosen by masks. Returns how many it did (a multiple of eight).
__attribute__((target("avx512f"))) int InclinationsAvx512(const double* squares,
                                                          const double* verticals, double* out,
                                                          int n) {
  constexpr double kTanPi8 = kInclinationTanPi8, kPi4 = kInclinationPi4;
  const __m512d tan_pi8 = _mm512_set1_pd(kTanPi8);
  const __m512i sign = _mm512_set1_epi64(std::numeric_limits<std::int64_t>::min());
  const __m512d zero = _mm512_setzero_pd();
  int j = 0;
  for (; j + 8 <= n; j += 8) {
    const __m512d h = _mm512_sqrt_pd(_mm512_loadu_pd(squares + j));
    const __m512d v = _mm512_loadu_pd(verticals + j);
    const __mmask8 low = _mm512_cmp_pd_mask(h, _mm512_mul_pd(v, tan_pi8), _CMP_LE_OQ);
    const __mmask8 high =
        static_cast<__mmask8>(~low & _mm512_cmp_pd_mask(v, _mm512_mul_pd(h, tan_pi8), _CMP_LE_OQ));
    const __mmask8 mid = static_cast<__mmask8>(~(low | high));
    const __m512d minus_v = _mm512_castsi512_pd(_mm512_xor_epi64(_mm512_castpd_si512(v), sign));
    // low: h / v; high: -v / h; between: (h - v) / (h + v).
    const __m512d num =
        _mm512_mask_mov_pd(_mm512_mask_mov_pd(_mm512_sub_pd(h, v), high, minus_v), low, h);
    const __m512d den =
        _mm512_mask_mov_pd(_mm512_mask_mov_pd(_mm512_add_pd(h, v), high, h), low, v);
    const __m512d offset = _mm512_mask_mov_pd(
        _mm512_mask_mov_pd(zero, high, _mm512_set1_pd(2.0 * kPi4)), mid, _mm512_set1_pd(kPi4));
    const __m512d t = _mm512_div_pd(num, den), z = _mm512_mul_pd(t, t);
    __m512d p = _mm512_set1_pd(kInclinationPoly[0]);
    for (int c = 1; c < 6; ++c)
      p = _mm512_add_pd(_mm512_mul_pd(p, z), _mm512_set1_pd(kInclinationPoly[c]));
    _mm512_storeu_pd(out + j, _mm512_add_pd(offset, _mm512_mul_pd(t, p)));
  }
  return j;
}

// Eight level points (k <= 8 of them, from `at`) as doubles; lanes outside `lanes` are 0 and
// not read.
__attribute__((target("avx512f"))) inline __m512d Widen(const float* at, __mmask16 lanes) {
  return _mm512_cvtps_pd(_mm512_castps512_ps256(_mm512_maskz_loadu_ps(lanes, at)));
}

// BuildDetection's surface normals at k <= 8 inner points i..i+k-1 of a run of segment `id`
// along a row (their row neighbours are the run's own), eight at a time (AVX-512F) with the
// scalar code's double operations in its order: the row tangent from the two row neighbours,
// the column tangent from the neighbours above and below that are in the segment (a point with
// neither has no normal), their cross product. Each normal that is not zero puts the square of
// its horizontal part in `squares` and its vertical part's size in `verticals`, in the points'
// order; returns how many did.
__attribute__((target("avx512f,popcnt"))) int InnerNormalsAvx512(
    const float* x, const float* y, const float* z, const std::int32_t* labels, int i, int k,
    int width, bool has_up, bool has_down, std::int32_t id, double* squares, double* verticals) {
  const auto lanes = static_cast<__mmask16>((1u << k) - 1);
  const __m512i vid = _mm512_set1_epi32(id);
  const auto in_segment = [&](int at) __attribute__((target("avx512f"))) {
    return _mm512_mask_cmpeq_epi32_mask(lanes, _mm512_maskz_loadu_epi32(lanes, labels + at), vid);
  };
  const __mmask16 below = has_down ? in_segment(i + width) : 0;
  const __mmask16 above = has_up ? in_segment(i - width) : 0;
  const __m512d px = Widen(x + i, lanes), py = Widen(y + i, lanes), pz = Widen(z + i, lanes);
  const __m512d ux = _mm512_sub_pd(Widen(x + i + 1, lanes), Widen(x + i - 1, lanes));
  const __m512d uy = _mm512_sub_pd(Widen(y + i + 1, lanes), Widen(y + i - 1, lanes));
  const __m512d uz = _mm512_sub_pd(Widen(z + i + 1, lanes), Widen(z + i - 1, lanes));
  // (below ? the point below : p) - (above ? the point above : p).
  const auto b8 = static_cast<__mmask8>(below), a8 = static_cast<__mmask8>(above);
  const __m512d vx = _mm512_sub_pd(_mm512_mask_blend_pd(b8, px, Widen(x + i + width, below)),
                                   _mm512_mask_blend_pd(a8, px, Widen(x + i - width, above)));
  const __m512d vy = _mm512_sub_pd(_mm512_mask_blend_pd(b8, py, Widen(y + i + width, below)),
                                   _mm512_mask_blend_pd(a8, py, Widen(y + i - width, above)));
  const __m512d vz = _mm512_sub_pd(_mm512_mask_blend_pd(b8, pz, Widen(z + i + width, below)),
                                   _mm512_mask_blend_pd(a8, pz, Widen(z + i - width, above)));
  // Eigen's cross product, term for term.
  const __m512d nx = _mm512_sub_pd(_mm512_mul_pd(uy, vz), _mm512_mul_pd(uz, vy));
  const __m512d ny = _mm512_sub_pd(_mm512_mul_pd(uz, vx), _mm512_mul_pd(ux, vz));
  const __m512d nz = _mm512_sub_pd(_mm512_mul_pd(ux, vy), _mm512_mul_pd(uy, vx));
  const __m512d square = _mm512_add_pd(_mm512_mul_pd(nx, nx), _mm512_mul_pd(ny, ny));
  const __m512d zero = _mm512_setzero_pd();
  const auto kept =
      static_cast<__mmask8>((a8 | b8) & (_mm512_cmp_pd_mask(square, zero, _CMP_GT_OQ) |
                                         _mm512_cmp_pd_mask(nz, zero, _CMP_NEQ_UQ)));
  CompressStore(squares, kept, square);
  CompressStore(verticals, kept, _mm512_abs_pd(nz));
  return __builtin_popcount(kept);
}

// BuildDetection's gathering of the pixels [begin, end) that are in a segment (label >= 0),
// sixteen at a time (AVX-512F): each such pixel is appended to `part` at `count`, and every
// label below 0 becomes 0. Returns the first pixel it left (fewer than sixteen before `end`).
__attribute__((target("avx512f,popcnt"))) int GatherMembersAvx512(std::int32_t* labels, int begin,
                                                                  int end, std::int32_t* part,
                                                                  int& count) {
  const __m512i zero = _mm512_setzero_si512(), sixteen = _mm512_set1_epi32(16);
  __m512i index =
      _mm512_add_epi32(_mm512_set1_epi32(begin),
                       _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0));
  int i = begin, c = count;
  for (; i + 16 <= end; i += 16) {
    const __m512i name = _mm512_loadu_si512(labels + i);
    const __mmask16 member = _mm512_cmpge_epi32_mask(name, zero);
    CompressStore(part + c, member, index);
    c += __builtin_popcount(member);
    _mm512_storeu_si512(labels + i, _mm512_max_epi32(name, zero));
    index = _mm512_add_epi32(index, sixteen);
  }
  count = c;
  return i;
}

// InclinationsAvx512 four at a time (AVX2), the pieces chosen by blends.
__attribute__((target("avx2"))) int InclinationsAvx2(const double* squares, const double* verticals,
                                                     double* out, int n) {
  constexpr double kTanPi8 = kInclinationTanPi8, kPi4 = kInclinationPi4;
  const __m256d tan_pi8 = _mm256_set1_pd(kTanPi8), sign = _mm256_set1_pd(-0.0);
  int j = 0;
  for (; j + 4 <= n; j += 4) {
    const __m256d h = _mm256_sqrt_pd(_mm256_loadu_pd(squares + j));
    const __m256d v = _mm256_loadu_pd(verticals + j);
    const __m256d low = _mm256_cmp_pd(h, _mm256_mul_pd(v, tan_pi8), _CMP_LE_OQ);
    const __m256d high =
        _mm256_andnot_pd(low, _mm256_cmp_pd(v, _mm256_mul_pd(h, tan_pi8), _CMP_LE_OQ));
    // low: h / v; high: -v / h; between: (h - v) / (h + v).
    const __m256d num = _mm256_blendv_pd(
        _mm256_blendv_pd(_mm256_sub_pd(h, v), _mm256_xor_pd(v, sign), high), h, low);
    const __m256d den = _mm256_blendv_pd(_mm256_blendv_pd(_mm256_add_pd(h, v), h, high), v, low);
    const __m256d offset = _mm256_blendv_pd(_mm256_andnot_pd(low, _mm256_set1_pd(kPi4)),
                                            _mm256_set1_pd(2.0 * kPi4), high);
    const __m256d t = _mm256_div_pd(num, den), z = _mm256_mul_pd(t, t);
    __m256d p = _mm256_set1_pd(kInclinationPoly[0]);
    for (int c = 1; c < 6; ++c)
      p = _mm256_add_pd(_mm256_mul_pd(p, z), _mm256_set1_pd(kInclinationPoly[c]));
    _mm256_storeu_pd(out + j, _mm256_add_pd(offset, _mm256_mul_pd(t, p)));
  }
  return j;
}

// Four level points (of `lanes`, all ones in each 64-bit lane taken) as doubles; the others 0.
__attribute__((target("avx2"))) inline __m256d Widen4(const float* at, __m256i lanes) {
  // The low 32 bits of each 64-bit lane, as the four 32-bit lanes of a load.
  const __m128i four = _mm256_castsi256_si128(
      _mm256_permutevar8x32_epi32(lanes, _mm256_setr_epi32(0, 2, 4, 6, 0, 0, 0, 0)));
  return _mm256_cvtps_pd(_mm_maskload_ps(at, four));
}

// InnerNormalsAvx512 for k <= 4 inner points four at a time (AVX2), the same double operations;
// the kept normals moved to the front by a permutation and stored whole (`squares` and
// `verticals` have room for four).
__attribute__((target("avx2,popcnt"))) int InnerNormalsAvx2(
    const float* x, const float* y, const float* z, const std::int32_t* labels, int i, int k,
    int width, bool has_up, bool has_down, std::int32_t id, double* squares, double* verticals) {
  const __m128i lanes32 = _mm_cmpgt_epi32(_mm_set1_epi32(k), _mm_setr_epi32(0, 1, 2, 3));
  const __m128i vid = _mm_set1_epi32(id);
  const auto in_segment = [&](int at) __attribute__((target("avx2"))) {
    return _mm256_cvtepi32_epi64(
        _mm_and_si128(lanes32, _mm_cmpeq_epi32(_mm_maskload_epi32(labels + at, lanes32), vid)));
  };
  const __m256i none = _mm256_setzero_si256();
  const __m256i below = has_down ? in_segment(i + width) : none;
  const __m256i above = has_up ? in_segment(i - width) : none;
  const __m256i lanes = _mm256_cvtepi32_epi64(lanes32);
  const __m256d px = Widen4(x + i, lanes), py = Widen4(y + i, lanes), pz = Widen4(z + i, lanes);
  const __m256d ux = _mm256_sub_pd(Widen4(x + i + 1, lanes), Widen4(x + i - 1, lanes));
  const __m256d uy = _mm256_sub_pd(Widen4(y + i + 1, lanes), Widen4(y + i - 1, lanes));
  const __m256d uz = _mm256_sub_pd(Widen4(z + i + 1, lanes), Widen4(z + i - 1, lanes));
  // (below ? the point below : p) - (above ? the point above : p).
  const __m256d b = _mm256_castsi256_pd(below), a = _mm256_castsi256_pd(above);
  const __m256d vx = _mm256_sub_pd(_mm256_blendv_pd(px, Widen4(x + i + width, below), b),
                                   _mm256_blendv_pd(px, Widen4(x + i - width, above), a));
  const __m256d vy = _mm256_sub_pd(_mm256_blendv_pd(py, Widen4(y + i + width, below), b),
                                   _mm256_blendv_pd(py, Widen4(y + i - width, above), a));
  const __m256d vz = _mm256_sub_pd(_mm256_blendv_pd(pz, Widen4(z + i + width, below), b),
                                   _mm256_blendv_pd(pz, Widen4(z + i - width, above), a));
  // Eigen's cross product, term for term.
  const __m256d nx = _mm256_sub_pd(_mm256_mul_pd(uy, vz), _mm256_mul_pd(uz, vy));
  const __m256d ny = _mm256_sub_pd(_mm256_mul_pd(uz, vx), _mm256_mul_pd(ux, vz));
  const __m256d nz = _mm256_sub_pd(_mm256_mul_pd(ux, vy), _mm256_mul_pd(uy, vx));
  const __m256d square = _mm256_add_pd(_mm256_mul_pd(nx, nx), _mm256_mul_pd(ny, ny));
  const __m256d zero = _mm256_setzero_pd();
  const auto kept = static_cast<unsigned>(_mm256_movemask_pd(
      _mm256_and_pd(_mm256_or_pd(a, b), _mm256_or_pd(_mm256_cmp_pd(square, zero, _CMP_GT_OQ),
                                                     _mm256_cmp_pd(nz, zero, _CMP_NEQ_UQ)))));
  // Double lane l is 32-bit lanes 2l and 2l + 1.
  unsigned pairs = 0;
  for (unsigned l = 0; l < 4; ++l) pairs |= (kept >> l & 1u) * (3u << (2 * l));
  const __m256i to_front = ToFront8(pairs);
  _mm256_storeu_pd(squares,
                   _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(square), to_front)));
  _mm256_storeu_pd(verticals,
                   _mm256_castps_pd(_mm256_permutevar8x32_ps(
                       _mm256_castpd_ps(_mm256_andnot_pd(_mm256_set1_pd(-0.0), nz)), to_front)));
  return __builtin_popcount(kept);
}

// GatherMembersAvx512 eight at a time (AVX2): the members' indices moved to the front by a
// permutation and stored whole (the eight stored from `count` end before i + 8 - begin, within
// `part`).
__attribute__((target("avx2,popcnt"))) int GatherMembersAvx2(std::int32_t* labels, int begin,
                                                             int end, std::int32_t* part,
                                                             int& count) {
  const __m256i zero = _mm256_setzero_si256(), minus_one = _mm256_set1_epi32(-1);
  const __m256i eight = _mm256_set1_epi32(8);
  __m256i index =
      _mm256_add_epi32(_mm256_set1_epi32(begin), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  int i = begin, c = count;
  for (; i + 8 <= end; i += 8) {
    const __m256i name = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(labels + i));
    const auto member = static_cast<unsigned>(
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(name, minus_one))));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(part + c),
                        _mm256_permutevar8x32_epi32(index, ToFront8(member)));
    c += __builtin_popcount(member);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(labels + i), _mm256_max_epi32(name, zero));
    index = _mm256_add_epi32(index, eight);
  }
  count = c;
  return i;
}
CAIRN_OD_AVX512_KERNELS_END
#endif

}  // namespace

void Inclinations(const double* squares, const double* verticals, double* out, int n) {
  int j = 0;
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (VectorLanes() == 16) j = InclinationsAvx512(squares, verticals, out, n);
  if (VectorLanes() == 8) j = InclinationsAvx2(squares, verticals, out, n);
#endif
#if defined(__SSE2__)
  constexpr double kTanPi8 = kInclinationTanPi8, kPi4 = kInclinationPi4;
  const __m128d tan_pi8 = _mm_set1_pd(kTanPi8), sign = _mm_set1_pd(-0.0);
  const __m128d all = _mm_castsi128_pd(_mm_set1_epi32(-1));
  for (; j + 2 <= n; j += 2) {
    const __m128d h = _mm_sqrt_pd(_mm_loadu_pd(squares + j)), v = _mm_loadu_pd(verticals + j);
    const __m128d low = _mm_cmple_pd(h, _mm_mul_pd(v, tan_pi8));
    const __m128d high = _mm_andnot_pd(low, _mm_cmple_pd(v, _mm_mul_pd(h, tan_pi8)));
    const __m128d mid = _mm_andnot_pd(_mm_or_pd(low, high), all);
    const __m128d num =
        _mm_or_pd(_mm_or_pd(_mm_and_pd(low, h), _mm_and_pd(high, _mm_xor_pd(v, sign))),
                  _mm_and_pd(mid, _mm_sub_pd(h, v)));
    const __m128d den = _mm_or_pd(_mm_or_pd(_mm_and_pd(low, v), _mm_and_pd(high, h)),
                                  _mm_and_pd(mid, _mm_add_pd(h, v)));
    const __m128d offset =
        _mm_or_pd(_mm_and_pd(high, _mm_set1_pd(2.0 * kPi4)), _mm_and_pd(mid, _mm_set1_pd(kPi4)));
    const __m128d t = _mm_div_pd(num, den), z = _mm_mul_pd(t, t);
    __m128d p = _mm_set1_pd(kInclinationPoly[0]);
    for (int c = 1; c < 6; ++c) p = _mm_add_pd(_mm_mul_pd(p, z), _mm_set1_pd(kInclinationPoly[c]));
    _mm_storeu_pd(out + j, _mm_add_pd(offset, _mm_mul_pd(t, p)));
  }
#endif
  for (; j < n; ++j) out[j] = Inclination(std::sqrt(squares[j]), verticals[j]);
}

namespace {

// One segment's features over some of its points, before the means: the sums behind them.
struct Partial {
  SegmentFeatures f;
  double sx = 0, sy = 0, sz = 0, s_range = 0, slope_sum = 0;

  Partial() {
    const double inf = std::numeric_limits<double>::infinity();
    f.bbox_min = Eigen::Vector3d::Constant(inf);
    f.bbox_max = Eigen::Vector3d::Constant(-inf);
    f.range_min_m = inf;
    f.row_min = f.col_min = std::numeric_limits<int>::max();
    f.row_max = f.col_max = -1;
  }
  // Adds the points of `o` (points that come after this one's in row-major order).
  void Add(const Partial& o) {
    f.point_count += o.f.point_count;
    f.raised_count += o.f.raised_count;
    f.bbox_min = f.bbox_min.cwiseMin(o.f.bbox_min);
    f.bbox_max = f.bbox_max.cwiseMax(o.f.bbox_max);
    f.range_min_m = std::min(f.range_min_m, o.f.range_min_m);
    f.row_min = std::min(f.row_min, o.f.row_min);
    f.row_max = std::max(f.row_max, o.f.row_max);
    f.col_min = std::min(f.col_min, o.f.col_min);
    f.col_max = std::max(f.col_max, o.f.col_max);
    f.slope_points += o.f.slope_points;
    f.slope_max_rad = std::max(f.slope_max_rad, o.f.slope_max_rad);
    sx += o.sx;
    sy += o.sy;
    sz += o.sz;
    s_range += o.s_range;
    slope_sum += o.slope_sum;
  }
};

}  // namespace

Detection BuildDetection(const RangeImage& image, const LevelPoints& level,
                         std::vector<std::int32_t> component,
                         const std::vector<std::uint8_t>& raised, float min_height,
                         const DetectionStats& stats, int threads) {
  const int n = image.size(), width = image.width(), height = image.height();
  Detection det;
  det.width = width;
  det.height = height;
  // The names become the labels in place (no array of the image's size to fault in).
  det.labels = std::move(component);
  det.foot.assign(n, 0);
  std::int32_t* const labels = det.labels.data();
  det.stats = stats;

  [[maybe_unused]] const int lanes = VectorLanes();
  // The segments' pixels, in row-major order (gathered in parts, joined in order): every
  // later pass visits only them.
  constexpr int kPixelParts = 8;
  std::array<std::vector<std::int32_t>, kPixelParts> gathered;
  ParallelFor(
      kPixelParts, threads,
      [&](int k) {
        // Filled here, not beside the other parts' headers; written at every pixel and
        // advanced at members (no branch to mispredict).
        const int begin = PartBegin(n, k, kPixelParts), end = PartBegin(n, k + 1, kPixelParts);
        std::vector<std::int32_t> part(end - begin);  // count <= i - begin at each write
        int count = 0, i = begin;
#if defined(CAIRN_OD_WIDE_VECTORS)
        if (lanes == 16) i = GatherMembersAvx512(labels, begin, end, part.data(), count);
        if (lanes == 8) i = GatherMembersAvx2(labels, begin, end, part.data(), count);
#endif
        for (; i < end; ++i) {
          part[count] = i;
          const std::int32_t name = labels[i];
          count += name >= 0;
          labels[i] = name >= 0 ? name : 0;  // no segment: label 0
        }
        part.resize(count);
        gathered[k] = std::move(part);
      },
      1);
  std::vector<std::int32_t> members;
  for (const auto& part : gathered) members.insert(members.end(), part.begin(), part.end());
  const int m = static_cast<int>(members.size());
  det.stats.obstacle_points = m;
  if (m == 0) return det;
  // Ids in row-major order of first pixels. A member other than its segment's first pixel
  // names a member before it, labelled already: its label is that one's (no array of the
  // image's size to clear and fill).
  int segments = 0;
  for (const int i : members) {
    const int before = labels[i];
    labels[i] = before == i ? ++segments : labels[before];
  }
  // The sums run over parts of the members, each part's per segment, added in order: how
  // the members are cut depends on the members only, so the result does not depend on the
  // threads. Parts hold at least 4096 members and 4 per segment (their sums' memory).
  const int parts = std::clamp(std::min(m / 4096, m / std::max(1, 4 * segments)), 1, 8);
  const auto part_begin = [&](int k) { return PartBegin(m, k, parts); };
  std::vector<Partial> partial(static_cast<std::size_t>(parts) * segments);
  // Surface slopes from each point's neighbours in its own segment.
  const bool wraps = std::holds_alternative<SphericalModel>(image.model());
  const auto at = [&](int j) { return Eigen::Vector3d(level.x[j], level.y[j], level.z[j]); };
  // The tangent along one line through i: neighbours `before` and `after` (-1: none).
  const auto tangent = [&](int i, int before, int after, Eigen::Vector3d& t) {
    const int id = det.labels[i];
    const bool b = before >= 0 && det.labels[before] == id;
    const bool a = after >= 0 && det.labels[after] == id;
    if (!a && !b) return false;
    t = (a ? at(after) : at(i)) - (b ? at(before) : at(i));
    return true;
  };
  ParallelFor(
      parts, threads,
      [&](int k) {
        Partial* sums = &partial[static_cast<std::size_t>(k) * segments];
        const int begin = part_begin(k), end = part_begin(k + 1);
        if (begin == end) return;
        // The members ascend: their row is followed, not divided out. Each run of them along
        // a row within one segment is summed on its own, then added to its segment's sums;
        // inside a run a point's row neighbours are its own segment's. The slopes' angles
        // wait for the end of a chunk, to be taken in one loop whose iterations overlap.
        int r = members[begin] / width, row_start = r * width;
        constexpr int kChunk = 256;
        double squares[kChunk], verticals[kChunk], slopes[kChunk];
        Partial* owners[kChunk];
        int pending = 0;
        const auto add_slopes = [&] {
          Inclinations(squares, verticals, slopes, pending);
          // Each owner's sums held in registers while its slopes follow each other (the
          // same additions in the same order).
          for (int j = 0; j < pending;) {
            Partial& s = *owners[j];
            double max = s.f.slope_max_rad, sum = s.slope_sum;
            const int first = j;
            for (; j < pending && owners[j] == &s; ++j) {
              max = std::max(max, slopes[j]);
              sum += slopes[j];
            }
            s.f.slope_points += j - first;
            s.f.slope_max_rad = max;
            s.slope_sum = sum;
          }
          pending = 0;
        };
        for (int mi = begin; mi < end;) {
          const int i0 = members[mi];
          while (i0 >= row_start + width) {
            row_start += width;
            ++r;
          }
          const int id = det.labels[i0], c0 = i0 - row_start;
          int len = 1;
          while (mi + len < end && members[mi + len] == i0 + len && c0 + len < width &&
                 det.labels[i0 + len] == id) {
            ++len;
          }
          mi += len;
          Partial& s = sums[id - 1];
          float lo[3] = {level.x[i0], level.y[i0], level.z[i0]}, hi[3] = {lo[0], lo[1], lo[2]};
          double sx = 0.0, sy = 0.0, sz = 0.0, s_range = 0.0;
          double range_min = std::numeric_limits<double>::infinity();
          int raised_points = 0;
          for (int j = 0; j < len; ++j) {
            const int i = i0 + j;
            const float x = level.x[i], y = level.y[i], z = level.z[i];
            ExtendBox(lo, hi, x, y, z);
            sx += x;
            sy += y;
            sz += z;
            const double range = image.range(i);
            s_range += range;
            range_min = std::min(range_min, range);
            raised_points += raised[i] != 0;
          }
          // The slopes, in the points' order. Inside the run both row neighbours are the
          // segment's; at its ends, as anywhere.
          const bool has_up = r > 0, has_down = r + 1 < height;
          const auto slope_at = [&](int j) {
            const int i = i0 + j;
            Eigen::Vector3d tu, tv;
            if (j > 0 && j + 1 < len) {
              tu = at(i + 1) - at(i - 1);
            } else {
              const int c = c0 + j;
              int left = c > 0 ? i - 1 : (wraps ? i + width - 1 : -1);
              int right = c + 1 < width ? i + 1 : (wraps ? i - c : -1);
              if (width == 1) left = right = -1;
              if (!tangent(i, left, right, tu)) return;
            }
            if (!tangent(i, has_up ? i - width : -1, has_down ? i + width : -1, tv)) return;
            const Eigen::Vector3d normal = tu.cross(tv);
            const double square = normal.x() * normal.x() + normal.y() * normal.y();
            if (!(square > 0.0 || normal.z() != 0.0)) return;
            if (pending == kChunk) add_slopes();
            squares[pending] = square;
            verticals[pending] = std::abs(normal.z());
            owners[pending++] = &s;
          };
          slope_at(0);
          int j = 1;
#if defined(CAIRN_OD_WIDE_VECTORS)
          if (lanes == 16) {  // the inner points eight at a time
            for (; j + 1 < len; j += 8) {
              if (pending + 8 > kChunk) add_slopes();
              const int kept =
                  InnerNormalsAvx512(level.x.data(), level.y.data(), level.z.data(), labels, i0 + j,
                                     std::min(8, len - 1 - j), width, has_up, has_down, id,
                                     squares + pending, verticals + pending);
              std::fill(owners + pending, owners + pending + kept, &s);
              pending += kept;
            }
          } else if (lanes == 8) {  // four at a time
            for (; j + 1 < len; j += 4) {
              if (pending + 4 > kChunk) add_slopes();
              const int kept =
                  InnerNormalsAvx2(level.x.data(), level.y.data(), level.z.data(), labels, i0 + j,
                                   std::min(4, len - 1 - j), width, has_up, has_down, id,
                                   squares + pending, verticals + pending);
              std::fill(owners + pending, owners + pending + kept, &s);
              pending += kept;
            }
          }
#endif
          for (; j + 1 < len; ++j) slope_at(j);
          if (len > 1) slope_at(len - 1);
          SegmentFeatures& f = s.f;
          f.point_count += len;
          f.raised_count += raised_points;
          f.bbox_min = f.bbox_min.cwiseMin(Eigen::Vector3f(lo[0], lo[1], lo[2]).cast<double>());
          f.bbox_max = f.bbox_max.cwiseMax(Eigen::Vector3f(hi[0], hi[1], hi[2]).cast<double>());
          f.range_min_m = std::min(f.range_min_m, range_min);
          f.row_min = std::min(f.row_min, r);
          f.row_max = std::max(f.row_max, r);
          f.col_min = std::min(f.col_min, c0);
          f.col_max = std::max(f.col_max, c0 + len - 1);
          s.sx += sx;
          s.sy += sy;
          s.sz += sz;
          s.s_range += s_range;
        }
        add_slopes();
      },
      1);
  for (int k = 1; k < parts; ++k) {
    for (int id = 0; id < segments; ++id) {
      partial[id].Add(partial[static_cast<std::size_t>(k) * segments + id]);
    }
  }
  det.segments.resize(segments);
  for (int id = 0; id < segments; ++id) {
    const Partial& s = partial[id];
    SegmentFeatures& f = det.segments[id];
    f = s.f;
    f.id = id + 1;
    const double np = f.point_count;
    const Eigen::Vector3d extent = f.bbox_max - f.bbox_min;
    f.bbox_perimeter_m = 2.0 * (extent.x() + extent.y());
    f.bbox_volume_m3 = extent.x() * extent.y() * extent.z();
    f.slope_mean_rad = f.slope_points > 0 ? s.slope_sum / f.slope_points : 0.0;
    f.centroid = Eigen::Vector3d(s.sx, s.sy, s.sz) / np;
    f.ground_height_m = f.bbox_min.z();
    f.height_mean_m = f.centroid.z() - f.bbox_min.z();
    f.height_max_m = f.bbox_max.z() - f.bbox_min.z();
    f.range_mean_m = s.s_range / np;
  }
  // Feet: not raised, and lower than HT above the segment's ground (counted per part).
  std::vector<int> feet(static_cast<std::size_t>(parts) * segments, 0);
  ParallelFor(
      parts, threads,
      [&](int k) {
        int* count = &feet[static_cast<std::size_t>(k) * segments];
        // The segment whose feet are being counted (0: none yet; ids start at 1), and its
        // count so far, added to its part's counts when another segment's points begin.
        int id = 0, feet_of_id = 0;
        double ground = 0.0;  // segment id's ground height
        // Raw pointers, the bounds and the ground held apart: the byte stores below may alias
        // anything, which would load each of them again at every member (captures too, such as
        // `labels`, which are read through the closure).
        const std::int32_t* const member = members.data();
        const std::int32_t* const label = det.labels.data();
        const std::uint8_t* const raised_of = raised.data();
        const float* const z = level.z.data();
        std::uint8_t* const foot_of = det.foot.data();
        const int begin = part_begin(k), end = part_begin(k + 1);
        for (int mi = begin; mi < end; ++mi) {
          const int i = member[mi];
          if (label[i] != id) {
            if (id > 0) count[id - 1] += feet_of_id;
            id = label[i];
            ground = det.segments[id - 1].ground_height_m;
            feet_of_id = 0;
          }
          const bool foot = raised_of[i] == 0 && z[i] - ground < min_height;
          foot_of[i] = foot;
          feet_of_id += foot;
        }
        if (id > 0) count[id - 1] += feet_of_id;
      },
      1);
  for (int k = 0; k < parts; ++k) {
    for (int id = 0; id < segments; ++id) {
      det.segments[id].foot_count += feet[static_cast<std::size_t>(k) * segments + id];
    }
  }
  return det;
}

}  // namespace cairn::od::internal
