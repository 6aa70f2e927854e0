// 16-bit z-depth PNGs: one unsigned value per pixel, metres = value * depth_scale, 0 = no
// return (the TUM RGB-D convention, where depth_scale = 1/5000 m).
#pragma once

#include <filesystem>

#include "cairn/od/expected.hpp"
#include "cairn/od/io/grid.hpp"
#include "cairn/od/io/intrinsics.hpp"

namespace cairn::od::io {

/// Reads a depth PNG into metres (0 where there is no return). Fails when the file is
/// missing or unreadable, is not 16-bit single-channel, or is not width x height.
Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path, int width, int height,
                                   double depth_scale_m);

/// The same with the size and scale of `intrinsics`.
Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path,
                                   const CameraIntrinsics& intrinsics);

/// Writes depths [m] as a 16-bit PNG (atomically): value = round(depth / depth_scale).
/// Non-finite or non-positive depths become 0 (no return); a depth beyond
/// 65535 * depth_scale is an error, since clipping it would invent a surface.
Status WriteDepthPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                     double depth_scale_m);

}  // namespace cairn::od::io
