// Z-depth images: 16-bit PNGs (one unsigned value per pixel, metres = value * depth_scale,
// 0 = no return: the TUM RGB-D convention, where depth_scale = 1/5000 m) and 32-bit float
// TIFFs (metres as they are; 0, negative or non-finite = no return). ReadDepthImage tells
// the two apart by the file's signature, so callers need not care which they were given.
#pragma once

#include <filesystem>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
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

/// Reads a 32-bit float single-channel TIFF of metres (depth_scale does not apply); 0,
/// negative, NaN or infinite values become 0 (no return). A 16-bit single-channel TIFF is
/// read like a PNG, value * depth_scale_m. Fails like ReadDepthPng.
Expected<Grid<float>> ReadDepthTiff(const std::filesystem::path& path, int width, int height,
                                    double depth_scale_m);

/// A 16-bit PNG or a float (or 16-bit) TIFF, by the file's signature; any other file is an
/// error naming the formats expected.
Expected<Grid<float>> ReadDepthImage(const std::filesystem::path& path, int width, int height,
                                     double depth_scale_m);
Expected<Grid<float>> ReadDepthImage(const std::filesystem::path& path,
                                     const CameraIntrinsics& intrinsics);

/// Writes depths [m] as a 32-bit float TIFF (atomically), exactly; non-finite or
/// non-positive depths become 0 (no return).
Status WriteDepthTiff(const std::filesystem::path& path, const Grid<float>& depth_m);

}  // namespace cairn::od::io
