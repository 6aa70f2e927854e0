// One parallel loop for every cairn library, the core's exact search among them: items handed out a
// few at a time from a shared counter to up to `threads` threads, the calling thread among them.
// When each item's result depends on nothing but the item (or per-thread results are merged in an
// order-free way), the output does not depend on the number of threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <system_error>
#include <thread>
#include <type_traits>
#include <vector>

namespace cairn::od {

/// The threads a loop asked for `threads` runs on: `threads`, or one per hardware thread for
/// 0 (at least 1).
inline int ThreadCount(int threads) {
  return threads > 0 ? threads
                     : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

/// Calls body(item), or body(worker, item) with worker in [0, threads) naming the thread
/// (for per-thread scratch), for every item in [0, count), on up to ThreadCount(threads)
/// threads and never more than one per `chunk` items. Returns the number of threads used.
/// `body` must be safe to call concurrently for different items.
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
  const auto work = [&](int worker) {
    for (int start = next.fetch_add(chunk); start < count; start = next.fetch_add(chunk)) {
      for (int item = start; item < std::min(count, start + chunk); ++item) call(worker, item);
    }
  };
  std::vector<std::thread> pool;
  for (int worker = 1; worker < used; ++worker) {
    // A thread the system cannot start (EAGAIN on a loaded machine) leaves its share to the
    // others, which take items from the same counter; throwing here would terminate the
    // program through the threads already started.
    try {
      pool.emplace_back(work, worker);
    } catch (const std::system_error&) {
      break;
    }
  }
  work(0);
  for (std::thread& thread : pool) thread.join();
  return static_cast<int>(pool.size()) + 1;  // workers 0 .. pool.size() ran
}

}  // namespace cairn::od
