// The process's resident memory, as Linux reports it in /proc/self/status: what `cairn map`
// records per frame (frames.csv rss_mb) and its peak (summary.json peak_rss_mb), so that a
// long run shows whether memory stays level once its rolling window is full.
#pragma once

namespace cairn::apps {

struct ProcessMemory {
  double rss_mb = 0.0;       ///< VmRSS: resident now [MiB]
  double peak_rss_mb = 0.0;  ///< VmHWM: the most resident so far [MiB]
};

/// Zeros where /proc/self/status cannot be read (not Linux).
ProcessMemory ReadProcessMemory();

}  // namespace cairn::apps
