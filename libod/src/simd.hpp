// Internal: how many float lanes the detectors' vector loops test at once. The library is
// built for x86-64's baseline (SSE2, four lanes); where the processor runs AVX2 (eight) or
// AVX-512F (sixteen), the loops that gain from it take the wider path, chosen once per process
// at run time: with AVX2 the exact search's hits, box tests, packing and its leaves' ranks by
// height, the column baseline's whole columns, the features' gathering of segment pixels,
// surface normals and slope angles (four doubles at a time, bit for bit; and libmap's
// free-space rays, ray_keys.hpp, eight under way, its terrain's plane fits, four cells at a
// time, and its placement of returns, four pixels at a time, terrain_map.cpp), with AVX-512F the
// same sixteen (or eight doubles) at a time, and also the column baseline's neighbourhoods and
// dense windows. The column baseline's gathering of columns and its binned columns' keys take AVX2
// with either. Capped to one lane, the searches run their scalar code (the level points are still
// rotated four at a time, and the features' angles taken two at a time). Every path does the pair
// test's float operations in the same order (no fused multiply-add: the library is built with
// -ffp-contract=off), so every width gives the same obstacle points, segments and features (the
// counts of pairs tested, and found where not every pair is sought, differ); the tests run each
// width the processor has against the definition and against each other.
#pragma once

#include <array>
#include <cstdint>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// The AVX2 and AVX-512F kernels, each function compiled for its instruction set alone.
#define CAIRN_OD_WIDE_VECTORS 1
#include <immintrin.h>
#endif

// Around AVX-512 kernels: GCC 12's AVX-512 intrinsics pass an undefined vector as an unused merge
// source, which -Wuninitialized and -Wmaybe-uninitialized report once inlined (GCC bug 105593,
// mended in GCC 13).
#if defined(__GNUC__) && !defined(__clang__)
#define CAIRN_OD_AVX512_KERNELS_BEGIN                                                        \
  _Pragma("GCC diagnostic push") _Pragma("GCC diagnostic ignored \"-Wmaybe-uninitialized\"") \
      _Pragma("GCC diagnostic ignored \"-Wuninitialized\"")
#define CAIRN_OD_AVX512_KERNELS_END _Pragma("GCC diagnostic pop")
#else
#define CAIRN_OD_AVX512_KERNELS_BEGIN
#define CAIRN_OD_AVX512_KERNELS_END
#endif

namespace cairn::od::internal {

/// 16 (AVX-512F), 8 (AVX2), 4 (SSE2) or 1 (one at a time): the widest the build and the
/// processor have, at most the cap.
int VectorLanes();

/// For each 8-bit mask, the lanes of its set bits from the lowest, four bits each: the
/// permutation that moves a register's chosen lanes to its front (AVX2 has no compress).
constexpr std::array<std::uint32_t, 256> PackLanes8() {
  std::array<std::uint32_t, 256> table{};
  for (unsigned mask = 0; mask < 256; ++mask) {
    std::uint32_t lanes = 0;
    int k = 0;
    for (unsigned lane = 0; lane < 8; ++lane) {
      if (mask >> lane & 1u) lanes |= lane << (4 * k++);
    }
    table[mask] = lanes;
  }
  return table;
}
inline constexpr std::array<std::uint32_t, 256> kPackLanes8 = PackLanes8();

#if defined(CAIRN_OD_WIDE_VECTORS)
/// The first n of eight 32-bit lanes, all ones (none when n <= 0, all when n >= 8).
__attribute__((target("avx2"))) inline __m256i FirstLanes8(int n) {
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(n), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}

/// The _mm256_permutevar8x32 indices that move the 32-bit lanes of `mask` (8 bits) to the
/// front, in their order (the lanes after them are left over).
__attribute__((target("avx2"))) inline __m256i ToFront8(unsigned mask) {
  return _mm256_srlv_epi32(_mm256_set1_epi32(static_cast<int>(kPackLanes8[mask])),
                           _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28));
}
#endif

#if defined(CAIRN_OD_WIDE_VECTORS)
// The lanes of `v` that `take` selects, stored side by side from `at` (what follows them is left
// as it was): a compress in a register and a masked store. Not the compress with a memory operand
// (_mm512_mask_compressstoreu_*), which Zen 4 runs as microcode: with it the exact search spent
// 15% of the KITTI scan packing leaves (BENCHMARKS.md).
__attribute__((target("avx512f,popcnt"))) inline void CompressStore(float* at, __mmask16 take,
                                                                    __m512 v) {
  const auto first = static_cast<__mmask16>((1u << __builtin_popcount(take)) - 1u);
  _mm512_mask_storeu_ps(at, first, _mm512_maskz_compress_ps(take, v));
}
__attribute__((target("avx512f,popcnt"))) inline void CompressStore(std::int32_t* at,
                                                                    __mmask16 take, __m512i v) {
  const auto first = static_cast<__mmask16>((1u << __builtin_popcount(take)) - 1u);
  _mm512_mask_storeu_epi32(at, first, _mm512_maskz_compress_epi32(take, v));
}
__attribute__((target("avx512f,popcnt"))) inline void CompressStore(double* at, __mmask8 take,
                                                                    __m512d v) {
  const auto first = static_cast<__mmask8>((1u << __builtin_popcount(take)) - 1u);
  _mm512_mask_storeu_pd(at, first, _mm512_maskz_compress_pd(take, v));
}
#endif

/// Tests: the vector loops use at most `lanes` (1, 4, 8 or 16) from now on, process-wide;
/// 0 lifts the cap.
void CapVectorLanes(int lanes);

}  // namespace cairn::od::internal
