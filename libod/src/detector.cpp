#include "cairn/od/detector.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <optional>
#include <string>
#include <variant>

#include "cairn/od/parallel.hpp"
#include "cairn/od/units.hpp"
#include "detection_internal.hpp"
#include "pair_search.hpp"
#include "search_region.hpp"

namespace cairn::od {
namespace {

Error BadField(const char* field, const std::string& expected, double value) {
  return Error{std::string("detector config: '") + field + "' must be " + expected + " (got " +
               std::to_string(value) + ")"};
}

// Scans `spans` for partners of the lower point `p`, testing each pair once; runs of
// pixels whose bounds (RowTiles) rule out every partner are skipped whole.
void ScanSpans(int p, const internal::RowSpans& spans, int width,
               const internal::LevelPoints& level, const internal::RowTiles& tiles,
               const PairTest& test, internal::UnionFind& sets,
               std::uint8_t* raised, DetectionStats& stats) {
  constexpr int kTile = internal::RowTiles::kTileWidth;
  const float px = level.x[p], py = level.y[p], pz = level.z[p];
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    const int row = r * width;
    const std::size_t row_tiles = static_cast<std::size_t>(r) * tiles.tiles_per_row;
    // A wrapped span (spherical images) is scanned as its two runs.
    const int runs[2][2] = {{spans.col_begin[r], std::min(spans.col_end[r], width)},
                            {0, spans.col_end[r] - width}};
    for (const auto& run : runs) {
      for (int c = run[0]; c < run[1];) {
        const int tile = c / kTile;
        const int stop = std::min(run[1], (tile + 1) * kTile);
        if (tiles.MayHoldPartner(row_tiles + tile, px, py, pz, test)) {
          stats.pairs_tested += stop - c;
          for (int q = row + c; q < row + stop; ++q) {
            const float dx = level.x[q] - px, dy = level.y[q] - py, dz = level.z[q] - pz;
            if (!test(dx, dy, dz)) continue;
            ++stats.pairs_compatible;
            sets.Union(p, q);
            raised[q] = 1;
          }
        }
        c = stop;
      }
    }
  }
}

Detection Finish(const RangeImage& image, const internal::LevelPoints& level,
                 internal::UnionFind& sets,
                 const std::vector<std::uint8_t>& raised, const PairTest& test,
                 const DetectionStats& stats) {
  return internal::BuildDetection(image, level, sets.Components(), raised,
                                  test.min_height, stats);
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
  if (threads < 0 || threads > 256) {
    return BadField("threads", "an integer in 0..256 (0: all hardware threads)", threads);
  }
  if (region_slabs < 1 || region_slabs > 64) {
    return BadField("region_slabs", "an integer in 1..64", region_slabs);
  }
  if (!std::isfinite(min_range_m) || min_range_m < 0.0) {
    return BadField("min_range", "a finite range >= 0 [m] (0: every return)", min_range_m);
  }
  return Status::Ok();
}

PairTest::PairTest(const DetectorConfig& config)
    : min_height(static_cast<float>(config.min_height_m)),
      max_height(static_cast<float>(config.max_height_m)),
      tan2_theta(static_cast<float>(std::tan(config.min_slope_rad) *
                                    std::tan(config.min_slope_rad))) {}

Expected<Detection> Detect(const RangeImage& image, const DetectorConfig& config) {
  if (config.search != SearchMode::kExact) return DetectRegionScan(image, config);
  if (Status s = config.Validate(); !s) return s.error();
  const int n = image.size();
  const int threads = ThreadCount(config.threads);
  // Returns nearer than min_range are holes from here on: only the level points are read
  // (and the image's ranges of segment points, which are none of them).
  const internal::LevelPoints level(image, threads, config.min_range_m);
  const PairTest test(config);
  const internal::BlockShape block = internal::BlockShapeFor(image);
  internal::PairSearchOptions options;
  options.threads = threads;
  const internal::Candidates candidates = internal::FindCandidates(level, test, threads);
  // The two trees, side by side when there are threads for it.
  std::optional<internal::PointTree> lower, upper;
  ParallelFor(
      2, threads,
      [&](int tree) {
        const bool is_lower = tree == 0;
        (is_lower ? lower : upper)
            .emplace(level, is_lower ? candidates.lower : candidates.upper, image.width(),
                     image.height(), block.rows, block.cols);
      },
      1);
  internal::PairSearchResult found = internal::SearchPairs(*lower, *upper, n, test, options);
  // A point's parent is itself for a set's first pixel (its root), else a pixel of its set
  // before it, which is what BuildDetection asks for (no walk to the root); points in no pair
  // get -1, in place.
  std::vector<std::int32_t> component = std::move(found.parent);
  constexpr int kParts = 8;
  ParallelFor(
      kParts, threads,
      [&](int k) {
        // Without a branch (which the processor mispredicts at every edge of a segment): a
        // select, which GCC vectorizes.
        const std::uint8_t* const is_lower = found.lower.data();
        const std::uint8_t* const is_raised = found.raised.data();
        std::int32_t* const name = component.data();
        const int end = internal::PartBegin(n, k + 1, kParts);
        for (int i = internal::PartBegin(n, k, kParts); i < end; ++i) {
          name[i] = (is_lower[i] | is_raised[i]) != 0 ? name[i] : -1;
        }
      },
      1);
  return internal::BuildDetection(image, level, std::move(component), found.raised, test.min_height,
                                  found.stats, threads);
}

Expected<Detection> DetectRegionScan(const RangeImage& image, const DetectorConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  if (std::optional<RangeImage> masked = internal::WithoutNearReturns(image, config.min_range_m)) {
    return DetectRegionScan(*masked, config);
  }
  const int n = image.size(), width = image.width(), height = image.height();
  const internal::LevelPoints level(image);
  const PairTest test(config);
  internal::UnionFind sets(n);
  std::vector<std::uint8_t> raised(n, 0);
  DetectionStats stats;
  if (image.valid_count() == 0) return Finish(image, level, sets, raised, test, stats);

  const internal::ConeRegion region(image, config);
  const internal::RowTiles tiles(level, width, height);

  // Workers take blocks of rows of lower points in turn. Each lower point's pairs are found
  // by one worker, which writes only that point's accumulator entries; unions and raised
  // upper points go into the worker's own union-find and flags, merged afterwards. The
  // result does not depend on the split.
  constexpr int kBlockRows = 4;
  const int blocks = (height + kBlockRows - 1) / kBlockRows;
  const int threads = std::clamp(ThreadCount(config.threads), 1, blocks);
  struct Worker {
    internal::UnionFind sets;
    internal::RowSpans spans;
    std::vector<std::uint8_t> raised;
    DetectionStats stats;
  };
  std::vector<Worker> workers;
  workers.reserve(threads);
  for (int t = 0; t < threads; ++t) {
    workers.push_back({internal::UnionFind(t == 0 ? 0 : n), internal::RowSpans(height),
                       std::vector<std::uint8_t>(t == 0 ? 0 : n, 0), {}});
  }
  // The calling thread is worker 0 and works into the final sets and flags.
  ParallelFor(
      blocks, threads,
      [&](int worker, int b) {
        Worker& w = workers[worker];
        internal::UnionFind& worker_sets = worker == 0 ? sets : w.sets;
        std::uint8_t* worker_raised = worker == 0 ? raised.data() : w.raised.data();
        const int p_end = std::min(height, (b + 1) * kBlockRows) * width;
        for (int p = b * kBlockRows * width; p < p_end; ++p) {
          if (!image.valid(p)) continue;
          region.Compute(p, w.spans);
          ScanSpans(p, w.spans, width, level, tiles, test, worker_sets, worker_raised, w.stats);
        }
      },
      1);
  for (const Worker& w : workers) {
    stats.pairs_tested += w.stats.pairs_tested;
    stats.pairs_compatible += w.stats.pairs_compatible;
  }
  for (int t = 1; t < threads; ++t) {
    sets.Merge(workers[t].sets);
    for (int i = 0; i < n; ++i) raised[i] |= workers[t].raised[i];
  }
  return Finish(image, level, sets, raised, test, stats);
}

Expected<Detection> DetectBruteForce(const RangeImage& image, const DetectorConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  if (std::optional<RangeImage> masked = internal::WithoutNearReturns(image, config.min_range_m)) {
    return DetectBruteForce(*masked, config);
  }
  const int n = image.size();
  const internal::LevelPoints level(image);
  const PairTest test(config);
  internal::UnionFind sets(n);
  std::vector<std::uint8_t> raised(n, 0);
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
      sets.Union(lo, up);
      raised[up] = 1;
    }
  }
  return Finish(image, level, sets, raised, test, stats);
}

Detection WithoutFeet(Detection detection) {
  if (detection.foot.size() != detection.labels.size()) return detection;  // made by hand
  detection.stats.obstacle_points = 0;
  for (std::size_t i = 0; i < detection.labels.size(); ++i) {
    if (detection.foot[i] != 0) detection.labels[i] = 0;
    detection.stats.obstacle_points += detection.labels[i] != 0 ? 1 : 0;
  }
  return detection;
}

}  // namespace cairn::od
