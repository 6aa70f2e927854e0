// Crash-safe file writing: the bytes go to a temporary file in the destination's directory,
// are flushed to disk, and the temporary is renamed over the destination. A reader sees the
// old file or the new one, never a half-written one, and a failed write leaves no temporary.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

#include "cairn/od/expected.hpp"

namespace cairn::util {

/// Writes `bytes` to `path` atomically (POSIX rename). The directory must exist. Errors
/// name the file and the system's reason.
Status WriteFileAtomic(const std::filesystem::path& path, std::string_view bytes);

/// For a log that only grows and whose committed length is kept elsewhere (a checkpoint):
/// cuts `path` to its first `at` bytes (creating it when missing), writes `bytes` there and
/// flushes them to disk. Whatever an earlier, interrupted call left beyond `at` is dropped;
/// the first `at` bytes are never touched. Fails, naming the file, when it holds fewer.
Status WriteFileAt(const std::filesystem::path& path, std::uint64_t at, std::string_view bytes);

}  // namespace cairn::util
