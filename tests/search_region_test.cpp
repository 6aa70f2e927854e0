// The exact search region is conservative: every pixel whose point is a compatible partner
// lies inside the region computed for the lower point, whatever the tilt, the intrinsics,
// the parameters and however near the points come to the camera.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "../libod/src/detection_internal.hpp"
#include "../libod/src/search_region.hpp"
#include "cairn/od/leveling.hpp"

namespace cairn::od {
namespace {

bool Inside(const internal::RowSpans& spans, int row, int col) {
  return row >= spans.row_begin && row < spans.row_end && col >= spans.col_begin[row] &&
         col < spans.col_end[row];
}

TEST(SearchRegion, ContainsEveryCompatiblePartner) {
  std::mt19937 rng(20021);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::int64_t pairs_checked = 0;
  for (int trial = 0; trial < 120; ++trial) {
    PinholeModel model;
    model.width = 24 + static_cast<int>(rng() % 40);
    model.height = 18 + static_cast<int>(rng() % 30);
    model.fx = 20.0 + 80.0 * u01(rng);
    model.fy = model.fx * (0.8 + 0.4 * u01(rng));
    model.cx = model.width * u01(rng);
    model.cy = model.height * u01(rng);
    // Depths spread over a wide band with holes, so that cones often reach nearer than the
    // nearest point (the clipped case) and partners abound.
    std::vector<float> depth(static_cast<std::size_t>(model.width) * model.height);
    const double base = 0.3 + 5.0 * u01(rng);
    for (float& d : depth) d = u01(rng) < 0.1 ? 0.0f : static_cast<float>(base * (0.5 + 3 * u01(rng)));
    Eigen::Vector3d up = CameraUpFromPitchRoll((u01(rng) - 0.5) * 1.2, (u01(rng) - 0.5) * 1.0);
    if (trial % 4 == 0) up = Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5);
    const Expected<RangeImage> image = RangeImage::FromDepth(depth, model, up);
    ASSERT_TRUE(image.ok()) << image.error().message;
    DetectorConfig config;
    config.min_height_m = 0.05 + 0.5 * u01(rng);
    config.max_height_m = config.min_height_m + 0.1 + 2.0 * u01(rng);
    config.min_slope_rad = 0.1 + 1.3 * u01(rng);
    config.region_slabs = 1 + static_cast<int>(rng() % 6);

    const internal::LevelPoints level(*image);
    const PairTest test(config);
    const internal::PinholeConeRegion region(model, image->up(), config,
                                             internal::NearestDepth(*image));
    internal::RowSpans spans(model.height);
    for (int p = 0; p < image->size(); ++p) {
      if (!image->valid(p)) continue;
      region.Compute(image->point(p), spans);
      for (int q = 0; q < image->size(); ++q) {
        if (!test(level.x[q] - level.x[p], level.y[q] - level.y[p], level.z[q] - level.z[p])) {
          continue;
        }
        ++pairs_checked;
        ASSERT_TRUE(Inside(spans, q / model.width, q % model.width))
            << "trial " << trial << ": partner " << q << " of " << p << " outside the region";
      }
    }
  }
  EXPECT_GT(pairs_checked, 100000);  // the property was exercised, not vacuous
}

TEST(SearchRegion, LevelCameraOnFlatGroundLooksUpwardOnly) {
  // A level camera 1.5 m above flat ground; a ground point 10 m ahead. Its upper cone
  // (0.3..1 m above it, 45 deg) projects between the rows of heights -1.2 m and -0.5 m
  // relative to the camera at depths 9..11 m: well above the point's own row, and only a
  // few columns wide. The region must hold that and must not be the whole image.
  PinholeModel model{640, 480, 500.0, 500.0, 319.5, 239.5};
  DetectorConfig config;  // HT 0.3, Hmax 1.0, 45 deg
  const internal::PinholeConeRegion region(model, Eigen::Vector3d(0, -1, 0), config, 2.0);
  internal::RowSpans spans(model.height);
  const Eigen::Vector3d p(0.0, 1.5, 10.0);  // projects to row 314.5, col 319.5
  region.Compute(p, spans);
  // Highest image row: the top rim's far point, y = 0.5, z = 11 -> row 262.2; lowest: the
  // bottom rim's near point, y = 1.2, z = 9.7 -> row 301.4. One pixel of margin each side.
  EXPECT_GE(spans.row_begin, 261);
  EXPECT_LE(spans.row_begin, 262);
  EXPECT_GE(spans.row_end, 302);
  EXPECT_LE(spans.row_end, 303);
  // Widest: the top rim (radius 1 m about depth 10 m) reaches x/z = 1/sqrt(99): +-50.3 px.
  int widest = 0;
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    EXPECT_GE(spans.col_begin[r], 319 - 52);
    EXPECT_LE(spans.col_end[r], 320 + 52);
    widest = std::max(widest, spans.col_end[r] - spans.col_begin[r]);
  }
  EXPECT_GE(widest, 100);
}

}  // namespace
}  // namespace cairn::od
