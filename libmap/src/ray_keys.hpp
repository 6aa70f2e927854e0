// Internal: the voxels a ray crosses, as OctoMap's OcTreeBaseImpl::computeRayKeys finds
// them, handed to a callback instead of stored.
//
// computeRayKeys writes every key into a KeyRay (a vector of 100,000 keys made per call
// site) and picks each step's axis with unpredictable branches; a frame's free space is
// ten million such steps. This walk is the same 3-D DDA (Amanatides & Woo) in the same
// float and double arithmetic, so it visits the same keys in the same order (checked
// against computeRayKeys on random rays in tests/map/terrain_map_test.cpp): the origin's
// voxel first, the end's voxel never. It only calls f(key) for each.
//
// Each step waits on the one before (which axis is next decides the next comparison), so a
// frame's rays are walked several at a time (ForEachRayKeyInTurn): the same double
// operations, two rays to an SSE2 register (four under way) or, where the processor has AVX2
// (libod's simd.hpp), four to a register (eight under way, 1.1x quicker on the free-space
// benchmark), the axis picked by masks instead of branches, the key kept as a number that a
// step adds an axis' stride to (a bit's index in a box of bits). With AVX2 the rays' starts
// (RayWalk::Begin: the end's key, the direction, nine divisions) are also taken four to a
// register, 64 rays ahead (BeginRaysAvx2): one at a time, between the steps, they cost a
// quarter of the walk (FreeRays/walk 20.6 -> 15.3 ms, BENCHMARKS.md).
#pragma once

#include <octomap/OcTreeKey.h>
#include <octomap/octomap_types.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "simd.hpp"  // libod/src: the processor's vector width

#if defined(__SSE2__) && defined(__x86_64__)
#define CAIRN_RAY_LANES_SSE2 1
#include <emmintrin.h>
#endif

namespace cairn::map::internal {

/// Hands a key to f: as its three coordinates when f takes them (they stay in registers;
/// an OcTreeKey built in memory and read back whole stalls the walk on every step), else as
/// an OcTreeKey.
template <typename F>
void Visit(F& f, int k0, int k1, int k2) {
  if constexpr (std::is_invocable_v<F&, unsigned, unsigned, unsigned>) {
    f(static_cast<unsigned>(k0), static_cast<unsigned>(k1), static_cast<unsigned>(k2));
  } else {
    f(octomap::OcTreeKey(static_cast<octomap::key_type>(k0), static_cast<octomap::key_type>(k1),
                         static_cast<octomap::key_type>(k2)));
  }
}

/// One ray's walk, computeRayKeys' loop with its state in the open: Begin sets it up and
/// Next takes one step.
struct RayWalk {
  enum class Start { kOutside, kEmpty, kWalk };

  /// Sets up the walk from origin to end: kOutside when either lies outside the tree
  /// (computeRayKeys' false), kEmpty when both lie in one voxel (no key), else kWalk with
  /// the origin's voxel, the ray's first key, in k0, k1, k2.
  template <typename Tree>
  Start Begin(const Tree& tree, const octomap::point3d& origin, const octomap::point3d& end) {
    octomap::OcTreeKey key, key_end;
    if (!tree.coordToKeyChecked(origin, key) || !tree.coordToKeyChecked(end, key_end)) {
      return Start::kOutside;
    }
    if (key == key_end) return Start::kEmpty;
    octomap::point3d direction = end - origin;
    const float length = static_cast<float>(direction.norm());
    direction /= length;
    const double resolution = tree.getResolution();
    double t_max[3];
    for (int i = 0; i < 3; ++i) {
      step[i] = direction(i) > 0.0f ? 1 : (direction(i) < 0.0f ? -1 : 0);
      if (step[i] != 0) {
        // The border of the voxel on the ray's side, where the ray first leaves it along i.
        double border = tree.keyToCoord(key[i]);
        border += static_cast<float>(step[i] * resolution * 0.5);
        t_max[i] = (border - origin(i)) / direction(i);
        t_delta[i] = resolution / std::fabs(direction(i));
      } else {
        t_max[i] = t_delta[i] = std::numeric_limits<double>::max();
      }
    }
    t0 = t_max[0];
    t1 = t_max[1];
    t2 = t_max[2];
    k0 = key[0];
    k1 = key[1];
    k2 = key[2];
    e0 = key_end[0];
    e1 = key_end[1];
    e2 = key_end[2];
    length_m = length;
    return Start::kWalk;
  }

