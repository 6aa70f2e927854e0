// The process's resident memory, as Linux reports it in /proc/self/status: what `cairn map`
// records per frame (frames.csv rss_mb) and its peak (summary.json peak_rss_mb), so that a
// long run shows whether memory stays level once its rolling window is full.
#pragma once

namespace cairn::apps {

struct ProcessMemory {
  double rss_mb = 0.0;       ///< VmRSS: resident now [MiB]
  double peak_rss_mb = 0.0;  ///< VmHWM: the most resident so far [MiB]
  /// Bytes the program holds from malloc (glibc's mallinfo2 uordblks + hblkhd) [MiB]: when
  /// resident memory grows but this does not, the growth is the allocator's, not a leak.
  double heap_mb = 0.0;
};

/// Zeros where /proc/self/status cannot be read (not Linux).
ProcessMemory ReadProcessMemory();

/// Hands the allocator's free pages back to the system (glibc's malloc_trim). A rolling map
/// frees and reallocates octree nodes all the time; without this the freed pages stay
/// resident and memory creeps up (about 10 MiB per 1,000 frames on tools/long-run.sh) while
/// the bytes in use stay level. A no-op elsewhere.
void ReleaseFreeMemory();

/// Frames between two ReleaseFreeMemory calls of `cairn map`: a few milliseconds each, on a
/// map of 60 MiB.
inline constexpr int kTrimEveryFrames = 50;
/// ReleaseFreeMemory on every kTrimEveryFrames-th frame.
inline void ReleaseFreeMemoryEvery(int frame) {
  if (frame % kTrimEveryFrames == 0) ReleaseFreeMemory();
}

}  // namespace cairn::apps
