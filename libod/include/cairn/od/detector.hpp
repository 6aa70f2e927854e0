// The cone detector of Talukder, Manduchi, Rankin and Matthies (IEEE IV 2002) on one range
// image: OD-2 (obstacle points by scanning the projected upper cone of each pixel) and OS-2
// (segments as the connected components of the compatibility graph) in one pass.
//
// Definitions (heights h along gravity's up vector, points in the level frame):
//  - p1, p2 are compatible when HT < |h2 - h1| < Hmax and |h2 - h1| / |p2 - p1| > sin(theta),
//    i.e. the line joining them is steeper than theta from the horizontal;
//  - an obstacle point has at least one compatible partner;
//  - a segment is a connected component of the graph whose edges are the compatible pairs.
// Each pair is found once, from its lower point. Detect bounds blocks of points (a tree of
// pixel rectangles, each rectangle's points split in space, with their 3-D boxes): block pairs that
// provably hold no compatible pair are skipped, block pairs that provably hold only compatible
// pairs are joined at once, and block pairs that can change nothing are skipped; the result equals
// DetectBruteForce's, point for point and segment for segment. DetectRegionScan, the earlier
// method, scans for each point the pixels onto which its upper cone (height HT..Hmax above it,
// half-angle 90 deg - theta about `up`) can project; it is kept as the reference that
// benchmarks and tests compare with, and it runs the paper's square window.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od {

enum class SearchMode {
  kExact,        ///< every compatible pair: the O(N^2) definition's result (default)
  kPaperWindow,  ///< the paper's square window above the pixel: an approximation
};

struct DetectorConfig {
  double min_height_m = 0.3;               ///< HT: least height of an obstacle [m]
  double max_height_m = 1.0;               ///< Hmax: bounds the search, splits obstacles [m]
  double min_slope_rad = 0.7853981633974483;  ///< theta, from the horizontal [rad] (45 deg)
  SearchMode search = SearchMode::kExact;
  /// kPaperWindow: the window's side is this many times the image size of an HT-tall
  /// object at the pixel's range (the paper uses 4-5); it spans from the pixel upwards and
  /// is centred on its column.
  double window_scale = 4.5;
  /// DetectRegionScan: the cone is bounded by this many height slabs, each by the bounding
  /// box of its projection; more slabs give a tighter region and cost more per pixel.
  /// Exactness does not depend on it.
  int region_slabs = 4;
  /// Worker threads; 0 uses every hardware thread. The result does not depend on it.
  int threads = 0;
  /// Returns nearer than this to the sensor [m] are no returns (the vehicle's own body, the
  /// sensor's blind zone): neither obstacle points nor partners. 0 keeps every return.
  double min_range_m = 0.0;

  /// Names the first bad field by its config-file key (min_height, max_height, min_slope in
  /// degrees, window_scale, region_slabs): 0 < HT < Hmax, 0 < theta < 90 deg, window_scale > 0,
  /// region_slabs in 1..64, threads in 0..256, all finite.
  Status Validate() const;
};

/// 3-D measures of one segment, computed from its points and its compatible pairs.
/// Coordinates are in the level frame of the image (sensor-centred, z up along gravity).
struct SegmentFeatures {
  int id = 0;                 ///< segment id, 1..n (0 is "no segment")
  int point_count = 0;        ///< obstacle points (pixels) in the segment
  int foot_count = 0;         ///< of which its foot (Detection::foot)
  /// Of which the upper point of some compatible pair: the points that stand HT..Hmax above,
  /// and steeper than theta from, another point of the segment (all but its foot and the
  /// lowest HT of its body). (Until 2026-12 segments counted their compatible pairs instead:
  /// on dense obstacles that meant billions, one by one.)
  int raised_count = 0;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();  ///< axis-aligned box, level frame [m]
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
  /// Perimeter of the box's footprint on the horizontal plane: 2 (dx + dy) [m].
  double bbox_perimeter_m = 0.0;
  /// Volume of the box: dx * dy * dz [m^3].
  double bbox_volume_m3 = 0.0;
  /// Slope of the surface at a point, as the paper's section 1 defines slope: the angle of
  /// its normal from up, in [0, 90 deg]. The normal is the cross product of the point's
  /// tangents along the row and along the column, each the difference of its two
  /// neighbours on that line that belong to the same segment (central), or of the one
  /// neighbour and the point (one-sided); columns wrap on spherical images. Points with no
  /// such neighbour on a line, or a degenerate normal, have no slope. Mean and max over
  /// the segment's points that have one; 0 when none has [rad]. (Until 2026-12 these were
  /// the mean and max slope of the segment's compatible pairs, which cost a slope per pair.)
  double slope_mean_rad = 0.0;
  double slope_max_rad = 0.0;
  int slope_points = 0;       ///< points with a slope
  /// Ground under the segment: the height of its lowest point, where its lowest compatible
  /// pair meets the terrain [m, level frame].
  double ground_height_m = 0.0;
  /// Height of the segment's points above ground_height_m: mean and max [m]. The max is the
  /// obstacle's height as the vehicle meets it.
  double height_mean_m = 0.0;
  double height_max_m = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  ///< mean of its points [m]
  /// Distance of its points from the sensor: mean and min [m].
  double range_mean_m = 0.0;
  double range_min_m = 0.0;
  /// Image extent, inclusive [px].
  int row_min = 0, row_max = 0, col_min = 0, col_max = 0;
};

