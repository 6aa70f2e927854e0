#include "cairn/od/detector.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "detection_internal.hpp"
#include "search_region.hpp"

namespace cairn::od {
namespace {

constexpr double kPi = 3.14159265358979323846;

Error BadField(const char* field, const std::string& expected, double value) {
  return Error{std::string("detector config: '") + field + "' must be " + expected + " (got " +
               std::to_string(value) + ")"};
}

// Scans `spans` for partners of the lower point `p`, testing each pair once; runs of
// pixels whose bounds (RowTiles) rule out every partner are skipped whole.
void ScanSpans(int p, const internal::RowSpans& spans, int width,
               const internal::LevelPoints& level, const internal::RowTiles& tiles,
               const PairTest& test, internal::UnionFind& sets, internal::PairAccumulator& pairs,
               DetectionStats& stats) {
  constexpr int kTile = internal::RowTiles::kTileWidth;
  const float px = level.x[p], py = level.y[p], pz = level.z[p];
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    const int row = r * width;
    const std::size_t row_tiles = static_cast<std::size_t>(r) * tiles.tiles_per_row;
    for (int c = spans.col_begin[r]; c < spans.col_end[r];) {
      const int tile = c / kTile;
      const int stop = std::min(spans.col_end[r], (tile + 1) * kTile);
      if (tiles.MayHoldPartner(row_tiles + tile, px, py, pz, test)) {
        stats.pairs_tested += stop - c;
        for (int q = row + c; q < row + stop; ++q) {
          const float dx = level.x[q] - px, dy = level.y[q] - py, dz = level.z[q] - pz;
          if (!test(dx, dy, dz)) continue;
          ++stats.pairs_compatible;
          pairs.Add(p, q, dx, dy, dz);
          sets.Union(p, q);
        }
      }
      c = stop;
    }
  }
}

Detection Finish(const RangeImage& image, const internal::LevelPoints& level,
                 internal::UnionFind& sets, const internal::PairAccumulator& pairs,
                 const DetectionStats& stats) {
  std::vector<std::int32_t> component(image.size(), -1);
  for (int i = 0; i < image.size(); ++i) {
    if (pairs.obstacle[i]) component[i] = sets.Find(i);
  }
  return internal::BuildDetection(image, level, component, pairs, stats);
}

}  // namespace

Status DetectorConfig::Validate() const {
  if (!std::isfinite(min_height_m) || min_height_m <= 0.0) {
    return BadField("min_height", "a finite height > 0 [m]", min_height_m);
  }
  if (!std::isfinite(max_height_m) || max_height_m <= min_height_m) {
    return BadField("max_height", "finite and greater than min_height [m]", max_height_m);
  }
  if (!std::isfinite(min_slope_rad) || min_slope_rad <= 0.0 || min_slope_rad >= kPi / 2) {
    return BadField("min_slope", "an angle strictly between 0 and 90 deg",
                    min_slope_rad * 180.0 / kPi);
  }
  if (!std::isfinite(window_scale) || window_scale <= 0.0) {
    return BadField("window_scale", "a finite factor > 0", window_scale);
  }
  if (region_slabs < 1 || region_slabs > 64) {
    return BadField("region_slabs", "an integer in 1..64", region_slabs);
  }
  return Status::Ok();
}

PairTest::PairTest(const DetectorConfig& config)
    : min_height(static_cast<float>(config.min_height_m)),
      max_height(static_cast<float>(config.max_height_m)),
      tan2_theta(static_cast<float>(std::tan(config.min_slope_rad) *
                                    std::tan(config.min_slope_rad))) {}

Expected<Detection> Detect(const RangeImage& image, const DetectorConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  const int n = image.size(), width = image.width();
  const internal::LevelPoints level(image);
  const PairTest test(config);
  internal::UnionFind sets(n);
  internal::PairAccumulator pairs(n);
  DetectionStats stats;
  internal::RowSpans spans(image.height());
  const internal::RowTiles tiles(level, width, image.height());
  if (image.valid_count() == 0) return Finish(image, level, sets, pairs, stats);

  const auto& model = std::get<PinholeModel>(image.model());
  const internal::PinholeConeRegion region(model, image.up(), config,
                                           internal::NearestDepth(image));
  for (int p = 0; p < n; ++p) {
    if (!image.valid(p)) continue;
    if (config.search == SearchMode::kExact) {
      region.Compute(image.point(p), spans);
    } else {
      internal::PaperWindow(model, config, p / width, p % width, image.z()[p], spans);
    }
    ScanSpans(p, spans, width, level, tiles, test, sets, pairs, stats);
  }
  return Finish(image, level, sets, pairs, stats);
}

Expected<Detection> DetectBruteForce(const RangeImage& image, const DetectorConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  const int n = image.size();
  const internal::LevelPoints level(image);
  const PairTest test(config);
  internal::UnionFind sets(n);
  internal::PairAccumulator pairs(n);
  DetectionStats stats;
  for (int i = 0; i < n; ++i) {
    if (!image.valid(i)) continue;
    for (int j = i + 1; j < n; ++j) {
      if (!image.valid(j)) continue;
      stats.pairs_tested += 1;
      // Test from the lower point with the same float arithmetic as Detect.
      const bool j_above = level.z[j] > level.z[i];
      const int lo = j_above ? i : j, up = j_above ? j : i;
      const float dx = level.x[up] - level.x[lo], dy = level.y[up] - level.y[lo],
                  dz = level.z[up] - level.z[lo];
      if (!test(dx, dy, dz)) continue;
      ++stats.pairs_compatible;
      pairs.Add(lo, up, dx, dy, dz);
      sets.Union(lo, up);
    }
  }
  return Finish(image, level, sets, pairs, stats);
}

}  // namespace cairn::od
