// Detect bounds blocks of points instead of testing pairs one by one; these tests hold it to
// the O(N^2) definition (DetectBruteForce) and to the earlier region scan (DetectRegionScan,
// itself checked against the definition here):
//  - seeded random camera views and LiDAR scans, tilted, with noise and holes;
//  - points on a coarse lattice, where many pairs sit exactly on HT, Hmax or theta, so that
//    the block bounds' rounding is put to the test;
//  - the benchmark frames themselves (RELLIS-3D, KITTI, the demo frame);
//  - on all of these, the column baseline's pass over each column against its own definition
//    (DetectColumnsBruteForce);
//  - the surface slope of a segment (detector.hpp) on planes of known inclination.
#include "../libod/src/pair_search.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <variant>
#include <vector>

#include "../libod/src/detection_internal.hpp"
#include "../libod/src/simd.hpp"
#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/random_scene.hpp"
#include "cairn/sim/render.hpp"

namespace cairn::od {
namespace {

// features derived from them.
void ExpectSame(const Detection& a, const Detection& b, const std::string& what) {
  ASSERT_EQ(a.labels.size(), b.labels.size()) << what;
  int differing = 0;
  for (std::size_t i = 0; i < a.labels.size(); ++i) differing += a.labels[i] != b.labels[i];
  EXPECT_EQ(differing, 0) << what << ": pixels with other labels";
  EXPECT_TRUE(a.foot == b.foot) << what << ": feet differ";
  EXPECT_EQ(a.stats.obstacle_points, b.stats.obstacle_points) << what;
  ASSERT_EQ(a.segments.size(), b.segments.size()) << what;
  for (std::size_t s = 0; s < a.segments.size(); ++s) {
    EXPECT_EQ(a.segments[s].raised_count, b.segments[s].raised_count) << what << ", segment " << s;
    EXPECT_EQ(a.segments[s].point_count, b.segments[s].point_count) << what << ", segment " << s;
    EXPECT_EQ(a.segments[s].slope_points, b.segments[s].slope_points) << what;
    EXPECT_DOUBLE_EQ(a.segments[s].slope_max_rad, b.segments[s].slope_max_rad) << what;
  }
}

// The labels of 8-connected blobs of `mask` (width x height) with at least `min_blob`
// pixels, numbered in row-major order of their first pixel, by flood fill: the blob
// colouring's definition, apart from the detector's own.
std::vector<std::int32_t> FloodFillBlobs(const std::vector<bool>& mask, int width, int height,
                                         int min_blob) {
  std::vector<std::int32_t> labels(mask.size(), 0);
  std::vector<int> blob, stack;
  std::int32_t next = 0;
  std::vector<bool> seen(mask.size(), false);
  for (int start = 0; start < static_cast<int>(mask.size()); ++start) {
    if (!mask[start] || seen[start]) continue;
    blob.clear();
    stack = {start};
    seen[start] = true;
    while (!stack.empty()) {
      const int i = stack.back();
      stack.pop_back();
      blob.push_back(i);
      const int r = i / width, c = i % width;
      for (int dr = -1; dr <= 1; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc, j = rr * width + cc;
          if (rr < 0 || rr >= height || cc < 0 || cc >= width || !mask[j] || seen[j]) continue;
          seen[j] = true;
          stack.push_back(j);
        }
      }
    }
    if (static_cast<int>(blob.size()) < min_blob) continue;
    ++next;
    for (const int i : blob) labels[i] = next;
  }
  return labels;
}

// The column baseline's pass over each column against its definition (every pair of each
// column): the same result, no more pairs found (it stops at a point's first partner where a
// column is dense), some found where there are any; and its blobs against a flood fill of its
// obstacle mask.
void ExpectSameColumns(const RangeImage& image, const DetectorConfig& detector, int min_blob,
                       const std::string& what) {
  ColumnConfig config = ColumnConfig::From(detector);
  config.min_blob_pixels = min_blob;
  const Detection fast = *DetectColumns(image, config);
  const Detection brute = *DetectColumnsBruteForce(image, config);
  ExpectSame(fast, brute, what + " (columns)");
  EXPECT_LE(fast.stats.pairs_compatible, brute.stats.pairs_compatible) << what << " (columns)";
  EXPECT_EQ(fast.stats.pairs_compatible > 0, brute.stats.pairs_compatible > 0)
      << what << " (columns)";
  // A pair is tested at most once from each end.
  EXPECT_LE(fast.stats.pairs_tested, 2 * brute.stats.pairs_tested) << what << " (columns)";
  ColumnConfig all = config;
  all.min_blob_pixels = 0;
  const Detection unfiltered = *DetectColumns(image, all);
  std::vector<bool> mask(unfiltered.labels.size());
  for (std::size_t i = 0; i < mask.size(); ++i) mask[i] = unfiltered.labels[i] > 0;
  EXPECT_TRUE(fast.labels == FloodFillBlobs(mask, image.width(), image.height(), min_blob))
      << what << " (column blobs against a flood fill)";
}

DetectorConfig RandomConfig(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  DetectorConfig c;
  c.min_height_m = 0.05 + 0.5 * u(rng);
  c.max_height_m = c.min_height_m + 0.1 + 1.5 * u(rng);
  c.min_slope_rad = (15.0 + 65.0 * u(rng)) * kDegToRad;
  c.threads = 1 + static_cast<int>(rng() % 3);
  return c;
}

RangeImage RandomView(int seed, double noise, double holes) {
  sim::RandomSceneOptions options;
  options.width = 72;
  options.height = 54;
  const sim::RandomView view = sim::MakeRandomView(seed, options);
  sim::RenderOptions render;
  render.max_range_m = 40.0;
  sim::DepthFrame frame = *sim::RenderDepth(view.scene, view.camera, render);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (float& d : frame.depth_m) {
    if (d <= 0.0f) continue;
    d = u(rng) < holes ? 0.0f : static_cast<float>(d * (1.0 + noise * (u(rng) - 0.5)));
  }
  return *RangeImage::FromDepth(frame.depth_m, view.camera.model, frame.up_optical);
}

TEST(PairSearch, EqualsTheDefinitionAndTheRegionScanOnRandomViews) {
  std::mt19937 rng(77);
  int with_obstacles = 0;
  for (int seed = 0; seed < 16; ++seed) {
    const RangeImage image = RandomView(300 + seed, seed % 2 ? 0.03 : 0.0, seed % 3 ? 0.05 : 0.0);
    const DetectorConfig config = RandomConfig(rng);
    const Detection fast = *Detect(image, config);
    const Detection brute = *DetectBruteForce(image, config);
    const Detection scan = *DetectRegionScan(image, config);
    const std::string what = "view " + std::to_string(seed);
    ExpectSame(fast, brute, what + " (blocks vs definition)");
    ExpectSame(scan, brute, what + " (region scan vs definition)");
    ExpectSameColumns(image, config, seed % 3, what);
    with_obstacles += brute.stats.obstacle_points > 0;
    // Blocks test fewer pairs one by one than the definition tests.
    EXPECT_LE(fast.stats.pairs_tested, brute.stats.pairs_tested) << what;
  }
  EXPECT_GE(with_obstacles, 12);
}

// Each pixel's foot, and each segment's ground and count of feet, by their definition
// (detector.hpp) from the raised points given: a foot is an obstacle point that is the upper
// point of no pair and lies less than HT above its own segment's ground (the lowest of its
// points).
void ExpectFeetFollowTheirDefinition(const Detection& d, const internal::LevelPoints& level,
                                     const std::vector<std::uint8_t>& raised, float min_height,
                                     const std::string& what) {
  std::vector<float> ground(d.segments.size(), std::numeric_limits<float>::infinity());
  for (std::size_t i = 0; i < d.labels.size(); ++i) {
    if (d.labels[i] > 0) ground[d.labels[i] - 1] = std::min(ground[d.labels[i] - 1], level.z[i]);
  }
  std::vector<int> feet(d.segments.size(), 0);
  int wrong = 0;
  for (std::size_t i = 0; i < d.labels.size(); ++i) {
    const bool foot =
        d.labels[i] > 0 && !raised[i] &&
        static_cast<double>(level.z[i]) - ground[d.labels[i] - 1] < static_cast<double>(min_height);
    wrong += d.is_foot(static_cast<int>(i)) != foot;
    if (foot) ++feet[d.labels[i] - 1];
  }
  EXPECT_EQ(wrong, 0) << what << ": pixels whose foot differs from the definition";
  for (std::size_t k = 0; k < d.segments.size(); ++k) {
    EXPECT_EQ(d.segments[k].ground_height_m, ground[k]) << what << ", segment " << k + 1;
    EXPECT_EQ(d.segments[k].foot_count, feet[k]) << what << ", segment " << k + 1;
  }
}

// The feet against their definition on views with several segments, so that a foot measured
// from another segment's ground shows; the raised points from pairs tested here one by one.
// (Every reference Detect is held to assembles its result with the same BuildDetection.)
TEST(PairSearch, FeetFollowTheirDefinitionInEverySegment) {
  std::mt19937 rng(91);
  int with_segments = 0;
  for (int seed = 0; seed < 12; ++seed) {
    const RangeImage image = RandomView(500 + seed, seed % 2 ? 0.03 : 0.0, 0.05);
    DetectorConfig config = RandomConfig(rng);
    config.min_height_m = 0.1 + 0.2 * (seed % 3);  // HT 0.1-0.5 m: a foot band of some height
    config.max_height_m = std::max(config.max_height_m, config.min_height_m + 0.1);
    const Detection d = *Detect(image, config);
    const internal::LevelPoints level(image);
    const PairTest test(config);
    const int n = image.size();
    std::vector<std::uint8_t> raised(n, 0);
    for (int i = 0; i < n; ++i) {
      if (!image.valid(i)) continue;
      for (int j = 0; j < n; ++j) {
        if (j == i || !image.valid(j) || !(level.z[j] > level.z[i])) continue;
        if (test(level.x[j] - level.x[i], level.y[j] - level.y[i], level.z[j] - level.z[i])) {
          raised[j] = 1;
        }
      }
    }
    ExpectFeetFollowTheirDefinition(d, level, raised, test.min_height,
                                    "view " + std::to_string(seed));
    with_segments += d.segments.size() >= 2;
  }
  EXPECT_GE(with_segments, 6);
}

// Depths on a 0.1 m lattice seen by a level camera with integer fx = fy and pixel-centred rays:
// coordinates are multiples of 0.1 m, so many pairs sit exactly on HT, Hmax and the slope,
// where rounding decides. A tenth of the pixels have no return.
RangeImage LatticeImage(std::mt19937& rng, int width, int height, double f) {
  PinholeModel model;
  model.width = width;
  model.height = height;
  model.fx = model.fy = f;
  model.cx = 0.5 * (width - 1);
  model.cy = 0.5 * (height - 1);
  std::vector<float> depth(model.width * model.height);
  for (float& d : depth) d = rng() % 10 == 0 ? 0.0f : 0.1f * (5 + rng() % 30);
  return *RangeImage::FromDepth(depth, model, {0.0, -1.0, 0.0});
}

// Thresholds on the lattice's steps, by trial: HT 0.1 or 0.3, Hmax 0.5 or 1.0, 45 deg or
// atan 2.
DetectorConfig LatticeConfig(int trial) {
  DetectorConfig config;
  config.min_height_m = trial % 2 ? 0.3 : 0.1;
  config.max_height_m = trial % 3 ? 1.0 : 0.5;
  config.min_slope_rad = trial % 4 ? kPi / 4 : std::atan(2.0);
  return config;
}

// The lattice in 40 x 30 images: the cone detector and the column baseline against the
// definition.
TEST(PairSearch, EqualsTheDefinitionOnThresholdsExactly) {
  std::mt19937 rng(4242);
  for (int trial = 0; trial < 12; ++trial) {
    const RangeImage image = LatticeImage(rng, 40, 30, 10.0 + trial);
    DetectorConfig config = LatticeConfig(trial);
    config.threads = 1 + trial % 2;
    const Detection brute = *DetectBruteForce(image, config);
    ExpectSame(*Detect(image, config), brute, "lattice trial " + std::to_string(trial));
    ExpectSameColumns(image, config, 0, "lattice trial " + std::to_string(trial));
    EXPECT_GT(brute.stats.pairs_compatible, 0);
  }
}

// Columns holding exactly as many points as the column baseline's limits (with AVX2 or AVX-512F,
// a whole column of at most 64 in one to eight vectors of eight or one to four of sixteen;
// binned above, and at every column on narrower vectors), lattice depths (pairs exactly on the
// thresholds), at every vector width the processor has: the definition's result; a whole column
// finds every pair (as many as the definition counts); eight and sixteen lanes (the same path
// where every column is whole) test and find the same pairs.
TEST(PairSearch, TheColumnBaselineAtItsColumnSizesEqualsTheDefinition) {
  struct Uncap {
    ~Uncap() { internal::CapVectorLanes(0); }
  } uncap;
  const int widest = internal::VectorLanes();
  // Columns are gathered sixteen at a time, eight rows at a time: the wider images give whole
  // blocks and a partial one (five columns, one), and 70 rows leave six to gather one by one.
  const std::vector<std::vector<int>> images_counts = {
      {0, 1, 2, 15, 16, 17, 31, 32, 33, 47, 48, 49, 63, 64},
      {63, 64, 65, 70},
      {0,  3,  8,  9,  15, 16, 17, 24, 31, 32, 33, 40, 47, 48, 49, 56, 63, 64, 5,
       12, 20, 28, 36, 44, 52, 60, 64, 1,  7,  13, 19, 25, 37, 43, 61, 62, 64},
      {70, 10, 65, 64, 0, 69, 33, 70, 2, 66, 48, 70, 17, 68, 1, 70, 40}};
  const int height = 70;
  std::mt19937 rng(6464);
  for (int trial = 0; trial < 6; ++trial) {
    for (const std::vector<int>& counts : images_counts) {
      const int width = static_cast<int>(counts.size());
      PinholeModel model;
      model.width = width;
      model.height = height;
      model.fx = model.fy = 8.0 + trial;
      model.cx = 0.5 * (width - 1);
      model.cy = 0.5 * (height - 1);
      std::vector<float> depth(static_cast<std::size_t>(width) * height, 0.0f);
      for (int c = 0; c < width; ++c) {
        std::vector<int> rows(height);
        for (int r = 0; r < height; ++r) rows[r] = r;
        std::shuffle(rows.begin(), rows.end(), rng);
        for (int k = 0; k < counts[c]; ++k) {
          depth[static_cast<std::size_t>(rows[k]) * width + c] = 0.1f * (5 + rng() % 30);
        }
      }
      const RangeImage image = *RangeImage::FromDepth(depth, model, {0.0, -1.0, 0.0});
      for (int c = 0; c < width; ++c) {
        int valid = 0;
        for (int r = 0; r < height; ++r) valid += image.valid(r * width + c);
        ASSERT_EQ(valid, counts[c]) << "column " << c;
      }
      const bool every_column_whole = *std::max_element(counts.begin(), counts.end()) <= 64;
      DetectorConfig config = LatticeConfig(trial);
      ColumnConfig columns = ColumnConfig::From(config);
      columns.min_blob_pixels = 0;
      const Detection brute = *DetectColumnsBruteForce(image, columns);
      // A whole column tests, as the lower point, every point of it HT..Hmax above it (the
      // difference as the pair test takes it), however its chunks are skipped.
      std::int64_t in_window = 0;
      {
        const internal::LevelPoints level(image, 1, columns.min_range_m);
        const PairTest test(config);
        for (int c = 0; c < width; ++c) {
          for (int i = c; i < width * height; i += width) {
            for (int j = c; j < width * height; j += width) {
              const float dz = level.z[j] - level.z[i];  // NaN where either is invalid
              in_window += dz > test.min_height && dz < test.max_height;
            }
          }
        }
      }
      EXPECT_GT(brute.stats.pairs_compatible, 0) << "trial " << trial;
      for (const int lanes : {16, 8, 4, 1}) {
        if (lanes > widest) continue;
        internal::CapVectorLanes(lanes);
        const std::string what = "trial " + std::to_string(trial) + ", " + std::to_string(width) +
                                 " columns, " + std::to_string(lanes) + " lanes";
        ExpectSameColumns(image, config, 0, what);
        const DetectionStats stats = DetectColumns(image, columns)->stats;
        if (lanes < 8 || !every_column_whole) continue;
        EXPECT_EQ(stats.pairs_compatible, brute.stats.pairs_compatible) << what;
        EXPECT_EQ(stats.pairs_tested, in_window) << what;
      }
    }
  }
}

// The same lattice in tall, narrow images: each column holds up to 200 points over a few
// metres, so its neighbourhoods are dense and the column baseline searches them only up to
// each point's first partner each way (it then finds fewer pairs than there are); its marks
// still equal the definition's where rounding decides.
TEST(PairSearch, TheColumnBaselineOnDenseColumnsEqualsTheDefinitionOnThresholdsExactly) {
  std::mt19937 rng(2424);
  int searched = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const RangeImage image = LatticeImage(rng, 6, 200, 20.0 + trial);
    const DetectorConfig config = LatticeConfig(trial);
    const std::string what = "dense lattice trial " + std::to_string(trial);
    ExpectSameColumns(image, config, 0, what);
    const ColumnConfig columns = ColumnConfig::From(config);
    const Detection fast = *DetectColumns(image, columns);
    const Detection brute = *DetectColumnsBruteForce(image, columns);
    EXPECT_GT(brute.stats.pairs_compatible, 0) << what;
    searched += fast.stats.pairs_compatible < brute.stats.pairs_compatible;
  }
  EXPECT_EQ(searched, 8);  // every trial went through the search up to first partners
}