  /// One step: true with the next key in k0, k1, k2; false when the ray has ended (at the
  /// end's voxel, which is not a key of the ray).
  bool Next() {
    // The step's axis is the least t, ties as OctoMap breaks them (0 < 1, then < 2).
    const bool first_01 = t0 < t1;
    const double t01 = first_01 ? t0 : t1;
    const int dim = t01 < t2 ? (first_01 ? 0 : 1) : 2;
    k0 += dim == 0 ? step[0] : 0;
    k1 += dim == 1 ? step[1] : 0;
    k2 += dim == 2 ? step[2] : 0;
    t0 += dim == 0 ? t_delta[0] : 0.0;
    t1 += dim == 1 ? t_delta[1] : 0.0;
    t2 += dim == 2 ? t_delta[2] : 0.0;
    if (k0 == e0 && k1 == e1 && k2 == e2) return false;
    // Past the end's distance without meeting its voxel (rounding): stop, as OctoMap does.
    const double t_least01 = t0 < t1 ? t0 : t1;
    return (t_least01 < t2 ? t_least01 : t2) <= length_m;
  }

  double t0 = 0.0, t1 = 0.0, t2 = 0.0;  // where the ray leaves the voxel along each axis
  double t_delta[3] = {0.0, 0.0, 0.0};  // a voxel's length along the ray, per axis
  double length_m = 0.0;
  int k0 = 0, k1 = 0, k2 = 0;  // the key
  int e0 = 0, e1 = 0, e2 = 0;  // the end's key
  int step[3] = {0, 0, 0};
};

/// Calls f(key) for every voxel computeRayKeys(origin, end) would put in its ray. Returns
/// false, calling nothing, when origin or end lies outside the tree (computeRayKeys' false).
template <typename Tree, typename F>
bool ForEachRayKey(const Tree& tree, const octomap::point3d& origin, const octomap::point3d& end,
                   F&& f) {
  RayWalk walk;
  const RayWalk::Start start = walk.Begin(tree, origin, end);
  if (start != RayWalk::Start::kWalk) return start == RayWalk::Start::kEmpty;
  do {
    Visit(f, walk.k0, walk.k1, walk.k2);
  } while (walk.Next());
  return true;
}

/// How ForEachRayKeyInTurn numbers a key: sum over the axes of (k - lo) * stride, each
/// stride a multiple of the one before larger than its axis' span of keys, so that a step
/// along one axis is an addition of its stride (for example a box of keys' bits,
/// KeyBitBox).
struct KeyLayout {
  std::int64_t lo[3] = {0, 0, 0};
  std::int64_t stride[3] = {1, std::int64_t{1} << 21, std::int64_t{1} << 42};