/// Counters that show how much work a detection did.
/// Work counters, not results: Detect (and DetectColumns on dense columns) skips the pairs
/// that can change nothing, so its pairs_compatible is at most the number of compatible
/// pairs, which DetectRegionScan and DetectBruteForce (and DetectColumnsBruteForce) count
/// exactly; DetectColumns' pairs_tested may count a pair once from each end.
struct DetectionStats {
  std::int64_t pairs_tested = 0;      ///< pairs tested point by point (Detect: HT..Hmax apart)
  std::int64_t pairs_compatible = 0;  ///< compatible pairs found (in blocks or one by one)
  std::int64_t node_pairs = 0;        ///< Detect: block pairs not rejected at once
  std::int64_t blocks_accepted = 0;   ///< Detect: block pairs compatible whole
  int obstacle_points = 0;
};

struct Detection {
  int width = 0;
  int height = 0;
  /// Segment id per pixel, row-major; 0 where the pixel is no obstacle point. Ids are
  /// numbered 1..n in the order of each segment's first pixel in row-major order.
  std::vector<std::int32_t> labels;
  /// segments[id - 1] describes segment `id`.
  std::vector<SegmentFeatures> segments;
  DetectionStats stats;
  /// Per pixel, row-major: 1 where an obstacle point is its segment's *foot*: it is the
  /// upper point of no compatible pair (nothing lies HT..Hmax below it in its cone) and it
  /// lies less than HT above the segment's ground (ground_height_m, its lowest point). That
  /// is the terrain at an obstacle's base, within min(height, Hmax) / tan(theta) of it, and
  /// the obstacle's own lowest HT: points the paper's definition joins to the obstacle,
  /// compatible with it, that a vehicle could drive over. 0 elsewhere.
  std::vector<std::uint8_t> foot;

  bool is_obstacle(int index) const { return labels[index] != 0; }
  bool is_foot(int index) const {
    return static_cast<std::size_t>(index) < foot.size() && foot[index] != 0;
  }
};

/// `detection` with its feet taken out: labels are 0 at foot points, so that the foot
/// counts as ground (what a cost map wants). Segments, their ids and features stay those of
/// the whole segment; stats.obstacle_points counts the points left. A Detection whose foot
/// is empty (made by hand) comes back as it is.
Detection WithoutFeet(Detection detection);

/// OD-2 + OS-2 on one range image. Fails only when the config does not validate.
/// kExact bounds blocks of points (see above); kPaperWindow runs DetectRegionScan's scan
/// over the paper's window.
Expected<Detection> Detect(const RangeImage& image, const DetectorConfig& config);

/// OD-2 + OS-2 by scanning each pixel's search region (the projected cone in kExact mode,
/// the paper's window in kPaperWindow): the earlier method, kept as the reference. Equal to
/// Detect in kExact mode, and slower.
Expected<Detection> DetectRegionScan(const RangeImage& image, const DetectorConfig& config);

/// The definition, by testing every pair of valid points: O(N^2), for tests and benchmarks.
/// Ignores config.search.
Expected<Detection> DetectBruteForce(const RangeImage& image, const DetectorConfig& config);

/// True when p_upper lies in the upper cone of p_lower (level-frame coordinates, z up):
/// HT < dz < Hmax and dz^2 > tan^2(theta) (dx^2 + dy^2). Shared by every detector so that
/// they agree bit for bit; NaN coordinates are never compatible.
struct PairTest {
  float min_height;
  float max_height;
  float tan2_theta;
  explicit PairTest(const DetectorConfig& config);
  bool operator()(float dx, float dy, float dz) const {
    return dz > min_height && dz < max_height && dz * dz > tan2_theta * (dx * dx + dy * dy);
  }
};

}  // namespace cairn::od