// Random LiDAR scans: points along each ring at random ranges, some above the ground, the
// sensor tilted.
RangeImage RandomScan(std::mt19937& rng, const std::string& sensor, int width) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const SphericalModel model = *SphericalModel::Preset(sensor, width);
  std::vector<Eigen::Vector3f> points;
  std::vector<std::int32_t> rows, cols;
  for (int r = 0; r < model.height(); ++r) {
    for (int c = 0; c < width; ++c) {
      if (u(rng) < 0.1) continue;
      const double e = model.ring_elevation_rad[r] + 0.002 * (u(rng) - 0.5);
      const double a = model.ColumnAzimuth(c);
      const double d = 1.0 + (c % 17 < 4 ? 3.0 : 15.0) * u(rng);
      points.emplace_back(d * std::cos(e) * std::cos(a), d * std::cos(e) * std::sin(a),
                          d * std::sin(e));
      rows.push_back(r);
      cols.push_back(c);
    }
  }
  const Eigen::Vector3d up(0.2 * (u(rng) - 0.5), 0.2 * (u(rng) - 0.5), 1.0);
  return *RangeImage::FromPoints(points, model, up, rows, cols);
}

// The level points drop returns nearer than min_range as DropReturnsNearerThan does, to the
// bit (the same double-precision test, four at a time and in each part's tail), on images
// whose eight parts leave 0-3 points past a multiple of four, with returns on the boundary,
// holes and points of either sign.
TEST(LevelPoints, DropNearReturnsAsTheImageWould) {
  std::mt19937 rng(77);
  for (int width = 29; width <= 36; ++width) {
    PinholeModel model;
    model.width = width;
    model.height = 7;
    model.fx = model.fy = 20.0;
    model.cx = 0.5 * (width - 1);
    model.cy = 3.0;
    std::vector<float> depth(model.width * model.height);
    for (float& d : depth) d = rng() % 7 == 0 ? 0.0f : 0.25f * (1 + rng() % 16);
    const RangeImage image = *RangeImage::FromDepth(depth, model, {0.3, -1.0, 0.1});
    // (100 m: every return dropped, no valid point in any part.)
    for (const double min_range : {0.0, 1.0, 2.0, 2.25, 3.7, 100.0}) {
      RangeImage holes = image;
      if (min_range > 0.0) holes.DropReturnsNearerThan(min_range);
      for (const int threads : {1, 2}) {
        const internal::LevelPoints masked(image, threads, min_range);
        const internal::LevelPoints reference(holes, threads);
        for (int i = 0; i < image.size(); ++i) {
          const std::string at = "width " + std::to_string(width) + ", min_range " +
                                 std::to_string(min_range) + ", pixel " + std::to_string(i);
          ASSERT_EQ(std::isnan(masked.z[i]), !holes.valid(i)) << at;
          const float got[3] = {masked.x[i], masked.y[i], masked.z[i]};
          const float want[3] = {reference.x[i], reference.y[i], reference.z[i]};
          for (int k = 0; k < 3; ++k) {
            ASSERT_EQ(std::isnan(got[k]), std::isnan(want[k])) << at;
            if (!std::isnan(got[k])) {
              ASSERT_EQ(got[k], want[k]) << at;
            }
          }
        }
        // The extent and count of the valid points, taken as they were stored, are those
        // of the points themselves (widths 29..36: every remainder of four, the tail included).
        float x_min = std::numeric_limits<float>::infinity(), x_max = -x_min;
        float y_min = x_min, y_max = x_max;
        int valid = 0;
        for (int i = 0; i < image.size(); ++i) {
          if (std::isnan(masked.z[i])) continue;
          ++valid;
          x_min = std::min(x_min, masked.x[i]);
          x_max = std::max(x_max, masked.x[i]);
          y_min = std::min(y_min, masked.y[i]);
          y_max = std::max(y_max, masked.y[i]);
        }
        const std::string what = "width " + std::to_string(width) + ", min_range " +
                                 std::to_string(min_range) + ", threads " + std::to_string(threads);
        EXPECT_EQ(masked.valid, valid) << what;
        EXPECT_EQ(masked.x_min, x_min) << what;
        EXPECT_EQ(masked.x_max, x_max) << what;
        EXPECT_EQ(masked.y_min, y_min) << what;
        EXPECT_EQ(masked.y_max, y_max) << what;
      }
    }
  }
}

