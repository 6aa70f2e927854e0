// Scoring one detection against per-pixel ground truth.
//
// A *detected point* is a pixel of a kept segment (rejected segments count as not
// detected). A *true obstacle point* is a valid pixel that sees an obstacle object.
//
// Per point: precision, recall, F1 and IoU of the obstacle points, twice:
//  - strict: every valid pixel counts; terrain a segment covers is a false positive;
//  - foot band excluded: terrain pixels in an obstacle's foot band are left out. By the
//    paper's definition terrain near an obstacle's foot pairs with the obstacle and is
//    marked (a ground point p and an obstacle point q higher by dh are compatible when
//    HT < dh < Hmax and q is within dh / tan(theta) of p horizontally; the rim of a ditch
//    likewise pairs with its walls below), so marking it is the method working as defined,
//    not a false detection. Recall is the same both ways
//    (band pixels are terrain, never true obstacle points).
//
// Per object (obstacle objects with at least `min_object_pixels` valid pixels; smaller
// ones are listed as not counted, neither found nor missed):
//  - found: at least `found_fraction` of its valid pixels are detected points;
//  - a kept segment is a *false obstacle* when less than `false_fraction` of its pixels
//    lie on obstacle objects or in their foot bands.
// Segmentation: a segment and an obstacle object are *linked* when they share at least
// `link_fraction` of the smaller of (the object's detected pixels, the segment's pixels).
// Segments per found object and obstacle objects per true (not false) kept segment, mean
// and max: 1 and 1 is a perfect segmentation; more segments per object is
// over-segmentation, more objects per segment is merging (touching objects in one).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cairn/eval/truth.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::eval {

struct ScoreOptions {
  double found_fraction = 0.5;  ///< share of an object's pixels detected to find it, (0, 1]
  int min_object_pixels = 20;   ///< objects seen by fewer valid pixels are not counted [px]
  double false_fraction = 0.2;  ///< kept segment with less of it on obstacles is false, (0, 1]
  double link_fraction = 0.1;   ///< overlap that links a segment and an object, (0, 1]

  /// Names the first field out of range.
  Status Validate() const;
};

/// The terrain pixels that the definition pairs with an obstacle: a terrain pixel t is in
/// the foot band of obstacle object o when some valid pixel q of o differs in height from t
/// by dh != 0 and lies within min(|dh|, Hmax) / tan(theta) of it horizontally (heights along
/// the image's up vector, level frame). For a pole or a rock, q is above t (the ground at its
/// foot); for a ditch, below it (the rim). Returns, per pixel, the id of such an obstacle
/// object (when several qualify, the farthest-reaching one found) or 0. Exact: points are
/// binned in horizontal cells only to skip those that cannot reach t.
std::vector<std::int32_t> FootBand(const od::RangeImage& image, const FrameTruth& truth,
                                   double max_height_m, double min_slope_rad);

/// Point counts of one or more frames; ratios are NaN when undefined (0 / 0).
struct PointCounts {
  std::int64_t tp = 0;  ///< detected and a true obstacle point
  std::int64_t fp = 0;  ///< detected, not a true obstacle point
  std::int64_t fn = 0;  ///< a true obstacle point, not detected

  double Precision() const;
  double Recall() const;
  double F1() const;
  double IoU() const;  ///< tp / (tp + fp + fn)
  PointCounts& operator+=(const PointCounts& o);
};

/// Everything that adds up over frames (each ratio is recomputed from the sums).
struct Score {
  PointCounts strict;
  PointCounts band_excluded;     ///< foot-band terrain pixels left out
  std::int64_t band_pixels = 0;  ///< terrain pixels in a foot band
  int objects_counted = 0;       ///< obstacle objects with enough valid pixels
  int objects_found = 0;
  int objects_small = 0;          ///< obstacle objects seen, too small to count
  int non_obstacles_counted = 0;  ///< non-obstacle objects with enough valid pixels
  int non_obstacles_marked = 0;   ///< ..of which found_fraction or more was detected
  int segments = 0;               ///< segments of the detection, kept or not
  int kept_segments = 0;
  int false_obstacles = 0;                   ///< kept segments with no true obstacle under them
  std::int64_t segments_per_object_sum = 0;  ///< over found objects
  int segments_per_object_max = 0;
  std::int64_t objects_per_segment_sum = 0;  ///< over true kept segments
  int true_segments = 0;                     ///< kept segments that are not false
  int objects_per_segment_max = 0;
  int merged_segments = 0;  ///< true kept segments linked to two or more obstacle objects
  int frames = 0;

  double FoundRate() const;          ///< objects_found / objects_counted (NaN when none)
  double SegmentsPerObject() const;  ///< mean over found objects (NaN when none)
  double ObjectsPerSegment() const;  ///< mean over true kept segments (NaN when none)
  Score& operator+=(const Score& o);
};

/// What happened to one object.
struct ObjectOutcome {
  int id = 0;
  std::string name;
  bool is_obstacle = true;
  int pixels = 0;    ///< valid pixels
  int detected = 0;  ///< of which detected points
  bool counted = false;
  bool found = false;  ///< counted and detected >= found_fraction * pixels
  int segments = 0;    ///< kept segments linked to it (obstacles only)
};

/// What one segment of the detection is.
struct SegmentOutcome {
  int id = 0;
  bool kept = true;
  int pixels = 0;
  int on_obstacles = 0;         ///< pixels on obstacle objects or in their foot bands
  bool false_obstacle = false;  ///< kept and on_obstacles < false_fraction * pixels
  int objects = 0;              ///< obstacle objects linked to it
};

struct FrameScore {
  Score score;
  std::vector<ObjectOutcome> objects;    ///< every object the truth lists, by id
  std::vector<SegmentOutcome> segments;  ///< segments[id - 1]
};

/// Scores `detection` with its classification against `truth`. `foot_band` is FootBand's
/// output for the same frame (empty: no band, both counts equal). Fails when sizes differ
/// or the options do not validate.
Expected<FrameScore> ScoreDetection(const FrameTruth& truth,
                                    const std::vector<std::int32_t>& foot_band,
                                    const od::Detection& detection,
                                    const od::Classification& classification,
                                    const ScoreOptions& options = {});

}  // namespace cairn::eval