  std::int64_t Of(int k0, int k1, int k2) const {
    return (k0 - lo[0]) * stride[0] + (k1 - lo[1]) * stride[1] + (k2 - lo[2]) * stride[2];
  }
  /// Key coordinate `axis` of the number n.
  int Axis(std::int64_t n, int axis) const {
    const std::int64_t below = axis == 2 ? n : n % stride[axis + 1];
    return static_cast<int>(below / stride[axis] + lo[axis]);
  }
};

#if defined(CAIRN_OD_WIDE_VECTORS)
/// Four rays under way, one to a lane of each register (ForEachRayKeyInTurnAvx2). A lane
/// without a ray has no length (it ends at every step) and is not live.
struct RayLanesAvx2 {
  __m256d t0, t1, t2;  // where each ray leaves its voxel along each axis
  __m256d d0, d1, d2;  // a voxel's length along the ray, per axis
  __m256d length;
  __m256i key, end;    // the key and the end's key, by their numbers
  __m256i s0, s1, s2;  // a step along each axis, as a number
  unsigned live = 0;
  unsigned pending = 0xfu;  // lanes to start the next ray on (every lane at first)
};

/// RayWalk::Begin of up to kRays rays at once, four at a time (AVX2), in its float and double
/// operations, so with its values: per ray, whether it walks, and its walk's state but for
/// the first key, which is the origin's for every ray. The key numbers are in `layout`.
struct RayStartsAvx2 {
  static constexpr int kRays = 64;
  alignas(32) double t0[kRays], t1[kRays], t2[kRays];  // where the ray leaves the origin's voxel
  alignas(32) double d0[kRays], d1[kRays], d2[kRays];  // a voxel's length along the ray, per axis
  alignas(32) double length[kRays];
  alignas(32) std::int64_t end[kRays];                       // the end's key, by its number
  alignas(32) std::int64_t s0[kRays], s1[kRays], s2[kRays];  // a step along each axis
  std::uint64_t walks = 0;                                   // bit r: ray r has keys (Start::kWalk)
};

/// Fills `out` for the rays from `origin` (inside the tree, its key `origin_key`) to the
/// centres of ends[0, count), count <= RayStartsAvx2::kRays.
template <typename Tree>
__attribute__((target("avx2"))) void BeginRaysAvx2(const Tree& tree, const octomap::point3d& origin,
                                                   const octomap::OcTreeKey& origin_key,
                                                   const octomap::OcTreeKey* ends, int count,
                                                   const KeyLayout& layout, RayStartsAvx2& out) {
  const double resolution = tree.getResolution();
  const __m256d res = _mm256_set1_pd(resolution);
  const __m256d factor = _mm256_set1_pd(1.0 / resolution);  // OctoMap's resolution_factor
  const __m256d half = _mm256_set1_pd(0.5);
  const __m256d sign = _mm256_set1_pd(-0.0);
  const __m256d most = _mm256_set1_pd(std::numeric_limits<double>::max());
  const int max_val = tree.coordToKey(0.0);  // OctoMap's tree_max_val
  const __m128i vmax = _mm_set1_epi32(max_val), vlimit = _mm_set1_epi32(2 * max_val);
  // The border of the origin's voxel on each side along each axis: its centre plus half a
  // voxel, as a float.
  __m256d border_up[3], border_down[3];
  for (int a = 0; a < 3; ++a) {
    const double centre = tree.keyToCoord(origin_key[a]);
    double up = centre, down = centre;
    up += static_cast<float>(1 * resolution * 0.5);
    down += static_cast<float>(-1 * resolution * 0.5);
    border_up[a] = _mm256_set1_pd(up);
    border_down[a] = _mm256_set1_pd(down);
  }
  out.walks = 0;
  for (int j = 0; j < count; j += 4) {
    alignas(16) std::int32_t k[3][4];
    for (int l = 0; l < 4; ++l) {
      // Lanes past the last ray repeat the origin's key (no walk).
      for (int a = 0; a < 3; ++a) k[a][l] = j + l < count ? ends[j + l][a] : origin_key[a];
    }
    __m128 dir[3];
    __m128i same = _mm_set1_epi32(-1), inside = _mm_set1_epi32(-1);
    __m256i number = _mm256_setzero_si256();
    for (int a = 0; a < 3; ++a) {
      const __m128i key = _mm_load_si128(reinterpret_cast<const __m128i*>(k[a]));
      // The end: keyToCoord(key) as floats; its key as coordToKeyChecked finds it.
      const __m128 end = _mm256_cvtpd_ps(
          _mm256_mul_pd(_mm256_add_pd(_mm256_cvtepi32_pd(_mm_sub_epi32(key, vmax)), half), res));
      const __m128i key_end = _mm_add_epi32(
          _mm256_cvttpd_epi32(_mm256_floor_pd(_mm256_mul_pd(factor, _mm256_cvtps_pd(end)))), vmax);
      inside = _mm_and_si128(inside, _mm_andnot_si128(_mm_cmplt_epi32(key_end, _mm_setzero_si128()),
                                                      _mm_cmplt_epi32(key_end, vlimit)));
      same = _mm_and_si128(same, _mm_cmpeq_epi32(key_end, _mm_set1_epi32(origin_key[a])));
      dir[a] = _mm_sub_ps(end, _mm_set1_ps(origin(a)));
      // (key_end - lo) * stride, in 64 bits (the difference is not negative: the box holds the
      // rays).
      const __m256i from_lo = _mm256_cvtepu32_epi64(
          _mm_sub_epi32(key_end, _mm_set1_epi32(static_cast<int>(layout.lo[a]))));
      const std::uint64_t stride = static_cast<std::uint64_t>(layout.stride[a]);
      const __m256i low = _mm256_mul_epu32(
          from_lo, _mm256_set1_epi64x(static_cast<long long>(stride & 0xffffffffu)));
      const __m256i high =
          _mm256_mul_epu32(from_lo, _mm256_set1_epi64x(static_cast<long long>(stride >> 32)));
      number = _mm256_add_epi64(number, _mm256_add_epi64(low, _mm256_slli_epi64(high, 32)));
    }
    _mm256_store_si256(reinterpret_cast<__m256i*>(out.end + j), number);
    const unsigned walks =
        static_cast<unsigned>(_mm_movemask_ps(_mm_castsi128_ps(_mm_andnot_si128(same, inside))));
    out.walks |= static_cast<std::uint64_t>(walks) << j;
    // The direction normalised by its float length (octomath's norm: the float sum, its double
    // square root).
    const __m128 norm2 =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(dir[0], dir[0]), _mm_mul_ps(dir[1], dir[1])),
                   _mm_mul_ps(dir[2], dir[2]));
    const __m128 length = _mm256_cvtpd_ps(_mm256_sqrt_pd(_mm256_cvtps_pd(norm2)));
    _mm256_store_pd(out.length + j, _mm256_cvtps_pd(length));
    double* const t_out[3] = {out.t0 + j, out.t1 + j, out.t2 + j};
    double* const d_out[3] = {out.d0 + j, out.d1 + j, out.d2 + j};
    std::int64_t* const s_out[3] = {out.s0 + j, out.s1 + j, out.s2 + j};
    for (int a = 0; a < 3; ++a) {
      const __m256d d = _mm256_cvtps_pd(_mm_div_ps(dir[a], length));
      const __m256d up = _mm256_cmp_pd(d, _mm256_setzero_pd(), _CMP_GT_OQ);
      const __m256d down = _mm256_cmp_pd(d, _mm256_setzero_pd(), _CMP_LT_OQ);
      const __m256d border = _mm256_blendv_pd(border_down[a], border_up[a], up);
      const __m256d moves = _mm256_or_pd(up, down);
      const __m256d t_max =
          _mm256_div_pd(_mm256_sub_pd(border, _mm256_set1_pd(static_cast<double>(origin(a)))), d);
      const __m256d t_delta = _mm256_div_pd(res, _mm256_andnot_pd(sign, d));
      _mm256_store_pd(t_out[a], _mm256_blendv_pd(most, t_max, moves));
      _mm256_store_pd(d_out[a], _mm256_blendv_pd(most, t_delta, moves));
      const std::int64_t stride = layout.stride[a];
      const __m256i step = _mm256_blendv_epi8(
          _mm256_and_si256(_mm256_castpd_si256(down), _mm256_set1_epi64x(-stride)),
          _mm256_set1_epi64x(stride), _mm256_castpd_si256(up));
      _mm256_store_si256(reinterpret_cast<__m256i*>(s_out[a]), step);
    }
  }
}