TEST(PairSearch, EqualsTheDefinitionOnLidarScans) {
  std::mt19937 rng(1964);
  for (int trial = 0; trial < 8; ++trial) {
    const RangeImage image = RandomScan(rng, trial % 2 ? "VLP-16" : "OS1-64", 60 + 8 * trial);
    const DetectorConfig config = RandomConfig(rng);
    const Detection brute = *DetectBruteForce(image, config);
    ExpectSame(*Detect(image, config), brute, "scan " + std::to_string(trial));
    ExpectSame(*DetectRegionScan(image, config), brute, "scan (region) " + std::to_string(trial));
    ExpectSameColumns(image, config, 0, "scan " + std::to_string(trial));
    ColumnConfig columns = ColumnConfig::From(config);
    columns.min_blob_pixels = 0;
    // The column baseline keeps the pairs within each column: a subset of the definition's.
    const Detection column = *DetectColumns(image, columns);
    for (int i = 0; i < image.size(); ++i) {
      EXPECT_TRUE(!column.is_obstacle(i) || brute.is_obstacle(i)) << "scan " << trial << ", " << i;
    }
  }
}

// --- The benchmark frames -------------------------------------------------------------------

const std::string kShared = CAIRN_SHARED_DATASETS;
const std::string kSource = CAIRN_SOURCE_DIR;

