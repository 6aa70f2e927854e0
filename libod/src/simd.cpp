#include "simd.hpp"

#include <algorithm>
#include <atomic>

namespace cairn::od::internal {
namespace {

int Widest() {
#if defined(CAIRN_OD_WIDE_VECTORS)
  __builtin_cpu_init();
  // The wide kernels count bits with POPCNT too (every processor with AVX2 has it).
  if (__builtin_cpu_supports("popcnt")) {
    if (__builtin_cpu_supports("avx512f")) return 16;
    if (__builtin_cpu_supports("avx2")) return 8;
  }
#endif
#if defined(__SSE2__)
  return 4;
#else
  return 1;
#endif
}

std::atomic<int> cap{0};

}  // namespace

int VectorLanes() {
  static const int widest = Widest();
  const int c = cap.load(std::memory_order_relaxed);
  return c > 0 ? std::min(c, widest) : widest;
}

void CapVectorLanes(int lanes) { cap.store(lanes, std::memory_order_relaxed); }

}  // namespace cairn::od::internal
