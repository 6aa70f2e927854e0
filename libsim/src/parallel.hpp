// A parallel loop over rows for the renderers, internal to cairn_sim. Rows are handed out
// in small chunks from a shared counter; each row's result depends on nothing but the row,
// so the output does not depend on the number of threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace cairn::sim::detail {

/// Calls body(row) for row in [0, rows) on up to `threads` threads (0: one per hardware
/// thread). `body` must be safe to call concurrently for different rows.
template <class Body>
void ParallelRows(int rows, int threads, const Body& body) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min(threads, std::max(1, rows / 4));
  if (threads <= 1) {
    for (int row = 0; row < rows; ++row) body(row);
    return;
  }
  constexpr int kChunk = 4;
  std::atomic<int> next{0};
  auto work = [&] {
    for (int start = next.fetch_add(kChunk); start < rows; start = next.fetch_add(kChunk)) {
      for (int row = start; row < std::min(rows, start + kChunk); ++row) body(row);
    }
  };
  std::vector<std::thread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace cairn::sim::detail