Expected<RangeImage> LoadScan(const std::string& path, const std::string& sensor) {
  Expected<od::PointCloud> cloud = io::ReadPointFile(path);
  if (!cloud) return cloud.error();
  od::LayoutOptions options;
  options.preset = *SphericalModel::Preset(sensor);
  Expected<od::FoundLayout> layout = od::FindLayout(*cloud, options, path);
  if (!layout) return layout.error();
  return RangeImage::FromPoints(cloud->points, layout->model, Eigen::Vector3d::UnitZ(),
                                layout->rows, layout->cols);
}

TEST(PairSearch, EqualsTheDefinitionOnTheRellisScan) {
  const std::string path = kShared + "/rellis3d-000104/os1_bin/000104.bin";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (../shared/datasets)";
  Expected<RangeImage> image = LoadScan(path, "OS1-64");
  ASSERT_TRUE(image.ok()) << image.error().message;
  DetectorConfig config = io::LoadDetectSettings(kSource + "/config/sensors/os1-64.yaml")->detector;
  const Detection brute = *DetectBruteForce(*image, config);
  EXPECT_GT(brute.stats.pairs_compatible, 100000);
  // More threads than cores: the workers share their findings, and interleave more.
  for (int threads : {1, 2, 5}) {
    config.threads = threads;
    ExpectSame(*Detect(*image, config), brute, "RELLIS, " + std::to_string(threads) + " threads");
  }
  ExpectSameColumns(*image, config, 0, "RELLIS");
}

TEST(PairSearch, EqualsTheRegionScanOnTheKittiScan) {
  const std::string path = kShared + "/kitti-seq00-0-10/velodyne/000000.bin";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent (../shared/datasets)";
  Expected<RangeImage> image = LoadScan(path, "HDL-64E");
  ASSERT_TRUE(image.ok()) << image.error().message;
  DetectorConfig config =
      io::LoadDetectSettings(kSource + "/config/sensors/hdl-64e.yaml")->detector;
  const Detection scan = *DetectRegionScan(*image, config);
  EXPECT_GT(scan.stats.pairs_compatible, 100000);
  for (int threads : {1, 2, 5}) {
    config.threads = threads;
    ExpectSame(*Detect(*image, config), scan,
               "KITTI 00 scan 0, " + std::to_string(threads) + " threads");
  }
  ExpectSameColumns(*image, config, 0, "KITTI 00 scan 0");
}

// The leaves' box tests at every width the processor has against one at a time (Classify
// itself), on points and boxes at multiples of 1/8 m with HT 0.25 m, Hmax 1 m and theta 45 deg
// or atan 2 (all exact in floats): many points lie exactly on a bound, where rounding decides.
TEST(PairSearch, TheLeafBoxTestsAreTheSameAtEveryWidth) {
  std::mt19937 rng(8080);
  const auto eighths = [&](int lo, int hi) {
    return 0.125f * static_cast<float>(lo + static_cast<int>(rng() % (hi - lo + 1)));
  };
  const float inf = std::numeric_limits<float>::infinity();
  std::int64_t kept = 0, accepted = 0, near = 0, on_bound = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    DetectorConfig config;
    config.min_height_m = 0.25;
    config.max_height_m = 1.0;
    config.min_slope_rad = trial % 2 ? kPi / 4 : std::atan(2.0);
    const PairTest test(config);
    const int count = 1 + static_cast<int>(rng() % 64);
    std::vector<float> x(count + 16, 0.0f), y(count + 16, 0.0f), z(count + 16, inf);
    for (int k = 0; k < count; ++k) {
      x[k] = eighths(-4, 4);
      y[k] = eighths(-4, 4);
      z[k] = eighths(-8, 8);
    }
    float lo[3], hi[3];
    for (int d = 0; d < 3; ++d) {
      lo[d] = eighths(-4, 4);
      hi[d] = lo[d] + eighths(0, d < 2 ? 2 : 4);
    }
    std::uint64_t keep_one = 0, accept_one = 0;
    internal::ClassifyByBox(1, x.data(), y.data(), z.data(), count, lo, hi, test, keep_one,
                            accept_one);
    float near_lo_one[3], near_hi_one[3];
    const std::uint64_t near_one = internal::NearBox(1, x.data(), y.data(), z.data(), count, lo, hi,
                                                     test, near_lo_one, near_hi_one);
    kept += __builtin_popcountll(keep_one);
    accepted += __builtin_popcountll(accept_one);
    near += __builtin_popcountll(near_one);
    for (int k = 0; k < count; ++k) {
      on_bound += z[k] - lo[2] == 0.25f || hi[2] - z[k] == 0.25f || lo[2] - z[k] == 0.25f;
    }
    for (const int lanes : {4, 8, 16}) {
      if (lanes > internal::VectorLanes()) continue;
      const std::string what = std::to_string(lanes) + " lanes, trial " + std::to_string(trial);
      std::uint64_t keep = 0, accept = 0;
      internal::ClassifyByBox(lanes, x.data(), y.data(), z.data(), count, lo, hi, test, keep,
                              accept);
      EXPECT_EQ(keep, keep_one) << what;
      EXPECT_EQ(accept, accept_one) << what;
      float near_lo[3], near_hi[3];
      EXPECT_EQ(internal::NearBox(lanes, x.data(), y.data(), z.data(), count, lo, hi, test, near_lo,
                                  near_hi),
                near_one)
          << what;
      for (int d = 0; d < 3; ++d) {
        EXPECT_EQ(near_lo[d], near_lo_one[d]) << what;
        EXPECT_EQ(near_hi[d], near_hi_one[d]) << what;
      }
    }
  }
  // Every verdict is met often, and bounds are hit.
  EXPECT_GT(accepted, 1000);
  EXPECT_GT(kept - accepted, 1000);
  EXPECT_GT(near, 1000);
  EXPECT_GT(on_bound, 1000);
  std::printf("box tests: %lld kept, %lld accepted, %lld near, %lld on a bound\n",
              static_cast<long long>(kept), static_cast<long long>(accepted),
              static_cast<long long>(near), static_cast<long long>(on_bound));
}