/// The pending lanes of `v` each take the next ray of [first + next, first + count) that has
/// keys (its first key, the origin's `origin_number`, handed to f), or are left without a ray
/// when there are no more. `starts` holds the rays from `chunk` on (BeginRaysAvx2), and is
/// filled afresh past them.
template <typename Tree, typename F>
__attribute__((target("avx2"), always_inline)) inline void StartRaysAvx2(
    RayLanesAvx2& v, std::size_t (&ray)[4], const Tree& tree, const octomap::point3d& origin,
    const octomap::OcTreeKey& origin_key, std::int64_t origin_number,
    const octomap::OcTreeKey* first, std::size_t count, std::size_t& next, std::size_t& chunk,
    RayStartsAvx2& starts, const KeyLayout& layout, F& f) {
  for (unsigned m = v.pending; m != 0; m &= m - 1) {
    const int l = __builtin_ctz(m);
    v.live &= ~(1u << l);
    while (next < count) {
      if (next >= chunk + RayStartsAvx2::kRays) {
        chunk = next;
        BeginRaysAvx2(tree, origin, origin_key, first + chunk,
                      static_cast<int>(std::min<std::size_t>(RayStartsAvx2::kRays, count - chunk)),
                      layout, starts);
      }
      const std::size_t r = next++;
      const std::size_t i = r - chunk;
      if (!(starts.walks >> i & 1)) continue;
      const __m256i lane =  // all ones in lane l
          _mm256_cmpeq_epi64(_mm256_set_epi64x(3, 2, 1, 0), _mm256_set1_epi64x(l));
      const __m256d lane_pd = _mm256_castsi256_pd(lane);
      v.t0 = _mm256_blendv_pd(v.t0, _mm256_set1_pd(starts.t0[i]), lane_pd);
      v.t1 = _mm256_blendv_pd(v.t1, _mm256_set1_pd(starts.t1[i]), lane_pd);
      v.t2 = _mm256_blendv_pd(v.t2, _mm256_set1_pd(starts.t2[i]), lane_pd);
      v.d0 = _mm256_blendv_pd(v.d0, _mm256_set1_pd(starts.d0[i]), lane_pd);
      v.d1 = _mm256_blendv_pd(v.d1, _mm256_set1_pd(starts.d1[i]), lane_pd);
      v.d2 = _mm256_blendv_pd(v.d2, _mm256_set1_pd(starts.d2[i]), lane_pd);
      v.length = _mm256_blendv_pd(v.length, _mm256_set1_pd(starts.length[i]), lane_pd);
      v.key = _mm256_blendv_epi8(v.key, _mm256_set1_epi64x(origin_number), lane);
      v.end = _mm256_blendv_epi8(v.end, _mm256_set1_epi64x(starts.end[i]), lane);
      v.s0 = _mm256_blendv_epi8(v.s0, _mm256_set1_epi64x(starts.s0[i]), lane);
      v.s1 = _mm256_blendv_epi8(v.s1, _mm256_set1_epi64x(starts.s1[i]), lane);
      v.s2 = _mm256_blendv_epi8(v.s2, _mm256_set1_epi64x(starts.s2[i]), lane);
      ray[l] = r;
      v.live |= 1u << l;
      f(r, origin_number);
      break;
    }
  }
  v.pending = 0;
}

