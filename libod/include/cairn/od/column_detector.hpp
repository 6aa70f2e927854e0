// The column-wise baseline (Matthies 1996, Bellutta 2000: the DEMO III XUV detector).
//
// Slope and height are measured along each image column's range profile only: a pixel is
// an obstacle point when some pixel of the same column is compatible with it by the same
// pair test as the cone detector (HT, Hmax, theta). The obstacle mask is then blob-coloured
// in 2-D (8-connected) and blobs smaller than `min_blob_pixels` are dropped. It misses steep
// faces whose normal points away from the column's slicing plane, which is the case the
// cone detector was made for; it is kept as the reference every evaluation shows beside it.
#pragma once

#include "cairn/od/detector.hpp"

namespace cairn::od {

struct ColumnConfig {
  double min_height_m = 0.3;                  ///< HT [m]
  double max_height_m = 1.0;                  ///< Hmax [m]
  double min_slope_rad = 0.7853981633974483;  ///< theta [rad]
  int min_blob_pixels = 0;  ///< blobs with fewer pixels are rejected (0: keep all)
  double min_range_m = 0.0;  ///< DetectorConfig::min_range_m [m]

  /// The same pair parameters as a cone detector config, blob rejection off.
  static ColumnConfig From(const DetectorConfig& config);
  Status Validate() const;
};

/// Result in the cone detector's form: labels are the 8-connected blobs that survive the
/// area rejection, numbered in row-major order of their first pixel; features, feet and
/// stats follow the cone detector's definitions (detector.hpp). Cost: one pass over each
/// column. Where the processor has AVX2 or AVX-512F, a column of at most 64 points (a LiDAR
/// column) is tested whole: each point with something more than HT above it against every point
/// of the column, 8 or 16 at a time, so stats.pairs_tested counts every pair HT..Hmax apart. A
/// larger column (a camera's), and every column on narrower vectors, has its points sorted into
/// bins, plus one test per candidate pair within HT..Hmax in the bins next to it (where those bins
/// are dense, and on every column where the compiler has no SSE2 or the vector lanes are capped to
/// one, only up to each point's first partner above and below, or the first four or sixteen points
/// holding one, all of whose hits are marked: stats.pairs_compatible then counts the pairs found,
/// at most as many as there are, and stats.pairs_tested may count a pair from each end), and blob
/// colouring by runs.
Expected<Detection> DetectColumns(const RangeImage& image, const ColumnConfig& config);

/// The same result by the definition: every pair of points of each column tested, O(H^2)
/// per column. The reference the tests and benchmarks hold DetectColumns to (equal labels,
/// feet and features; its stats count every pair of a column tested and every compatible
/// pair).
Expected<Detection> DetectColumnsBruteForce(const RangeImage& image, const ColumnConfig& config);

}  // namespace cairn::od
