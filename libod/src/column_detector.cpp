#include "cairn/od/column_detector.hpp"

#include <string>

#include "detection_internal.hpp"
#include "pair_search.hpp"

namespace cairn::od {

ColumnConfig ColumnConfig::From(const DetectorConfig& config) {
  ColumnConfig c;
  c.min_height_m = config.min_height_m;
  c.max_height_m = config.max_height_m;
  c.min_slope_rad = config.min_slope_rad;
  c.min_range_m = config.min_range_m;
  return c;
}

namespace {

DetectorConfig PairParameters(const ColumnConfig& config) {
  DetectorConfig d;
  d.min_height_m = config.min_height_m;
  d.max_height_m = config.max_height_m;
  d.min_slope_rad = config.min_slope_rad;
  d.min_range_m = config.min_range_m;
  return d;
}

}  // namespace

Status ColumnConfig::Validate() const {
  if (Status s = PairParameters(*this).Validate(); !s) {
    return Error{"column config: " + s.message().substr(s.message().find('\'') )};
  }
  if (min_blob_pixels < 0) {
    return Error{"column config: 'min_blob_pixels' must be >= 0 (got " +
                 std::to_string(min_blob_pixels) + ")"};
  }
  return Status::Ok();
}

Expected<Detection> DetectColumns(const RangeImage& image, const ColumnConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  if (std::optional<RangeImage> masked = internal::WithoutNearReturns(image, config.min_range_m)) {
    return DetectColumns(*masked, config);
  }
  const DetectorConfig pair_config = PairParameters(config);
  const int n = image.size(), width = image.width(), height = image.height();
  const internal::LevelPoints level(image);
  const PairTest test(pair_config);

  // 1. Column profiles: the compatible pairs within each column, one tree of blocks of
  //    rows per column (pair_search.hpp), so that a column's far apart rows are skipped
  //    in blocks.
  const internal::Candidates candidates = internal::FindCandidates(level, test);
  const internal::PointTree lower(level, candidates.lower, width, height, 8, 1, true);
  const internal::PointTree upper(level, candidates.upper, width, height, 8, 1, true);
  internal::PairSearchOptions options;
  options.unions = false;
  const internal::PairSearchResult found = internal::SearchPairs(lower, upper, n, test, options);
  std::vector<std::uint8_t> obstacle(n, 0);
  for (int i = 0; i < n; ++i) obstacle[i] = found.lower[i] | found.raised[i];
  const std::vector<std::uint8_t>& raised = found.raised;
  DetectionStats stats = found.stats;
  stats.node_pairs = stats.blocks_accepted = 0;

  // 2. Blob colouring of the obstacle mask, 8-connected.
  internal::UnionFind blobs(n);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const int i = r * width + c;
      if (!obstacle[i]) continue;
      // Earlier neighbours: left, and the three above.
      if (c > 0 && obstacle[i - 1]) blobs.Union(i, i - 1);
      if (r == 0) continue;
      for (int dc = -1; dc <= 1; ++dc) {
        const int cc = c + dc;
        if (cc >= 0 && cc < width && obstacle[i - width + dc]) blobs.Union(i, i - width + dc);
      }
    }
  }

  // 3. Blob-area rejection, then the same assembly as the cone detector.
  std::vector<std::int32_t> component(n, -1), area(n, 0);
  for (int i = 0; i < n; ++i) {
    if (obstacle[i]) ++area[component[i] = blobs.Find(i)];
  }
  for (int i = 0; i < n; ++i) {
    if (component[i] >= 0 && area[component[i]] < config.min_blob_pixels) component[i] = -1;
  }
  return internal::BuildDetection(image, level, component, raised, test.min_height, stats);
}

}  // namespace cairn::od