/// One step of the live rays of `v`, in the scalar walk's double operations: f(ray, key) for
/// those that go on; those that end are marked pending.
template <typename F>
__attribute__((target("avx2"), always_inline)) inline void StepRaysAvx2(RayLanesAvx2& v,
                                                                        const std::size_t (&ray)[4],
                                                                        F& f) {
  // The least t, ties to the lower axis.
  const __m256d first_01 = _mm256_cmp_pd(v.t0, v.t1, _CMP_LT_OQ);
  const __m256d t01 = _mm256_min_pd(v.t0, v.t1);  // t0 < t1 ? t0 : t1
  const __m256d before_2 = _mm256_cmp_pd(t01, v.t2, _CMP_LT_OQ);
  const __m256d on0 = _mm256_and_pd(first_01, before_2);
  const __m256d on1 = _mm256_andnot_pd(first_01, before_2);
  v.t0 = _mm256_add_pd(v.t0, _mm256_and_pd(on0, v.d0));
  v.t1 = _mm256_add_pd(v.t1, _mm256_and_pd(on1, v.d1));
  v.t2 = _mm256_add_pd(v.t2, _mm256_andnot_pd(before_2, v.d2));
  const __m256i move =
      _mm256_or_si256(_mm256_or_si256(_mm256_and_si256(_mm256_castpd_si256(on0), v.s0),
                                      _mm256_and_si256(_mm256_castpd_si256(on1), v.s1)),
                      _mm256_andnot_si256(_mm256_castpd_si256(before_2), v.s2));
  v.key = _mm256_add_epi64(v.key, move);
  const __m256d least = _mm256_min_pd(_mm256_min_pd(v.t0, v.t1), v.t2);
  const __m256d at_end = _mm256_castsi256_pd(_mm256_cmpeq_epi64(v.key, v.end));
  v.pending = static_cast<unsigned>(_mm256_movemask_pd(
                  _mm256_or_pd(at_end, _mm256_cmp_pd(least, v.length, _CMP_GT_OQ)))) &
              v.live;
  const unsigned go_on = v.live & ~v.pending;
  const __m128i low = _mm256_castsi256_si128(v.key);
  const __m128i high = _mm256_extracti128_si256(v.key, 1);
  if (go_on & 1u) f(ray[0], static_cast<std::int64_t>(_mm_cvtsi128_si64(low)));
  if (go_on & 2u) f(ray[1], static_cast<std::int64_t>(_mm_extract_epi64(low, 1)));
  if (go_on & 4u) f(ray[2], static_cast<std::int64_t>(_mm_cvtsi128_si64(high)));
  if (go_on & 8u) f(ray[3], static_cast<std::int64_t>(_mm_extract_epi64(high, 1)));
}

