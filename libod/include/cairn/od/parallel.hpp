// One parallel loop for every cairn library, the core's exact search among them: items handed out a
// few at a time from a shared counter to up to `threads` threads, the calling thread among them.
// When each item's result depends on nothing but the item (or per-thread results are merged in an
// order-free way), the output does not depend on the number of threads.
//
// The helper threads are kept from one loop to the next (a pool that grows to the most threads
// loops have asked for at once; never destroyed: its idle threads end with the process), so that a
// loop of a few hundred microseconds, as the detector's stages are on one frame, is worth
// splitting. (TBB would do this, but Debian's build of it is not instrumented for ThreadSanitizer,
// which then reports races inside it; this pool is made of the standard library's threads, mutex
// and condition variables, which the CI's TSan stage checks.)
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <functional>
#include <thread>
#include <type_traits>

namespace cairn::od {

/// The threads a loop asked for `threads` runs on: `threads`, or one per hardware thread for
/// 0 (at least 1).
inline int ThreadCount(int threads) {
  return threads > 0 ? threads
                     : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

namespace internal {
/// Calls work(0) on the calling thread and work(1), work(2), ... on up to `helpers` of the
/// pool's threads, those free now or soon (the pool grows by `helpers` beyond the threads
/// busy or promised to other loops, as far as the system lets it); returns once every call
/// made has returned, with the number of calls made (1 + the helpers that joined). A helper
/// that comes after the caller's work(0) has returned is not called: `work` must share its
/// items through the caller's own counter. An exception from a call is rethrown here once
/// every call has returned (the caller's own first, else the first helper's).
int RunTeam(int helpers, const std::function<void(int)>& work);

/// The first item of part k of [0, n) cut into `parts` parts of nearly equal size.
inline int PartBegin(int n, int k, int parts) {
  return static_cast<int>(static_cast<std::int64_t>(n) * k / parts);
}
}  // namespace internal

/// Calls body(item), or body(worker, item) with worker in [0, threads) naming the thread
/// (for per-thread scratch), for every item in [0, count), on up to ThreadCount(threads)
/// threads and never more than one per `chunk` items. Returns the number of threads used.
/// `body` must be safe to call concurrently for different items. When a call throws, no
/// item is started after it, and the exception reaches the caller once the calls under way
/// have returned.
template <class Body>
int ParallelFor(int count, int threads, const Body& body, int chunk = 4) {
  chunk = std::max(chunk, 1);
  const int used = std::clamp(ThreadCount(threads), 1, std::max(1, count / chunk));
  const auto call = [&body](int worker, int item) {
    if constexpr (std::is_invocable_v<const Body&, int, int>) {
      body(worker, item);
    } else {
      body(item);
    }
  };
  if (used == 1) {
    for (int item = 0; item < count; ++item) call(0, item);
    return 1;
  }
  std::atomic<int> next{0};
  return internal::RunTeam(used - 1, [&](int worker) {
    try {
      for (int start = next.fetch_add(chunk); start < count; start = next.fetch_add(chunk)) {
        for (int item = start; item < std::min(count, start + chunk); ++item) call(worker, item);
      }
    } catch (...) {
      next.store(count);  // the others take no more items
      throw;
    }
  });
}

}  // namespace cairn::od
