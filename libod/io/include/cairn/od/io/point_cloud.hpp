// LiDAR point clouds at the edge: scans in (KITTI-layout `.bin`, PLY, "x y z" text, plain or
// bzip2-compressed), SemanticKITTI-layout `.label` files out, the ring/column layout of each
// point (from a preset or found in the data), and a bird's-eye rendering.
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
#include "cairn/od/sensor_model.hpp"

namespace cairn::od::io {

/// A scan as stored: points in input order (no return = (0, 0, 0), as KITTI and Ouster
/// write it), with their intensities and, when the file has them, their ring numbers.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;  ///< sensor frame [m]
  std::vector<float> intensity;         ///< one per point, sensor units (0 when not stored)
  /// One per point from the file's ring field (PLY `ring`, as Ouster and Velodyne drivers
  /// write it: the laser's number, not necessarily top first); empty when the file has none.
  std::vector<std::int32_t> ring;
};

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

/// How points map to range-image rows (rings) and columns (azimuth steps).
enum class OrganisedMode {
  kAuto,  ///< organised when the data says so (see ResolveLayout, FindLayout)
  kYes,   ///< index = col * rings + ring; fails when the count is not a multiple of rings
  kNo,    ///< never the storage order; with a preset, rows from its nearest nominal ring
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
/// FindLayout below also finds rings without a preset, from ring fields, ring-after-ring
/// order and elevations, and measures their elevations; this stays for callers that want
/// the preset's nominal model.
Expected<PointLayout> ResolveLayout(const PointCloud& cloud, const SphericalModel& preset,
                                    OrganisedMode mode, const std::string& source);

/// Where a layout's rows came from.
enum class RingSource {
  kRingField,          ///< the file's ring numbers (PointCloud::ring)
  kOrganised,          ///< the storage order: index = col * rings + ring
  kRingBreaks,         ///< ring after ring in the storage order (KITTI), cut at each turn
  kElevationClusters,  ///< separate peaks of the elevation histogram
  kNominal,            ///< the preset's nearest nominal ring
  kUniformBins,        ///< no rings: equal elevation bins
};

/// "ring field", "organised", "ring breaks", "elevation clusters", "nominal rings" or
/// "uniform elevation bins".
const char* RingSourceName(RingSource source);

/// What FindLayout may use.
struct LayoutOptions {
  /// A sensor preset (SphericalModel::Preset): its ring count must match the rings found
  /// in the data, else rows come from its nominal elevations. Empty: the data decides.
  std::optional<SphericalModel> preset;
  OrganisedMode organised = OrganisedMode::kAuto;  ///< kNo: never the storage order
  /// Azimuth steps of a scan that is not organised; 0: the preset's width, or else measured
  /// on the data (MeasureAzimuthSteps; square cells for uniform bins).
  int columns = 0;
  ElevationRingOptions elevation;  ///< how elevation clusters are told apart
};

/// Ring-after-ring storage found in a point order.
struct RingBreaks {
  int rings = 0;
  std::vector<std::int32_t> ring;  ///< per point in storage order (-1 for no return)
  double seam_rad = 0.0;           ///< azimuth where each ring starts [rad]
};

/// Finds the rings of a scan stored ring after ring (KITTI's `.bin`): within a ring the
/// azimuth sweeps one way by small steps; a new ring starts where the azimuth, measured
/// from the seam (where rings start), falls back by more than half a turn. The seam is
/// first the first return's azimuth, then placed, between the scan's last return and its
/// first, where the elevation steps by a ring spacing in most rings (rings join there with
/// no azimuth gap). Fails, saying why, when the order is not ring after ring: fewer than 3
/// rings, under 90% of the steps small and one way, azimuth jumps of more than 10 degrees
/// back within rings (tilting-laser lines), or the median ring sweeping under 3/4 of a
/// turn (firing-order scans). A ring without any return cannot be seen, nor a break where
/// one ring ends and the next starts on the same side of the seam with no return across.
Expected<RingBreaks> FindRingBreaks(const std::vector<Eigen::Vector3f>& points);
/// The same with the points' angles computed already.
Expected<RingBreaks> FindRingBreaks(const std::vector<Eigen::Vector3f>& points,
                                    const PointAngles& angles);

/// A scan's layout: every point's row and column, and the model of its range image.
struct FoundLayout {
  RingSource source = RingSource::kNominal;
  SphericalModel model;
  std::vector<std::int32_t> rows;  ///< per point, -1 for no return
  std::vector<std::int32_t> cols;  ///< per point, -1 for no return
  /// Why earlier sources were passed over (e.g. a preset whose ring count disagrees with
  /// the data), for the user; empty when the first applicable source was taken.
  std::string note;
};

/// The layout of a scan, every point with its row and column. Rows, in this order of
/// preference: the ring field; the storage order (organised: with a preset, its ring
/// count; else every ring count that divides the point count is tried, and the one whose
/// rows have distinct, tight elevations and whose azimuth follows the column is taken);
/// ring breaks; elevation clusters; then the preset's nominal rings, or uniform elevation
/// bins without a preset. `OrganisedMode::kNo` with a preset goes straight to its nominal
/// rings (the old behaviour of ResolveLayout). The model holds the measured ring
/// elevations, top first; columns not given by the storage order are centred on the
/// returns' azimuths (FitAzimuthStart), with +x in the middle column. `source` names the
/// cloud in errors.
Expected<FoundLayout> FindLayout(const PointCloud& cloud, const LayoutOptions& options,
                                 const std::string& source);

/// A scan in its range image: the layout FindLayout finds and the image FromPoints makes
/// of it with gravity's `up_sensor` (LiDAR frame). What `cairn detect --points` and the
/// Python module do with a scan once it is read; `source` names the cloud in errors.
struct PlacedScan {
  FoundLayout layout;
  RangeImage image;
};
Expected<PlacedScan> PlaceScan(const PointCloud& cloud, const LayoutOptions& options,
                               const Eigen::Vector3d& up_sensor, const std::string& source);

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
