// What a detection leaves on disk, every file written atomically:
//   segments.png        16-bit, segment id per pixel, 0 = no obstacle point
//   classes.png         8-bit, SegmentClass per pixel: 0 none, 1 kept, 2 rejected
//   segments.json       per segment: class, rejection reason, every SegmentFeatures measure
//                       (units in the key names, slopes in degrees); image size, method and
//                       the settings used
//   overlay.png         grey depth (near bright, no return black), kept obstacle points
//                       blue, rejected ones red
//   segments_color.png  one deterministic colour per segment over the grey depth
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::od::io {

/// How a detection was made, recorded in segments.json.
struct RunDescription {
  std::string method = "cone";  ///< "cone" | "column"
  bool rules_applied = true;    ///< false: every segment kept (--no-rules)
  DetectSettings settings;
  std::string depth_file;  ///< inputs, as given (may be empty)
  std::string intrinsics_file;
  std::string config_file;  ///< empty: built-in defaults
};

/// Where WriteDetectionFiles put each file.
struct DetectionFiles {
  std::filesystem::path segments_png;
  std::filesystem::path classes_png;
  std::filesystem::path segments_json;
  std::filesystem::path overlay_png;
  std::filesystem::path segments_color_png;
};

/// Writes the five files into `dir` (created when missing). `depth_m` is the frame the
/// detection was made on (for the renderings); sizes must agree with `detection`.
Expected<DetectionFiles> WriteDetectionFiles(const std::filesystem::path& dir,
                                             const Grid<float>& depth_m, const Detection& detection,
                                             const Classification& classification,
                                             const RunDescription& run);

/// Single writers. Errors name the file. Segment ids above 65535 do not fit segments.png.
Status WriteSegmentsPng(const std::filesystem::path& path, const Detection& detection);
Status WriteClassesPng(const std::filesystem::path& path, const Detection& detection,
                       const Classification& classification);
Status WriteSegmentsJson(const std::filesystem::path& path, const Detection& detection,
                         const Classification& classification, const RunDescription& run);
Status WriteOverlayPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                       const Detection& detection, const Classification& classification);
Status WriteSegmentsColorPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                             const Detection& detection);

/// What WriteSegmentsJson writes, as text (for callers that keep it in memory, as the
/// Python module does). Fails, naming `where`, when the sizes disagree.
Expected<std::string> SegmentsJsonText(const std::string& where, const Detection& detection,
                                       const Classification& classification,
                                       const RunDescription& run);

/// Readers for evaluation and tests: segment ids and classes back from their PNGs.
Expected<Grid<std::int32_t>> ReadSegmentsPng(const std::filesystem::path& path);
Expected<Grid<std::uint8_t>> ReadClassesPng(const std::filesystem::path& path);

/// Grey rendering of depth, 8-bit: near bright, far dark, no return 0. Grey levels scale
/// with inverse depth between the frame's nearest and farthest returns.
Grid<std::uint8_t> RenderDepthGrey(const Grid<float>& depth_m);

/// Segment `id`'s colour, as {r, g, b}: distinct for neighbouring ids (golden-ratio hues),
/// the same on every run.
std::array<std::uint8_t, 3> SegmentColor(int id);

/// An 8-bit colour image in memory, {r, g, b} per pixel.
using RgbImage = Grid<std::array<std::uint8_t, 3>>;

/// What overlay.png and segments_color.png hold, as images in memory (for figures that put
/// several detections side by side). Fail, like the writers, when the sizes disagree.
Expected<RgbImage> RenderOverlay(const Grid<float>& depth_m, const Detection& detection,
                                 const Classification& classification);
Expected<RgbImage> RenderSegmentsColor(const Grid<float>& depth_m, const Detection& detection);

}  // namespace cairn::od::io
