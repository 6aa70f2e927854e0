// LiDAR point clouds at the edge: KITTI-layout `.bin` scans in, SemanticKITTI-layout `.label`
// files out, the ring/column layout of each point, and a bird's-eye rendering.
//
// `.bin`: float32 x, y, z [m], intensity per point, little-endian, 16 bytes per point, in the
// sensor frame (x forward, y left, z up). `.label`: one uint32 per point, same order,
// little-endian; lower 16 bits a class, upper 16 bits an instance (here: segment) id.
// Readers validate and name the file in every error; writers are atomic.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::od::io {

/// A scan as stored: points in input order (no return = (0, 0, 0), as KITTI and Ouster
/// write it), with their intensities.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;  ///< sensor frame [m]
  std::vector<float> intensity;         ///< one per point, sensor units
};

/// Reads a KITTI-layout `.bin`. Fails, naming the file, when it is missing or unreadable,
/// when its size is not a multiple of 16 bytes (truncated), or when a coordinate is not
/// finite (the message gives the point's index).
Expected<PointCloud> ReadKittiBin(const std::filesystem::path& path);

/// Writes a KITTI-layout `.bin` atomically (intensity 0 when `cloud.intensity` is empty).
Status WriteKittiBin(const std::filesystem::path& path, const PointCloud& cloud);

/// How points map to range-image rows (rings) and columns (azimuth steps).
enum class OrganisedMode {
  kAuto,  ///< organised when the data says so (see ResolveLayout)
  kYes,   ///< index = col * rings + ring; fails when the count is not a multiple of rings
  kNo,    ///< rows from the nearest nominal ring, columns from the azimuth
};

/// Each point's cell, and the model that the range image uses.
struct PointLayout {
  bool organised = false;
  SphericalModel model;  ///< width = columns; azimuth_start fitted to the data when organised
  std::vector<std::int32_t> rows;  ///< per point; empty when unorganised (FromPoints computes)
  std::vector<std::int32_t> cols;  ///< per point; empty when unorganised
};

/// Decides the layout of `cloud` for a sensor with `rings` = preset.height() rings.
/// Organised (Ouster order, index = col * rings + ring, ring 0 the top beam, azimuth
/// decreasing with col; e.g. 131072 = 64 x 2048): in kAuto mode, when the count is a
/// multiple of the ring count and, over the returns, elevation falls with the ring index
/// within columns and the azimuth follows the column (both for at least 90% of the
/// neighbouring pairs). Unorganised: `preset` as given (its width is the azimuth
/// resolution), rows from the nearest elevation. `source` names the cloud in errors.
Expected<PointLayout> ResolveLayout(const PointCloud& cloud, const SphericalModel& preset,
                                    OrganisedMode mode, const std::string& source);

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

/// Each return as a pixel coloured by `point_class` (one per point: 0 grey, 1 kept blue,
/// 2 rejected red); obstacle points drawn last so that the ground does not hide them.
/// Points are levelled with the image's up vector. Fails on size mismatches or bad options.
Expected<RgbImage> RenderBirdsEye(const RangeImage& image,
                                  const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::uint8_t>& point_class,
                                  const BirdsEyeOptions& options = {});

/// Writes an RGB image as an 8-bit colour PNG, atomically.
Status WriteRgbPng(const std::filesystem::path& path, const RgbImage& image);

}  // namespace cairn::od::io
