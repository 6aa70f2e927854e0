#include "process_memory.hpp"

#include <malloc.h>

#include <fstream>
#include <sstream>
#include <string>

namespace cairn::apps {

ProcessMemory ReadProcessMemory() {
  ProcessMemory m;
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    double* field = line.rfind("VmRSS:", 0) == 0   ? &m.rss_mb
                    : line.rfind("VmHWM:", 0) == 0 ? &m.peak_rss_mb
                                                   : nullptr;
    if (field == nullptr) continue;
    std::istringstream value(line.substr(6));
    double kib = 0.0;
    if (value >> kib) *field = kib / 1024.0;  // the kernel reports kB (KiB)
  }
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  const struct mallinfo2 info = mallinfo2();
  m.heap_mb = static_cast<double>(info.uordblks + info.hblkhd) / (1024.0 * 1024.0);
#endif
  return m;
}

void ReleaseFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace cairn::apps
