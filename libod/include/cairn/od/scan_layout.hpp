// A LiDAR scan as stored, and where each of its points goes on the range image: its ring
// (row) and azimuth step (column), from a sensor preset or found in the data itself: the
// file's ring field, the storage order (organised scans, ring after ring), separate
// elevation clusters, or else nominal rings or uniform elevation bins. The readers of scan
// files are in cairn/od/io/point_cloud.hpp; the ring fits these use are in sensor_model.hpp.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::od {

/// A scan as stored: points in input order (no return = (0, 0, 0), as KITTI and Ouster
/// write it), with their intensities and, when the file has them, their ring numbers.
struct PointCloud {
  std::vector<Eigen::Vector3f> points;  ///< sensor frame [m]
  std::vector<float> intensity;         ///< one per point, sensor units (0 when not stored)
  /// One per point from the file's ring field (PLY `ring`, as Ouster and Velodyne drivers
  /// write it: the laser's number, not necessarily top first); empty when the file has none.
  std::vector<std::int32_t> ring;
};

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

}  // namespace cairn::od