// Every vector width the processor has (simd.hpp), down to one pair at a time, finds the same
// pairs: random views, scans and the lattice against the definition (both detectors), and the
// KITTI scan against the widest.
TEST(PairSearch, EveryVectorWidthFindsTheSamePairs) {
  struct Uncap {
    ~Uncap() { internal::CapVectorLanes(0); }
  } uncap;
  const int widest = internal::VectorLanes();
  std::mt19937 rng(515);
  std::vector<RangeImage> images;
  std::vector<DetectorConfig> configs;
  for (int k = 0; k < 6; ++k) {
    images.push_back(RandomView(600 + k, k % 2 ? 0.03 : 0.0, 0.05));
    configs.push_back(RandomConfig(rng));
  }
  for (int k = 0; k < 4; ++k) {
    images.push_back(RandomScan(rng, k % 2 ? "VLP-16" : "OS1-64", 60 + 8 * k));
    configs.push_back(RandomConfig(rng));
  }
  for (int trial = 0; trial < 6; ++trial) {
    images.push_back(LatticeImage(rng, 40, 30, 10.0 + trial));
    configs.push_back(LatticeConfig(trial));
  }
  std::vector<Detection> brute;
  for (std::size_t k = 0; k < images.size(); ++k) {
    configs[k].threads = 1;
    brute.push_back(*DetectBruteForce(images[k], configs[k]));
  }
  const std::string kitti = kShared + "/kitti-seq00-0-10/velodyne/000000.bin";
  std::optional<RangeImage> scan;
  DetectorConfig scan_config;
  std::optional<Detection> widest_scan;
  if (std::filesystem::exists(kitti)) {
    scan = *LoadScan(kitti, "HDL-64E");
    scan_config = io::LoadDetectSettings(kSource + "/config/sensors/hdl-64e.yaml")->detector;
    scan_config.threads = 1;
    widest_scan = *Detect(*scan, scan_config);
  }
  // The point trees of the lattice (many equal heights) and of a random view (few), blocks of
  // 2 x 32 and of 8 x 8 (each one leaf) and Detect's (split in space), one at a time: each
  // leaf's points by height, ties in pixel order, and the same nodes (their points, children,
  // parents and boxes; a box's zero may differ in sign only, which == does not see).
  const auto trees = [&] {
    std::vector<std::vector<float>> stored;
    std::vector<std::size_t> tree_images = {0};
    for (std::size_t k = images.size() - 6; k < images.size(); ++k) tree_images.push_back(k);
    for (const std::size_t k : tree_images) {
      const internal::LevelPoints level(images[k]);
      std::vector<std::uint8_t> all(images[k].size());
      for (int i = 0; i < images[k].size(); ++i) all[i] = images[k].valid(i);
      for (const internal::BlockShape block :
           {internal::BlockShape{2, 32}, internal::BlockShape{8, 8}, internal::kLidarBlock,
            internal::kCameraBlock}) {
        const internal::PointTree tree(level, all, images[k].width(), images[k].height(),
                                       block.rows, block.cols);
        stored.push_back(tree.z);
        stored.emplace_back(tree.pixel.begin(), tree.pixel.end());
        std::vector<float> nodes;
        for (const internal::PointTree::Node& node : tree.nodes) {
          nodes.insert(nodes.end(),
                       {node.lo[0], node.lo[1], node.lo[2], node.hi[0], node.hi[1], node.hi[2],
                        static_cast<float>(node.begin), static_cast<float>(node.end),
                        static_cast<float>(node.child[0]), static_cast<float>(node.child[1]),
                        static_cast<float>(node.parent)});
        }
        stored.push_back(std::move(nodes));
      }
    }
    return stored;
  };
  internal::CapVectorLanes(1);
  const std::vector<std::vector<float>> one_at_a_time = trees();
  int widths = 0;
  std::vector<DetectionStats> cone_stats;  // at the widest width
  // The column baseline takes one path at two widths where every column of an image is of one
  // kind: at most 64 points (searched whole at eight and sixteen lanes) or more (binned, four
  // at a time at four and eight lanes). Path 0: none shared.
  const auto column_path = [](const RangeImage& image, int lanes) {
    int least = image.height(), most = 0;
    for (int c = 0; c < image.width(); ++c) {
      int valid = 0;
      for (int r = 0; r < image.height(); ++r) valid += image.valid(r * image.width() + c);
      least = std::min(least, valid);
      most = std::max(most, valid);
    }
    if (lanes >= 8 && most <= 64) return 16;
    if (lanes == 4 || (lanes == 8 && least > 64)) return 4;
    return 0;
  };
  std::map<std::pair<std::size_t, int>, DetectionStats> column_stats;  // by image and path
  for (int lanes : {16, 8, 4, 1}) {
    if (lanes > widest) continue;
    ++widths;
    internal::CapVectorLanes(lanes);
    ASSERT_EQ(internal::VectorLanes(), lanes);
    EXPECT_TRUE(trees() == one_at_a_time) << lanes << " lanes: the point trees differ";
    const std::string width = std::to_string(lanes) + " lanes, ";
    for (std::size_t k = 0; k < images.size(); ++k) {
      const std::string what = width + "image " + std::to_string(k);
      const Detection cone = *Detect(images[k], configs[k]);
      ExpectSame(cone, brute[k], what);
      ExpectSameColumns(images[k], configs[k], 0, what);
      // On one thread every width takes the same steps: the same pairs tested and found, one
      // by one (a wrong window or a lost hit shows here even where the labels hide it). The
      // column baseline too, at the widths that take one path on the image (column_path).
      ColumnConfig column_config = ColumnConfig::From(configs[k]);
      column_config.min_blob_pixels = 0;
      const DetectionStats columns = DetectColumns(images[k], column_config)->stats;
      if (const int path = column_path(images[k], lanes); path != 0) {
        const auto [first, made] = column_stats.emplace(std::pair(k, path), columns);
        if (!made) {
          EXPECT_EQ(columns.pairs_tested, first->second.pairs_tested) << what << " (columns)";
          EXPECT_EQ(columns.pairs_compatible, first->second.pairs_compatible)
              << what << " (columns)";
        }
      }
      if (cone_stats.size() <= k) cone_stats.push_back(cone.stats);
      if (lanes == widest) continue;
      EXPECT_EQ(cone.stats.pairs_tested, cone_stats[k].pairs_tested) << what;
      EXPECT_EQ(cone.stats.pairs_compatible, cone_stats[k].pairs_compatible) << what;
    }
    if (scan) {
      const Detection found = *Detect(*scan, scan_config);
      ExpectSame(found, *widest_scan, width + "KITTI 00 scan 0");
      EXPECT_EQ(found.stats.pairs_tested, widest_scan->stats.pairs_tested) << width;
      EXPECT_EQ(found.stats.pairs_compatible, widest_scan->stats.pairs_compatible) << width;
    }
  }
  EXPECT_GE(widths, widest > 1 ? 2 : 1);
  std::printf("vector widths checked: up to %d lanes%s\n", widest,
              scan ? "" : " (the KITTI scan is absent: ../shared/datasets)");
}

// The bundled demo frame and its detector settings (config/default.yaml).
RangeImage DemoFrame() {
  const std::string dir = kSource + "/datasets/frames/demo/";
  const io::CameraIntrinsics camera = *io::LoadIntrinsics(dir + "intrinsics.yaml");
  const od::Grid<float> depth = *io::ReadDepthImage(dir + "depth.png", camera);
  return *RangeImage::FromDepth(depth.data, camera.model, camera.up);
}
DetectorConfig DemoConfig() {
  return io::LoadDetectSettings(kSource + "/config/default.yaml", {"map", "tilt", "frames"})
      ->detector;
}