/// ForEachRayKeyInTurn where the processor has AVX2: eight rays under way, four to a register
/// (two registers' steps overlap). A ray that ends hands its lane to the next ray there and
/// then; the others walk on.
template <typename Tree, typename F>
__attribute__((target("avx2"))) void ForEachRayKeyInTurnAvx2(const Tree& tree,
                                                             const octomap::point3d& origin,
                                                             const octomap::OcTreeKey* first,
                                                             const octomap::OcTreeKey* last,
                                                             const KeyLayout& layout, F& f) {
  const std::size_t count = static_cast<std::size_t>(last - first);
  octomap::OcTreeKey origin_key;
  if (!tree.coordToKeyChecked(origin, origin_key)) return;  // RayWalk::Begin's kOutside
  const std::int64_t origin_number = layout.Of(origin_key[0], origin_key[1], origin_key[2]);
  std::size_t next = 0;
  std::size_t chunk = 0;
  RayStartsAvx2 starts;
  BeginRaysAvx2(tree, origin, origin_key, first,
                static_cast<int>(std::min<std::size_t>(RayStartsAvx2::kRays, count)), layout,
                starts);
  RayLanesAvx2 a, b;
  a.t0 = a.t1 = a.t2 = a.d0 = a.d1 = a.d2 = _mm256_setzero_pd();
  a.length = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
  a.key = a.end = a.s0 = a.s1 = a.s2 = _mm256_setzero_si256();
  b = a;
  std::size_t ray_a[4] = {}, ray_b[4] = {};
  for (;;) {
    if ((a.pending | b.pending) != 0) {
      StartRaysAvx2(a, ray_a, tree, origin, origin_key, origin_number, first, count, next, chunk,
                    starts, layout, f);
      StartRaysAvx2(b, ray_b, tree, origin, origin_key, origin_number, first, count, next, chunk,
                    starts, layout, f);
      if ((a.live | b.live) == 0) return;
    }
    StepRaysAvx2(a, ray_a, f);
    StepRaysAvx2(b, ray_b, f);
  }
}
#endif

