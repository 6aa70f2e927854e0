// LiDAR point clouds at the edge: scans in (KITTI-layout `.bin`, PLY, "x y z" text, plain or
// bzip2-compressed), SemanticKITTI-layout `.label` files out, and a bird's-eye rendering. The
// ring/column layout of each point (from a preset or found in the data) is an algorithm of
// the core: cairn/od/scan_layout.hpp.
//
// `.bin`: float32 x, y, z [m], intensity per point, little-endian, 16 bytes per point, in the
// sensor frame (x forward, y left, z up). `.label`: one uint32 per point, same order,
// little-endian; lower 16 bits a class, upper 16 bits an instance (here: segment) id.
// Readers validate and name the file in every error, with the byte offset or line of the
// fault and what was expected; writers are atomic. Memory limits (limits.hpp): at most
// kMaxScanPoints points or labels per file, checked from the file size or the PLY header
// before anything is allocated, and kMaxDecompressedBytes of text out of a .bz2.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/limits.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/scan_layout.hpp"  // PointCloud and the layout of its points
#include "cairn/od/sensor_model.hpp"

namespace cairn::od::io {

// Non-finite values. A point whose x, y and z are all NaN is a no return and is stored as
// (0, 0, 0) (PCL writes organised clouds that way); any other NaN or infinity in a
// coordinate or an intensity is an error naming the point and its byte offset or line.

/// Reads a KITTI-layout `.bin`. Fails, naming the file, when it is missing, unreadable or
/// empty, when its size is not a multiple of 16 bytes (truncated: the message gives the
/// size and the offset of the incomplete point), or on a non-finite value (the point's
/// index and byte offset).
Expected<PointCloud> ReadKittiBin(const std::filesystem::path& path);

/// Reads the vertices of a PLY file (ascii or binary_little_endian 1.0): properties x, y, z
/// (required), intensity and ring (optional), any others skipped; every scalar PLY type.
/// Elements before `vertex` must have no list properties. Fails, naming the file, on a
/// malformed header (the line), a missing x/y/z, a big-endian body, a body shorter than
/// the header announces (byte offset or line), no vertices, or non-finite values.
Expected<PointCloud> ReadPly(const std::filesystem::path& path);

/// Reads a text scan: one point per line as "x y z" or "x y z intensity", separated by
/// blanks or commas; empty lines and lines starting with '#' skipped. A name ending in
/// `.bz2` is decompressed first (bzip2). Fails, naming the file and the line, on a line
/// with fewer than 3 or more than 4 numbers or a non-number, on a corrupt bzip2 stream, or
/// when there is no point.
Expected<PointCloud> ReadXyzText(const std::filesystem::path& path);

/// Any of the above, chosen by content and name: a file beginning with "ply" is PLY; a
/// name ending in .bin is KITTI; .txt, .xyz, .dat, .pts, .asc, .csv (each optionally
/// .bz2) are text. Fails, naming the file, on other names.
Expected<PointCloud> ReadPointFile(const std::filesystem::path& path);

/// Writes a KITTI-layout `.bin` atomically (intensity 0 when `cloud.intensity` is empty).
Status WriteKittiBin(const std::filesystem::path& path, const PointCloud& cloud);

/// Per-point labels in SemanticKITTI layout: lower 16 bits the SegmentClass of the point's
/// cell (0 none, 1 kept, 2 rejected; 0 for no return), upper 16 bits its segment id (0
/// none). `image` must come from FromPoints and `detection` be made on it. Fails when a
/// segment id does not fit 16 bits.
Expected<std::vector<std::uint32_t>> PointLabels(const RangeImage& image,
                                                 const Detection& detection,
                                                 const Classification& classification);

/// `.label` files: uint32 per point, little-endian. The reader fails, naming the file, when
/// it is missing or its size is not a multiple of 4 bytes; the writer is atomic.
Status WriteLabelFile(const std::filesystem::path& path, const std::vector<std::uint32_t>& labels);
Expected<std::vector<std::uint32_t>> ReadLabelFile(const std::filesystem::path& path);

/// Range image as a grid [m] (Euclidean range per cell, 0 where no return), for the image
/// renderers of detection_files.hpp.
Grid<float> RangeGrid(const RangeImage& image);

/// Top view of the level frame (x forward up the image, y left to the left), sensor at the
/// centre. Default: 0.05 m per pixel (5 m per 100 px) over +-30 m, 1200 x 1200 px.
struct BirdsEyeOptions {
  double metres_per_pixel = 0.05;  ///< [m/px]
  double half_extent_m = 30.0;     ///< shown: |x|, |y| up to this [m]
};

/// point_class of RenderBirdsEye for the foot of a kept segment (Detection::foot).
inline constexpr std::uint8_t kBirdsEyeFoot = 3;

/// Each return as a pixel coloured by `point_class` (one per point: 0 grey, 1 kept blue,
/// 2 rejected red, kBirdsEyeFoot light blue); obstacle points drawn last so that the ground
/// does not hide them.
/// Points are levelled with the image's up vector. Fails on size mismatches or bad options.
Expected<RgbImage> RenderBirdsEye(const RangeImage& image,
                                  const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::uint8_t>& point_class,
                                  const BirdsEyeOptions& options = {});

/// Writes an RGB image as an 8-bit colour PNG, atomically.
Status WriteRgbPng(const std::filesystem::path& path, const RgbImage& image);

/// Where WriteScanOutputs put each file.
struct ScanOutputs {
  DetectionFiles images;            ///< segments.png, classes.png, segments.json, overlay, colours
  std::filesystem::path labels;     ///< labels.label
  std::filesystem::path birds_eye;  ///< birds_eye.png
  std::vector<std::uint32_t> point_labels;  ///< what labels.label holds
};

/// Everything a detection on one scan leaves in `dir` (created when missing): the files of
/// WriteDetectionFiles for its range image, labels.label (PointLabels) and birds_eye.png.
/// `image` must come from FromPoints(points, ...) and `detection` be made on it.
Expected<ScanOutputs> WriteScanOutputs(const std::filesystem::path& dir, const RangeImage& image,
                                       const std::vector<Eigen::Vector3f>& points,
                                       const Detection& detection,
                                       const Classification& classification,
                                       const RunDescription& run);

}  // namespace cairn::od::io
