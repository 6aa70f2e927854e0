#include "cairn/od/column_detector.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "detection_internal.hpp"

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

namespace {

// Per pixel: in a compatible pair within its column (either point), the upper point of one;
// pairs_compatible counts every such pair, pairs_tested those tested one by one.
struct ColumnPairs {
  std::vector<std::uint8_t> obstacle, raised;
  DetectionStats stats;
};

// The compatible pairs within each column, fast. A partner q of a lower point p lies less
// than reach = Hmax / tan(theta) from it horizontally, so less than reach along any
// horizontal direction: the column's points are put in bins of that width along the
// column's mean horizontal direction u, each bin sorted by height, and p meets the points
// of its own and the two neighbouring bins from the first more than HT above it (as the
// pair test rounds the difference, which grows with the upper height) to the last less than
// Hmax above, one by one.
ColumnPairs FindColumnPairs(const internal::LevelPoints& level, const PairTest& test, int width,
                            int height) {
  const int n = width * height;
  ColumnPairs out{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0), {}};
  std::vector<std::uint8_t>& obstacle = out.obstacle;
  std::vector<std::uint8_t>& raised = out.raised;
  DetectionStats& stats = out.stats;
  struct Point {
    float x, y, z;
    std::int32_t pixel;
    std::int32_t bin;
  };
  struct Bin {
    std::int32_t bin;
    int begin, end;  // its points in the column
  };
  // The valid points of every column, column after column, in one pass over the rows.
  std::vector<std::int32_t> start(width + 1, 0);
  for (int r = 0, i = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c, ++i) start[c + 1] += !std::isnan(level.z[i]);
  }
  for (int c = 0; c < width; ++c) start[c + 1] += start[c];
  std::vector<Point> points(start[width]);
  {
    std::vector<std::int32_t> fill(start.begin(), start.end() - 1);
    for (int r = 0, i = 0; r < height; ++r) {
      for (int c = 0; c < width; ++c, ++i) {
        if (!std::isnan(level.z[i])) points[fill[c]++] = {level.x[i], level.y[i], level.z[i], i, 0};
      }
    }
  }
  std::vector<Bin> bins;
  const float ht = test.min_height, hmax = test.max_height, tan2 = test.tan2_theta;
  // The bins are wider than the reach by a margin covering the rounding of u. Bin numbers
  // are clamped to +-1e9: a bin that far out holds nothing within reach of the others.
  const double bin_width =
      test.max_height / std::sqrt(static_cast<double>(test.tan2_theta)) * 1.001 + 1e-3;
  for (int c = 0; c < width; ++c) {
    Point* const column = points.data() + start[c];
    const int m = start[c + 1] - start[c];
    double mx = 0.0, my = 0.0;
    for (int k = 0; k < m; ++k) {
      mx += column[k].x;
      my += column[k].y;
    }
    const double norm = std::sqrt(mx * mx + my * my);
    const double ux = norm > 0.0 ? mx / norm : 1.0, uy = norm > 0.0 ? my / norm : 0.0;
    for (int k = 0; k < m; ++k) {
      const double u = std::clamp((ux * column[k].x + uy * column[k].y) / bin_width, -1e9, 1e9);
      int bin = static_cast<int>(u);
      bin -= static_cast<double>(bin) > u;  // floor
      column[k].bin = bin;
    }
    std::sort(column, column + m, [](const Point& a, const Point& b) {
      return a.bin < b.bin || (a.bin == b.bin && a.z < b.z);
    });
    bins.clear();
    for (int k = 0; k < m; ++k) {
      if (bins.empty() || bins.back().bin != column[k].bin) bins.push_back({column[k].bin, k, k});
      bins.back().end = k + 1;
    }
    for (int g = 0; g < static_cast<int>(bins.size()); ++g) {
      // The bins within one of g's, each with the first point more than HT above the
      // current lower point (which only moves up, as the lower points of g do).
      const Point* first[3];
      const Point* end[3];
      int near = 0;
      for (int h = std::max(0, g - 1); h <= g + 1 && h < static_cast<int>(bins.size()); ++h) {
        if (bins[h].bin < bins[g].bin - 1 || bins[h].bin > bins[g].bin + 1) continue;
        first[near] = column + bins[h].begin;
        end[near++] = column + bins[h].end;
      }
      for (int k = bins[g].begin; k < bins[g].end; ++k) {
        const float px = column[k].x, py = column[k].y, pz = column[k].z;
        const int p = column[k].pixel;
        for (int h = 0; h < near; ++h) {
          while (first[h] < end[h] && !(first[h]->z - pz > ht)) ++first[h];
          const Point* q = first[h];
          for (; q < end[h] && q->z - pz < hmax; ++q) {
            const float dx = q->x - px, dy = q->y - py, dz = q->z - pz;
            if (!(dz * dz > tan2 * (dx * dx + dy * dy))) continue;
            ++stats.pairs_compatible;
            obstacle[p] = obstacle[q->pixel] = 1;
            raised[q->pixel] = 1;
          }
          stats.pairs_tested += q - first[h];
        }
      }
    }
  }
  return out;
}