/// ForEachRayKey from `origin` to the centre of each key in [first, last), four rays at a
/// time, eight with AVX2 (each step of a walk waits on the one before; the steps of the rays
/// under way overlap): calls f(ray, n) for every key of every ray, `ray` the end's index in
/// [first, last) and n the key's number in `layout`, each ray's keys in its order (those of
/// the rays under way interleave). Every key of a ray must have a number in `layout` (a box:
/// the keys between the origin's and the end's, one more on each side). Rays that
/// ForEachRayKey would not walk (the origin outside the tree) are skipped.
template <typename Tree, typename F>
void ForEachRayKeyInTurn(const Tree& tree, const octomap::point3d& origin,
                         const octomap::OcTreeKey* first, const octomap::OcTreeKey* last,
                         const KeyLayout& layout, F&& f) {
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (od::internal::VectorLanes() >= 8) {
    ForEachRayKeyInTurnAvx2(tree, origin, first, last, layout, f);
    return;
  }
#endif
  constexpr int kLanes = 4;
  const std::size_t count = static_cast<std::size_t>(last - first);
  std::size_t next = 0;
  RayWalk lane[kLanes];
  std::int64_t number[kLanes] = {};  // the lane's key by its number (lane's k0, k1, k2 go stale)
  std::size_t ray[kLanes] = {};
  // Starts the next ray on lane l with its first key; false when there are no more.
  const auto start = [&](int l) {
    while (next < count) {
      ray[l] = next++;
      if (lane[l].Begin(tree, origin, tree.keyToCoord(first[ray[l]])) == RayWalk::Start::kWalk) {
        number[l] = layout.Of(lane[l].k0, lane[l].k1, lane[l].k2);
        f(ray[l], number[l]);
        return true;
      }
    }
    return false;
  };
  bool live[kLanes];
  bool all_live = true;
  for (int l = 0; l < kLanes; ++l) all_live = (live[l] = start(l)) && all_live;
#if defined(CAIRN_RAY_LANES_SSE2)
  // Two lanes per register, the keys by their numbers, the axis picked by masks, in the
  // scalar walk's double operations.
  while (all_live) {
    __m128d t0[2], t1[2], t2[2], d0[2], d1[2], d2[2], length[2];
    __m128i key[2], end[2], s0[2], s1[2], s2[2];
    const auto both = [](std::int64_t lo, std::int64_t hi) {
      return _mm_set_epi64x(static_cast<long long>(hi), static_cast<long long>(lo));
    };
    for (int p = 0; p < 2; ++p) {
      const RayWalk& a = lane[2 * p];
      const RayWalk& b = lane[2 * p + 1];
      t0[p] = _mm_set_pd(b.t0, a.t0);
      t1[p] = _mm_set_pd(b.t1, a.t1);
      t2[p] = _mm_set_pd(b.t2, a.t2);
      d0[p] = _mm_set_pd(b.t_delta[0], a.t_delta[0]);
      d1[p] = _mm_set_pd(b.t_delta[1], a.t_delta[1]);
      d2[p] = _mm_set_pd(b.t_delta[2], a.t_delta[2]);
      length[p] = _mm_set_pd(b.length_m, a.length_m);
      key[p] = both(number[2 * p], number[2 * p + 1]);
      end[p] = both(layout.Of(a.e0, a.e1, a.e2), layout.Of(b.e0, b.e1, b.e2));
      s0[p] = both(a.step[0] * layout.stride[0], b.step[0] * layout.stride[0]);
      s1[p] = both(a.step[1] * layout.stride[1], b.step[1] * layout.stride[1]);
      s2[p] = both(a.step[2] * layout.stride[2], b.step[2] * layout.stride[2]);
    }
    int done = 0;
    while (done == 0) {
#pragma GCC unroll 2
      for (int p = 0; p < 2; ++p) {
        const __m128d first_01 = _mm_cmplt_pd(t0[p], t1[p]);
        const __m128d t01 = _mm_min_pd(t0[p], t1[p]);  // t0 < t1 ? t0 : t1
        const __m128d before_2 = _mm_cmplt_pd(t01, t2[p]);
        const __m128d on0 = _mm_and_pd(first_01, before_2);
        const __m128d on1 = _mm_andnot_pd(first_01, before_2);
        t0[p] = _mm_add_pd(t0[p], _mm_and_pd(on0, d0[p]));
        t1[p] = _mm_add_pd(t1[p], _mm_and_pd(on1, d1[p]));
        t2[p] = _mm_add_pd(t2[p], _mm_andnot_pd(before_2, d2[p]));
        const __m128i move = _mm_or_si128(_mm_or_si128(_mm_and_si128(_mm_castpd_si128(on0), s0[p]),
                                                       _mm_and_si128(_mm_castpd_si128(on1), s1[p])),
                                          _mm_andnot_si128(_mm_castpd_si128(before_2), s2[p]));
        key[p] = _mm_add_epi64(key[p], move);
        const __m128i eq32 = _mm_cmpeq_epi32(key[p], end[p]);
        const __m128i at_end = _mm_and_si128(eq32, _mm_shuffle_epi32(eq32, 0xb1));
        const __m128d least = _mm_min_pd(_mm_min_pd(t0[p], t1[p]), t2[p]);
        const int ended =
            _mm_movemask_pd(_mm_or_pd(_mm_castsi128_pd(at_end), _mm_cmpgt_pd(least, length[p])));
        if (!(ended & 1)) f(ray[2 * p], static_cast<std::int64_t>(_mm_cvtsi128_si64(key[p])));
        if (!(ended & 2)) {
          f(ray[2 * p + 1],
            static_cast<std::int64_t>(_mm_cvtsi128_si64(_mm_unpackhi_epi64(key[p], key[p]))));
        }
        done |= ended << (2 * p);
      }
    }
    // Back into the lanes; the ended ones start their next rays.
    alignas(16) double v0[2], v1[2], v2[2];
    for (int p = 0; p < 2; ++p) {
      _mm_store_pd(v0, t0[p]);
      _mm_store_pd(v1, t1[p]);
      _mm_store_pd(v2, t2[p]);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(number + 2 * p), key[p]);
      for (int h = 0; h < 2; ++h) {
        RayWalk& w = lane[2 * p + h];
        w.t0 = v0[h];
        w.t1 = v1[h];
        w.t2 = v2[h];
      }
    }
    for (int l = 0; l < kLanes; ++l) {
      if (done >> l & 1) all_live = (live[l] = start(l)) && all_live;
    }
  }
#endif
  // The rays still under way, one at a time.
  for (int l = 0; l < kLanes; ++l) {
    if (live[l]) {
      lane[l].k0 = layout.Axis(number[l], 0);
      lane[l].k1 = layout.Axis(number[l], 1);
      lane[l].k2 = layout.Axis(number[l], 2);
    }
    while (live[l]) {
      while (lane[l].Next()) f(ray[l], layout.Of(lane[l].k0, lane[l].k1, lane[l].k2));
      live[l] = start(l);
    }
  }
}

}  // namespace cairn::map::internal