// Detect's trees (blocks of pixels, each split in space into leaves): every point stored once,
// leaves of at most kMaxLeafPoints by height (ties in pixel order), each node's box the exact
// box of its points, each leaf within one block, and each split of a block's points at a plane
// across the longest side of its box, which leaves its two parts apart on that side (unless
// that side is at most one float step long). Blocks with more points than a leaf are split, on
// every image kind; a block of one point many times is halved in pixel order.
TEST(PairSearch, TheTreesSplitEachBlockInSpaceIntoLeavesOfNearbyPoints) {
  std::mt19937 rng(2207);
  std::vector<RangeImage> images = {RandomView(71, 0.0, 0.05), RandomView(72, 0.03, 0.2),
                                    RandomScan(rng, "OS1-64", 256), LatticeImage(rng, 40, 30, 12.0),
                                    DemoFrame()};
  for (std::size_t k = 0; k < images.size(); ++k) {
    const RangeImage& image = images[k];
    const internal::LevelPoints level(image);
    const internal::BlockShape block = internal::BlockShapeFor(image);
    std::vector<std::uint8_t> mask(image.size());
    for (int i = 0; i < image.size(); ++i) mask[i] = image.valid(i) && rng() % 4 != 0;
    const internal::PointTree tree(level, mask, image.width(), image.height(), block.rows,
                                   block.cols);
    const std::string what = "image " + std::to_string(k);
    std::vector<std::int32_t> stored = tree.pixel, wanted;
    std::sort(stored.begin(), stored.end());
    for (int i = 0; i < image.size(); ++i) {
      if (mask[i]) wanted.push_back(i);
    }
    ASSERT_EQ(stored, wanted) << what;
    ASSERT_EQ(tree.roots.size(), 1u) << what;
    ASSERT_GE(tree.roots[0], 0);
    EXPECT_EQ(tree.nodes[tree.roots[0]].parent, -1) << what;
    EXPECT_EQ(tree.nodes[tree.roots[0]].begin, 0) << what;
    EXPECT_EQ(tree.nodes[tree.roots[0]].end, tree.size()) << what;
    const auto block_of = [&](int pixel) {
      return std::pair(pixel / image.width() / block.rows, pixel % image.width() / block.cols);
    };
    int splits = 0;
    for (std::size_t n = 0; n < tree.nodes.size(); ++n) {
      const internal::PointTree::Node& node = tree.nodes[n];
      const std::string at = what + ", node " + std::to_string(n);
      ASSERT_LT(node.begin, node.end) << at;
      float lo[3] = {tree.x[node.begin], tree.y[node.begin], tree.z[node.begin]};
      float hi[3] = {lo[0], lo[1], lo[2]};
      bool one_block = true;
      for (int j = node.begin; j < node.end; ++j) {
        const float q[3] = {tree.x[j], tree.y[j], tree.z[j]};
        for (int d = 0; d < 3; ++d) {
          lo[d] = std::min(lo[d], q[d]);
          hi[d] = std::max(hi[d], q[d]);
        }
        one_block = one_block && block_of(tree.pixel[j]) == block_of(tree.pixel[node.begin]);
      }
      for (int d = 0; d < 3; ++d) {
        EXPECT_EQ(node.lo[d], lo[d]) << at;
        EXPECT_EQ(node.hi[d], hi[d]) << at;
      }
      if (node.child[0] < 0) {
        EXPECT_LE(node.end - node.begin, internal::PointTree::kMaxLeafPoints) << at;
        EXPECT_TRUE(one_block) << at;
        for (int j = node.begin + 1; j < node.end; ++j) {
          EXPECT_TRUE(tree.z[j - 1] < tree.z[j] ||
                      (tree.z[j - 1] == tree.z[j] && tree.pixel[j - 1] < tree.pixel[j]))
              << at;
        }
        continue;
      }
      const internal::PointTree::Node& a = tree.nodes[node.child[0]];
      const internal::PointTree::Node& b = tree.nodes[node.child[1]];
      EXPECT_EQ(a.parent, static_cast<int>(n)) << at;
      EXPECT_EQ(b.parent, static_cast<int>(n)) << at;
      EXPECT_EQ(a.begin, node.begin) << at;
      EXPECT_EQ(a.end, b.begin) << at;
      EXPECT_EQ(b.end, node.end) << at;
      if (!one_block) continue;
      ++splits;
      EXPECT_GT(node.end - node.begin, internal::PointTree::kMaxLeafPoints) << at;
      int axis = 0;
      for (int d = 1; d < 3; ++d) {
        if (hi[d] - lo[d] > hi[axis] - lo[axis]) axis = d;
      }
      const bool one_step = std::nextafter(lo[axis], hi[axis] + 1.0f) >= hi[axis];
      EXPECT_TRUE(one_step || a.hi[axis] < b.lo[axis]) << at << ": parts not apart";
    }
    EXPECT_GT(splits, 0) << what << ": no block split";
  }
  // A block whose points all coincide (a camera block of 16 x 16 on the random view, every
  // pixel made one point): no side to split, so halves in pixel order, down to four leaves of
  // 64, each in pixel order.
  const RangeImage& view = images[0];
  internal::LevelPoints level(view);
  std::vector<std::uint8_t> mask(view.size(), 0);
  const int side = internal::kCameraBlock.rows;
  ASSERT_EQ(internal::kCameraBlock.cols, side);
  ASSERT_EQ(side * side, 4 * internal::PointTree::kMaxLeafPoints);
  for (int r = 0; r < side; ++r) {
    for (int c = 0; c < side; ++c) {
      const int i = r * view.width() + c;
      level.x[i] = 1.0f;
      level.y[i] = 2.0f;
      level.z[i] = 0.5f;
      mask[i] = 1;
    }
  }
  const internal::PointTree tree(level, mask, view.width(), view.height(), side, side);
  ASSERT_EQ(tree.size(), side * side);
  int leaves = 0;
  for (const internal::PointTree::Node& node : tree.nodes) {
    if (node.child[0] >= 0) continue;
    ++leaves;
    EXPECT_EQ(node.end - node.begin, internal::PointTree::kMaxLeafPoints);
    for (int j = node.begin + 1; j < node.end; ++j) EXPECT_LT(tree.pixel[j - 1], tree.pixel[j]);
  }
  EXPECT_EQ(leaves, 4);
  for (int j = 1; j < tree.size(); ++j) EXPECT_LT(tree.pixel[j - 1], tree.pixel[j]);
}

TEST(PairSearch, EqualsTheRegionScanOnTheDemoFrame) {
  const RangeImage image = DemoFrame();
  DetectorConfig config = DemoConfig();
  config.threads = 2;
  const Detection scan = *DetectRegionScan(image, config);
  EXPECT_GT(scan.segments.size(), 5u);
  for (int threads : {1, 2, 5}) {
    config.threads = threads;
    ExpectSame(*Detect(image, config), scan, "demo frame, " + std::to_string(threads) + " threads");
  }
  ExpectSameColumns(image, config, 10, "demo frame");
}

