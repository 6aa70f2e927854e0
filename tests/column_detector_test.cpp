// The column-wise baseline: a frontal wall is found by it and by the cone detector; its
// obstacle points are those of the pair test within each column; blobs are 8-connected and
// small ones are rejected.
#include "cairn/od/column_detector.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/random_scene.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn {
namespace {

od::Detection Columns(const od::RangeImage& image, const od::ColumnConfig& config) {
  Expected<od::Detection> d = od::DetectColumns(image, config);
  if (!d.ok()) {
    ADD_FAILURE() << d.error().message;
    std::abort();
  }
  return std::move(d).value();
}

od::Detection Cone(const od::RangeImage& image, const od::DetectorConfig& config) {
  Expected<od::Detection> d = od::Detect(image, config);
  if (!d.ok()) {
    ADD_FAILURE() << d.error().message;
    std::abort();
  }
  return std::move(d).value();
}

struct Rendered {
  sim::DepthFrame frame;
  od::RangeImage image;
};

Rendered Render(const sim::Scene& scene, const sim::Camera& camera) {
  sim::RenderOptions options;
  options.max_range_m = 40.0;
  sim::DepthFrame frame = sim::RenderDepth(scene, camera, options).value();
  od::RangeImage image =
      od::RangeImage::FromDepth(frame.depth_m, camera.model, frame.up_optical).value();
  return {std::move(frame), std::move(image)};
}

TEST(ColumnDetector, FrontalWallIsFoundByBothDetectors) {
  // A 3 m wide, 0.8 m tall wall 5.85 m ahead, its face towards the camera: every column
  // crossing it sees a vertical profile.
  sim::Scene scene;
  const int wall = scene.Add(sim::Box{{6.0, 0.0, 0.4}, {0.3, 3.0, 0.8}, 0.0}, true);
  const od::PinholeModel model = sim::PinholeFromFov(160, 120, 60.0 * kDegToRad);
  for (const auto& [pitch, roll] : {std::pair{8.0, 0.0}, {15.0, 10.0}}) {
    const sim::Camera camera = sim::Camera::AboveGround(model, scene.terrain(), 0.0, 0.0, 1.6, 0.0,
                                                        pitch * kDegToRad, roll * kDegToRad);
    const Rendered r = Render(scene, camera);
    const od::DetectorConfig config;  // HT 0.3, Hmax 1.0, theta 45 deg
    const od::Detection cone = Cone(r.image, config);
    const od::Detection columns = Columns(r.image, od::ColumnConfig::From(config));
    int face = 0, by_cone = 0, by_columns = 0;
    for (int i = 0; i < r.image.size(); ++i) {
      // The front face: the wall's pixels whose normal points back along -x.
      if (r.frame.object_id[i] != wall || r.frame.normal[i].x() > -0.999f) continue;
      ++face;
      by_cone += cone.is_obstacle(i);
      by_columns += columns.is_obstacle(i);
    }
    ASSERT_GT(face, 500);
    // Every face point has a partner 0.3..0.8 m above or below it, or the ground at its
    // foot, or the top edge.
    EXPECT_GE(by_cone, 0.95 * face) << "pitch " << pitch << ": " << by_cone << " of " << face;
    EXPECT_GE(by_columns, 0.95 * face) << "pitch " << pitch << ": " << by_columns << " of " << face;
    EXPECT_GE(columns.segments.size(), 1u);
  }
}

// Obstacle points by the definition, restricted to pairs within one column, in double
// precision; thresholds moved by `eps` to bracket float rounding. Returns the mask and
// counts the pairs.
std::vector<char> ColumnReference(const od::RangeImage& image, const od::ColumnConfig& config,
                                  double eps, std::int64_t* pairs) {
  std::vector<char> mask(image.size(), 0);
  const Eigen::Vector3d up = image.up();
  const double tan_theta = std::tan(config.min_slope_rad);
  *pairs = 0;
  for (int c = 0; c < image.width(); ++c) {
    for (int r1 = 0; r1 < image.height(); ++r1) {
      const int i = r1 * image.width() + c;
      if (!image.valid(i)) continue;
      const Eigen::Vector3d p = image.point(i);
      for (int r2 = r1 + 1; r2 < image.height(); ++r2) {
        const int j = r2 * image.width() + c;
        if (!image.valid(j)) continue;
        const Eigen::Vector3d d = image.point(j) - p;
        const double dh = std::abs(up.dot(d));
        const double horizontal = std::sqrt(std::max(0.0, d.squaredNorm() - dh * dh));
        if (dh > config.min_height_m + eps && dh < config.max_height_m - eps &&
            dh > tan_theta * horizontal + eps) {
          mask[i] = mask[j] = 1;
          ++*pairs;
        }
      }
    }
  }
  return mask;
}

TEST(ColumnDetector, ObstaclePointsAreThoseOfTheColumnPairs) {
  // On seeded random scenes: the definition within columns brackets the result, and the
  // column pairs are a subset of all pairs, so its mask lies inside the cone detector's.
  sim::Random rng(77);
  int with_obstacles = 0;
  for (int seed = 100; seed < 112; ++seed) {
    sim::RandomSceneOptions options;
    options.width = 96;
    options.height = 72;
    const sim::RandomView view = sim::MakeRandomView(seed, options);
    const Rendered r = Render(view.scene, view.camera);
    od::DetectorConfig config;
    config.min_height_m = rng.Uniform(0.1, 0.5);
    config.max_height_m = config.min_height_m + rng.Uniform(0.2, 1.5);
    config.min_slope_rad = rng.Uniform(25.0, 70.0) * kDegToRad;
    const od::ColumnConfig column_config = od::ColumnConfig::From(config);
    EXPECT_EQ(column_config.min_blob_pixels, 0);
    const od::Detection columns = Columns(r.image, column_config);
    const od::Detection cone = Cone(r.image, config);
    std::int64_t strict_pairs = 0, loose_pairs = 0;
    const auto strict = ColumnReference(r.image, column_config, 1e-4, &strict_pairs);
    const auto loose = ColumnReference(r.image, column_config, -1e-4, &loose_pairs);
    int missed = 0, invented = 0, beyond_cone = 0;
    for (int i = 0; i < r.image.size(); ++i) {
      missed += strict[i] && !columns.is_obstacle(i);
      invented += !loose[i] && columns.is_obstacle(i);
      beyond_cone += columns.is_obstacle(i) && !cone.is_obstacle(i);
    }
    const std::string what = "scene " + std::to_string(seed);
    EXPECT_EQ(missed, 0) << what;
    EXPECT_EQ(invented, 0) << what;
    EXPECT_EQ(beyond_cone, 0) << what;
    with_obstacles += columns.stats.obstacle_points > 0;
  }
  EXPECT_GE(with_obstacles, 6);
}

// A hand-made sparse depth image seen by a level camera (up = -y): fx = fy = 25, depth 5 m,
// so one row is 0.2 m of height. Four pixels stacked in a column at the same depth are all
// obstacle points (rows 2 apart differ by 0.4 m, vertically). Everything else is invalid.
//   blob A: column 5 rows 4..7 and column 6 rows 8..11 (touching only diagonally)
//   blob B: column 15 rows 4..7
//   blobs C, D: columns 18 and 20, rows 14..17 (a one-pixel gap between them)
constexpr int kSide = 24;

od::RangeImage HandMade() {
  std::vector<float> depth(kSide * kSide, 0.0f);
  auto stack = [&](int col, int first_row) {
    for (int r = first_row; r < first_row + 4; ++r) depth[r * kSide + col] = 5.0f;
  };
  stack(5, 4);
  stack(6, 8);
  stack(15, 4);
  stack(18, 14);
  stack(20, 14);
  od::PinholeModel model;
  model.width = model.height = kSide;
  model.fx = model.fy = 25.0;
  model.cx = model.cy = 11.5;
  return od::RangeImage::FromDepth(depth, model, Eigen::Vector3d(0.0, -1.0, 0.0)).value();
}

int Label(const od::Detection& d, int col, int row) { return d.labels[row * kSide + col]; }

TEST(ColumnDetector, BlobsAreEightConnected) {
  const od::RangeImage image = HandMade();
  ASSERT_EQ(image.valid_count(), 20);
  const od::Detection d = Columns(image, od::ColumnConfig());
  EXPECT_EQ(d.stats.obstacle_points, 20);
  ASSERT_EQ(d.segments.size(), 4u);
  // Numbered in row-major order of their first pixel: A (4, 5), B (4, 15), C (14, 18),
  // D (14, 20).
  for (int r = 4; r < 8; ++r) EXPECT_EQ(Label(d, 5, r), 1);
  for (int r = 8; r < 12; ++r) EXPECT_EQ(Label(d, 6, r), 1) << "diagonal neighbour not joined";
  for (int r = 4; r < 8; ++r) EXPECT_EQ(Label(d, 15, r), 2);
  for (int r = 14; r < 18; ++r) EXPECT_EQ(Label(d, 18, r), 3);
  for (int r = 14; r < 18; ++r) EXPECT_EQ(Label(d, 20, r), 4) << "joined across a gap";
  EXPECT_EQ(d.segments[0].point_count, 8);
  EXPECT_EQ(d.segments[1].point_count, 4);
  EXPECT_EQ(d.segments[0].row_min, 4);
  EXPECT_EQ(d.segments[0].row_max, 11);
  EXPECT_EQ(d.segments[0].col_min, 5);
  EXPECT_EQ(d.segments[0].col_max, 6);
  // Three pairs per stack of four: rows (0, 2), (0, 3), (1, 3); neighbours are only
  // 0.2 m apart, below HT. Rows 2 and 3 stand above a partner: two raised points a stack.
  EXPECT_EQ(d.segments[0].raised_count, 4);
  EXPECT_EQ(d.segments[1].raised_count, 2);
}

TEST(ColumnDetector, BlobAreaRejectionRemovesSmallBlobs) {
  const od::RangeImage image = HandMade();
  od::ColumnConfig config;
  config.min_blob_pixels = 5;  // keeps A (8 px), drops B, C, D (4 px each)
  od::Detection d = Columns(image, config);
  ASSERT_EQ(d.segments.size(), 1u);
  EXPECT_EQ(d.segments[0].point_count, 8);
  for (int i = 0; i < kSide * kSide; ++i) {
    const int col = i % kSide;
    EXPECT_EQ(d.labels[i], (col == 5 || col == 6) && image.valid(i) ? 1 : 0) << i;
  }
  config.min_blob_pixels = 8;  // fewer than 8 is rejected: A stays
  EXPECT_EQ(Columns(image, config).segments.size(), 1u);
  config.min_blob_pixels = 9;
  d = Columns(image, config);
  EXPECT_TRUE(d.segments.empty());
  for (std::int32_t label : d.labels) EXPECT_EQ(label, 0);
}

// An image of no pixels (a default RangeImage): no obstacles, quickly, from both.
TEST(ColumnDetector, AnEmptyImageHasNoObstacles) {
  const od::RangeImage empty;
  const od::ColumnConfig config;
  for (const bool fast : {true, false}) {
    const Expected<od::Detection> d =
        fast ? od::DetectColumns(empty, config) : od::DetectColumnsBruteForce(empty, config);
    ASSERT_TRUE(d.ok()) << d.error().message;
    EXPECT_TRUE(d->labels.empty() && d->segments.empty()) << (fast ? "fast" : "brute force");
  }
}

TEST(ColumnConfig, ValidationNamesTheBadField) {
  EXPECT_TRUE(od::ColumnConfig().Validate().ok());
  od::ColumnConfig c;
  c.min_blob_pixels = -1;
  ASSERT_FALSE(c.Validate().ok());
  EXPECT_NE(c.Validate().message().find("min_blob_pixels"), std::string::npos)
      << c.Validate().message();
  c = od::ColumnConfig();
  c.min_height_m = 1.5;  // above Hmax
  ASSERT_FALSE(c.Validate().ok());
  const std::string m = c.Validate().message();
  EXPECT_TRUE(m.find("min_height") != std::string::npos ||
              m.find("max_height") != std::string::npos)
      << m;
  c = od::ColumnConfig();
  c.min_slope_rad = 100.0 * kDegToRad;
  ASSERT_FALSE(c.Validate().ok());
  EXPECT_NE(c.Validate().message().find("min_slope"), std::string::npos) << c.Validate().message();
  EXPECT_FALSE(od::DetectColumns(HandMade(), c).ok());
}

}  // namespace
}  // namespace cairn
