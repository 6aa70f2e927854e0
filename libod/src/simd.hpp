// Internal: how many float lanes the detectors' vector loops test at once. The library is
// built for x86-64's baseline (SSE2, four lanes); where the processor runs AVX2 (eight) or
// AVX-512F (sixteen), the loops that gain from it take the wider path, chosen once per process
// at run time: with AVX2 the exact search's hits, box tests, packing and its leaves' ranks by
// height, the column baseline's whole columns (and libmap's free-space rays, ray_keys.hpp, eight
// under way in double), with AVX-512F the same sixteen at a time, and also the column
// baseline's neighbourhoods and dense windows, and the features' gathering of segment pixels,
// surface normals and slope angles (in double, bit for bit). Capped to one lane, the searches
// run their scalar code (the level points are still rotated four at a time, and the features'
// angles taken two at a time).
// Every path does the pair test's float operations in the same order (no fused multiply-add:
// the library is built with -ffp-contract=off), so every width gives the same obstacle points,
// segments and features (the counts of pairs tested, and found where not every pair is sought,
// differ); the tests run each width the processor has against the definition and against each
// other.
#pragma once

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

/// Tests: the vector loops use at most `lanes` (1, 4, 8 or 16) from now on, process-wide;
/// 0 lifts the cap.
void CapVectorLanes(int lanes);

}  // namespace cairn::od::internal
