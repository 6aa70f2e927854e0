// Limits that protect memory: what the readers of cairn::od_io accept before they allocate.
// A file beyond one of them is refused with a message naming the file and the limit, never
// read into memory it would exhaust. They are far above any sensor cairn reads (a 64x2048
// scan holds 131072 points, a 1280x720 depth image 0.9 Mpx).
#pragma once

#include <cstddef>
#include <cstdint>

namespace cairn::od::io {

/// Width or height of an image (depth, grey, intrinsics) [px].
inline constexpr int kMaxImageSide = 16384;
/// Pixels of one image, width * height (64 Mpx: 256 MB as float depth).
inline constexpr std::int64_t kMaxImagePixels = std::int64_t{1} << 26;
/// Points of one scan file (.bin, PLY, text) and labels of one .label file (16.7 M: a .bin
/// of 268 MB).
inline constexpr std::size_t kMaxScanPoints = std::size_t{1} << 24;
/// Bytes of one text scan after bzip2 decompression (1 GiB).
inline constexpr std::size_t kMaxDecompressedBytes = std::size_t{1} << 30;
/// One allocation of the cairn command (2 GiB; apps/allocation_guard.cpp): above every
/// buffer the limits above allow (64 Mpx of double xyz is 1.5 GiB), so that a corrupt file
/// whose header claims billions of elements, which a third-party reader (MRPT's rawlog
/// deserialisation) allocates before it reads them, is refused as std::bad_alloc instead of
/// taking the machine's memory.
inline constexpr std::size_t kMaxAllocationBytes = std::size_t{1} << 31;

}  // namespace cairn::od::io