// The definition: every pair of valid points of each column, tested with the same float
// arithmetic.
ColumnPairs FindColumnPairsBruteForce(const internal::LevelPoints& level, const PairTest& test,
                                      int width, int height) {
  const int n = width * height;
  ColumnPairs out{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0), {}};
  for (int c = 0; c < width; ++c) {
    for (int i = c; i < n; i += width) {
      if (std::isnan(level.z[i])) continue;
      for (int j = i + width; j < n; j += width) {
        if (std::isnan(level.z[j])) continue;
        ++out.stats.pairs_tested;
        const bool j_above = level.z[j] > level.z[i];
        const int lo = j_above ? i : j, up = j_above ? j : i;
        if (!test(level.x[up] - level.x[lo], level.y[up] - level.y[lo],
                  level.z[up] - level.z[lo])) {
          continue;
        }
        ++out.stats.pairs_compatible;
        out.obstacle[lo] = out.obstacle[up] = 1;
        out.raised[up] = 1;
      }
    }
  }
  return out;
}

// Blob colouring of the obstacle mask (8-connected), blob-area rejection, then the same
// assembly as the cone detector.
Detection Blobs(const RangeImage& image, const internal::LevelPoints& level,
                const ColumnPairs& pairs, const ColumnConfig& config, float min_height) {
  const int n = image.size(), width = image.width(), height = image.height();
  const std::vector<std::uint8_t>& obstacle = pairs.obstacle;
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

  std::vector<std::int32_t> component(n, -1), area(n, 0);
  for (int i = 0; i < n; ++i) {
    if (obstacle[i]) ++area[component[i] = blobs.Find(i)];
  }
  for (int i = 0; i < n; ++i) {
    if (component[i] >= 0 && area[component[i]] < config.min_blob_pixels) component[i] = -1;
  }
  return internal::BuildDetection(image, level, component, pairs.raised, min_height, pairs.stats);
}

// DetectColumns (fast = true) and DetectColumnsBruteForce.
Expected<Detection> Columns(const RangeImage& image, const ColumnConfig& config, bool fast) {
  if (Status s = config.Validate(); !s) return s.error();
  if (std::optional<RangeImage> masked = internal::WithoutNearReturns(image, config.min_range_m)) {
    return Columns(*masked, config, fast);
  }
  const internal::LevelPoints level(image);
  const PairTest test(PairParameters(config));
  const ColumnPairs pairs = fast ? FindColumnPairs(level, test, image.width(), image.height())
                                 : FindColumnPairsBruteForce(level, test, image.width(),
                                                             image.height());
  return Blobs(image, level, pairs, config, test.min_height);
}

}  // namespace

Expected<Detection> DetectColumns(const RangeImage& image, const ColumnConfig& config) {
  return Columns(image, config, true);
}

Expected<Detection> DetectColumnsBruteForce(const RangeImage& image, const ColumnConfig& config) {
  return Columns(image, config, false);
}

}  // namespace cairn::od