// Each segment's features against their definitions (detector.hpp), recomputed here in one
// pass over the labels: counts, feet, the level-frame box, centroid and ground (in double
// here, in float in the detector), ranges, rows and columns, and the slope.
void ExpectFeaturesFollowTheirDefinitions(const RangeImage& image, const Detection& d,
                                          const std::string& frame) {
  const Eigen::Matrix3d R = image.R_level_sensor();
  struct Sums {
    int points = 0, feet = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = Eigen::Vector3d::Constant(-1e30);
    double range_sum = 0.0;
    int slope_points = 0;
    double slope_sum = 0.0, slope_max = 0.0;
    int row_min = 1 << 30, row_max = -1, col_min = 1 << 30, col_max = -1;
  };
  std::vector<Sums> sums(d.segments.size());
  const auto level = [&](int i) {
    return Eigen::Vector3d(
        R * Eigen::Vector3f(image.x()[i], image.y()[i], image.z()[i]).cast<double>());
  };
  // The slope: tangents between the detector's own level-frame points (float), of the
  // neighbours on the row and on the column that are in the point's segment (central, else
  // one-sided; rows wrap on spherical images), the normal their cross product, its angle
  // from up by std::atan2.
  const internal::LevelPoints points(image);
  const auto at = [&](int j) { return Eigen::Vector3d(points.x[j], points.y[j], points.z[j]); };
  const int width = image.width(), height = image.height();
  const bool wraps = std::holds_alternative<SphericalModel>(image.model());
  const auto tangent = [&](int i, int before, int after, Eigen::Vector3d& t) {
    const bool b = before >= 0 && d.labels[before] == d.labels[i];
    const bool a = after >= 0 && d.labels[after] == d.labels[i];
    t = (a ? at(after) : at(i)) - (b ? at(before) : at(i));
    return a || b;
  };
  for (int i = 0; i < image.size(); ++i) {
    if (d.labels[i] == 0) continue;
    Sums& s = sums[d.labels[i] - 1];
    const int r = i / width, c = i % width;
    s.row_min = std::min(s.row_min, r);
    s.row_max = std::max(s.row_max, r);
    s.col_min = std::min(s.col_min, c);
    s.col_max = std::max(s.col_max, c);
    const int left = width == 1 ? -1 : (c > 0 ? i - 1 : (wraps ? i + width - 1 : -1));
    const int right = width == 1 ? -1 : (c + 1 < width ? i + 1 : (wraps ? i - c : -1));
    Eigen::Vector3d tu, tv;
    if (tangent(i, left, right, tu) &&
        tangent(i, r > 0 ? i - width : -1, r + 1 < height ? i + width : -1, tv)) {
      const Eigen::Vector3d normal = tu.cross(tv);
      const double horizontal = std::hypot(normal.x(), normal.y());
      if (horizontal > 0.0 || normal.z() != 0.0) {
        const double slope = std::atan2(horizontal, std::abs(normal.z()));
        ++s.slope_points;
        s.slope_sum += slope;
        s.slope_max = std::max(s.slope_max, slope);
      }
    }
    const Eigen::Vector3d p = level(i);
    ++s.points;
    s.feet += d.foot[i];
    s.sum += p;
    s.lo = s.lo.cwiseMin(p);
    s.hi = s.hi.cwiseMax(p);
    s.range_sum += image.range(i);
  }
  for (std::size_t k = 0; k < sums.size(); ++k) {
    const SegmentFeatures& f = d.segments[k];
    const Sums& s = sums[k];
    const std::string what = frame + ", segment " + std::to_string(k + 1);
    EXPECT_EQ(f.point_count, s.points) << what;
    EXPECT_EQ(f.foot_count, s.feet) << what;
    // The level frame in float (the detector's) against double here: 1e-5 m at 10 m.
    EXPECT_LT((f.centroid - s.sum / s.points).norm(), 1e-4) << what;
    EXPECT_LT((f.bbox_min - s.lo).norm(), 1e-4) << what;
    EXPECT_LT((f.bbox_max - s.hi).norm(), 1e-4) << what;
    EXPECT_NEAR(f.ground_height_m, s.lo.z(), 1e-4) << what;
    EXPECT_NEAR(f.range_mean_m, s.range_sum / s.points, 1e-6) << what;
    EXPECT_EQ(f.slope_points, s.slope_points) << what;
    EXPECT_NEAR(f.slope_max_rad, s.slope_max, 1e-9) << what;
    EXPECT_NEAR(f.slope_mean_rad, s.slope_points > 0 ? s.slope_sum / s.slope_points : 0.0, 1e-9)
        << what;
    EXPECT_TRUE(f.row_min == s.row_min && f.row_max == s.row_max && f.col_min == s.col_min &&
                f.col_max == s.col_max)
        << what;
  }
}

// The features of a frame whose segments have tens of thousands of points, summed in parts
// (BuildDetection): bit for bit the same on any number of threads, and equal to each
// segment's features recomputed here from its labels in one pass.
TEST(PairSearch, FeaturesOfTheDemoFrameAreTheSameOnAnyThreadsAndMatchTheirDefinition) {
  const RangeImage image = DemoFrame();
  DetectorConfig config = DemoConfig();
  config.threads = 1;
  const Detection one = *Detect(image, config);
  // BuildDetection's parts: at least 4,096 points and 4 per segment each.
  const int m = one.stats.obstacle_points, segments = static_cast<int>(one.segments.size());
  ASSERT_GE(std::min(m / 4096, m / (4 * segments)), 2)
      << "too few points for the sums to run in parts";
  // Its feet by their definition, counted in those parts too; the raised points from the pair
  // search (too many points to test the pairs one by one here).
  {
    const internal::LevelPoints level(image, 1, config.min_range_m);
    const PairTest test(config);
    const internal::Candidates candidates = internal::FindCandidates(level, test, 1);
    const internal::PointTree lower(level, candidates.lower, image.width(), image.height(),
                                    internal::kCameraBlock.rows, internal::kCameraBlock.cols);
    const internal::PointTree upper(level, candidates.upper, image.width(), image.height(),
                                    internal::kCameraBlock.rows, internal::kCameraBlock.cols);
    const internal::PairSearchResult found =
        internal::SearchPairs(lower, upper, image.size(), test, internal::PairSearchOptions{});
    ExpectFeetFollowTheirDefinition(one, level, found.raised, test.min_height, "demo frame");
  }
  for (int threads : {2, 5}) {
    config.threads = threads;
    const Detection many = *Detect(image, config);
    ASSERT_EQ(many.segments.size(), one.segments.size());
    EXPECT_TRUE(many.labels == one.labels && many.foot == one.foot) << threads << " threads";
    for (std::size_t s = 0; s < one.segments.size(); ++s) {
      const SegmentFeatures& a = many.segments[s];
      const SegmentFeatures& b = one.segments[s];
      const std::string what = std::to_string(threads) + " threads, segment " + std::to_string(s);
      EXPECT_EQ(a.centroid, b.centroid) << what;
      EXPECT_EQ(a.slope_mean_rad, b.slope_mean_rad) << what;
      EXPECT_EQ(a.slope_max_rad, b.slope_max_rad) << what;
      EXPECT_EQ(a.range_mean_m, b.range_mean_m) << what;
      EXPECT_EQ(a.height_mean_m, b.height_mean_m) << what;
      EXPECT_EQ(a.foot_count, b.foot_count) << what;
    }
  }
  ExpectFeaturesFollowTheirDefinitions(image, one, "demo frame");
}

// BuildDetection's segments named by an earlier member (as the search's union-find parents
// name them) give what their first pixels give: here each member names the member of its
// segment just before it, which makes chains as long as the segments.
TEST(PairSearch, SegmentsNamedByEarlierMembersGetTheLabelsOfTheirFirstPixels) {
  const RangeImage image = DemoFrame();
  DetectorConfig config = DemoConfig();
  config.threads = 1;
  const Detection d = *Detect(image, config);
  ASSERT_GT(d.segments.size(), 2u);
  const int n = image.size();
  std::vector<std::int32_t> first(n, -1), previous(n, -1), last(d.segments.size() + 1, -1);
  std::vector<std::uint8_t> raised(n, 0);
  for (int i = 0; i < n; ++i) {
    const int id = d.labels[i];
    if (id == 0) continue;
    first[i] = last[id] < 0 ? i : first[last[id]];
    previous[i] = last[id] < 0 ? i : last[id];
    last[id] = i;
    raised[i] = d.foot[i] == 0;
  }
  const internal::LevelPoints level(image);
  const float ht = static_cast<float>(config.min_height_m);
  const Detection by_first = internal::BuildDetection(image, level, first, raised, ht, d.stats);
  const Detection by_previous =
      internal::BuildDetection(image, level, previous, raised, ht, d.stats);
  ExpectSame(by_previous, by_first, "previous member against first pixel");
  // (Their raised counts are the stand-in marks', not Detect's.)
  EXPECT_TRUE(by_first.labels == d.labels && by_first.foot == d.foot);
}

// The same on LiDAR scans whose near objects straddle the seam of the azimuth (columns
// 0 and width - 1, neighbours on a spherical image), at random settings.
TEST(PairSearch, FeaturesOfLidarScansAcrossTheSeamMatchTheirDefinitions) {
  std::mt19937 rng(2027);
  int across = 0;
  for (int trial = 0; trial < 4; ++trial) {
    // (width - 1) % 17 == 0: the first and last columns are both among the near ones.
    const RangeImage image = RandomScan(rng, trial % 2 ? "VLP-16" : "OS1-64", 69 + 17 * trial);
    DetectorConfig config = RandomConfig(rng);
    const Detection d = *Detect(image, config);
    for (const SegmentFeatures& f : d.segments)
      across += f.col_min == 0 && f.col_max == image.width() - 1;
    ExpectFeaturesFollowTheirDefinitions(image, d, "scan " + std::to_string(trial));
  }
  EXPECT_GT(across, 0) << "no segment across the seam: the test would not see the wrap";
}

// The features, labels and feet at every vector width the processor has, bit for bit: with
// AVX-512F, BuildDetection gathers a segment's pixels sixteen at a time, and takes the normals of
// a run's inner points and the slopes' angles eight at a time; at four lanes it does each one at
// a time (and the angles two at a time). On the demo frame (runs of hundreds of points, first and
// last rows) and on LiDAR scans across the seam (short runs, wrapped neighbours).
TEST(PairSearch, FeaturesAreTheSameAtEveryVectorWidth) {
  struct Uncap {
    ~Uncap() { internal::CapVectorLanes(0); }
  } uncap;
  const int widest = internal::VectorLanes();
  std::mt19937 rng(4242);
  std::vector<std::pair<RangeImage, DetectorConfig>> frames = {{DemoFrame(), DemoConfig()}};
  for (int trial = 0; trial < 3; ++trial) {
    frames.emplace_back(RandomScan(rng, trial % 2 ? "VLP-16" : "OS1-64", 69 + 17 * trial),
                        RandomConfig(rng));
  }
  // What the frames must hold for the wide paths to be seen: runs of ten points or more (a
  // block of eight inner points, or two of four), runs whose last block of four (and so of
  // eight) is shorter, runs in the first or last row (one neighbour in the column), segments
  // across a LiDAR scan's seam.
  int long_runs = 0, short_blocks = 0, edge_runs = 0, across = 0;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const auto& [image, config] = frames[f];
    internal::CapVectorLanes(1);
    const Detection one = *Detect(image, config);
    ASSERT_FALSE(one.segments.empty()) << "frame " << f;
    const int width = image.width(), height = image.height();
    for (int r = 0; r < height; ++r) {
      for (int c = 0; c < width;) {
        const std::int32_t id = one.labels[static_cast<std::size_t>(r) * width + c];
        int len = 1;
        while (c + len < width && one.labels[static_cast<std::size_t>(r) * width + c + len] == id) {
          ++len;
        }
        if (id != 0 && len >= 3) {
          long_runs += len >= 10;
          short_blocks += (len - 2) % 4 != 0;
          edge_runs += r == 0 || r == height - 1;
        }
        c += len;
      }
    }
    for (const SegmentFeatures& s : one.segments) {
      across += s.col_min == 0 && s.col_max == width - 1 &&
                std::holds_alternative<SphericalModel>(image.model());
    }
    for (const int lanes : {16, 8, 4}) {
      if (lanes > widest) continue;
      internal::CapVectorLanes(lanes);
      const Detection d = *Detect(image, config);
      const std::string what =
          "frame " + std::to_string(f) + ", " + std::to_string(lanes) + " lanes against one";
      EXPECT_TRUE(d.labels == one.labels && d.foot == one.foot) << what;
      ASSERT_EQ(d.segments.size(), one.segments.size()) << what;
      for (std::size_t k = 0; k < d.segments.size(); ++k) {
        const SegmentFeatures &a = d.segments[k], &b = one.segments[k];
        EXPECT_TRUE(a.point_count == b.point_count && a.raised_count == b.raised_count &&
                    a.foot_count == b.foot_count && a.slope_points == b.slope_points &&
                    a.bbox_min == b.bbox_min && a.bbox_max == b.bbox_max &&
                    a.centroid == b.centroid && a.range_min_m == b.range_min_m &&
                    a.range_mean_m == b.range_mean_m && a.ground_height_m == b.ground_height_m &&
                    a.row_min == b.row_min && a.row_max == b.row_max && a.col_min == b.col_min &&
                    a.col_max == b.col_max)
            << what << ", segment " << k;
        // Bit for bit (EXPECT_EQ on doubles compares values exactly).
        EXPECT_EQ(a.slope_mean_rad, b.slope_mean_rad) << what << ", segment " << k;
        EXPECT_EQ(a.slope_max_rad, b.slope_max_rad) << what << ", segment " << k;
      }
    }
  }
  EXPECT_GT(long_runs, 0);
  EXPECT_GT(short_blocks, 0);
  EXPECT_GT(edge_runs, 0);
  EXPECT_GT(across, 0);
  if (widest < 16) {
    std::printf("note: no AVX-512F here: the features' paths of sixteen were not run%s\n",
                widest < 8 ? ", nor those of eight (AVX2)" : "");
  }
}

// --- Surface slope -----------------------------------------------------------------------

// A level camera (up = -y) facing a plane that rises 4 m ahead at `slope` from the
// horizontal, with nothing else in view: every tangent between two of its points lies in
// the plane, so every point with neighbours has the plane's slope, to float rounding.
TEST(SegmentSlope, IsTheInclinationOfThePlane) {
  for (double slope_deg : {50.0, 70.0, 90.0}) {
    PinholeModel model;
    model.width = 80;
    model.height = 60;
    model.fx = model.fy = 60.0;
    model.cx = 39.5;
    model.cy = 29.5;
    const double t = std::tan(slope_deg * kDegToRad);
    std::vector<float> depth(model.width * model.height, 0.0f);
    for (int r = 0; r < model.height; ++r) {
      const double v = (r - model.cy) / model.fy;
      // Height above the camera's foot at depth z: 1.5 - v z (y down); on the plane it is
      // t (z - 4) (z - 4 = 0 for the vertical plane). The plane spans 0..2.5 m up.
      const double z = slope_deg == 90.0 ? 4.0 : (1.5 + 4.0 * t) / (t + v);
      const double height = 1.5 - v * z;
      if (height < 0.0 || height > 2.5 || z <= 0.0) continue;
      for (int c = 0; c < model.width; ++c) depth[r * model.width + c] = static_cast<float>(z);
    }
    const RangeImage image = *RangeImage::FromDepth(depth, model, {0.0, -1.0, 0.0});
    DetectorConfig config;
    config.min_height_m = 0.3;
    config.max_height_m = 1.0;
    config.min_slope_rad = 45.0 * kDegToRad;
    const Detection d = *Detect(image, config);
    ASSERT_EQ(d.segments.size(), 1u) << slope_deg << " deg";
    const SegmentFeatures& plane = d.segments[0];
    EXPECT_EQ(plane.slope_points, plane.point_count) << slope_deg << " deg";
    EXPECT_NEAR(plane.slope_max_rad, slope_deg * kDegToRad, 1e-4) << slope_deg << " deg";
    EXPECT_NEAR(plane.slope_mean_rad, slope_deg * kDegToRad, 1e-4) << slope_deg << " deg";
  }
}

}  // namespace
}  // namespace cairn::od
