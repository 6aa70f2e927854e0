// The exact search region is conservative: every pixel whose point is a compatible partner
// lies inside the region computed for the lower point, whatever the tilt, the intrinsics,
// the parameters and however near the points come to the camera.
#include "../libod/src/search_region.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../libod/src/detection_internal.hpp"
#include "../libod/src/simd.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"

namespace cairn::od {
namespace {

// Checks that every compatible partner of every point lies in that point's search region;
// returns the number of pairs checked.
std::int64_t CheckEveryPartnerInside(const RangeImage& image, const DetectorConfig& config,
                                     const std::string& what) {
  const internal::LevelPoints level(image);
  const PairTest test(config);
  const internal::ConeRegion region(image, config);
  internal::RowSpans spans(image.height());
  std::int64_t checked = 0;
  for (int p = 0; p < image.size(); ++p) {
    if (!image.valid(p)) continue;
    region.Compute(p, spans);
    for (int q = 0; q < image.size(); ++q) {
      if (!test(level.x[q] - level.x[p], level.y[q] - level.y[p], level.z[q] - level.z[p])) {
        continue;
      }
      ++checked;
      EXPECT_TRUE(spans.Contains(q / image.width(), q % image.width(), image.width()))
          << what << ": partner " << q << " of " << p << " outside the region";
      if (::testing::Test::HasFailure()) return checked;
    }
  }
  return checked;
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
    for (float& d : depth)
      d = u01(rng) < 0.1 ? 0.0f : static_cast<float>(base * (0.5 + 3 * u01(rng)));
    Eigen::Vector3d up = CameraUpFromPitchRoll((u01(rng) - 0.5) * 1.2, (u01(rng) - 0.5) * 1.0);
    if (trial % 4 == 0) up = Eigen::Vector3d(u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5);
    const Expected<RangeImage> image = RangeImage::FromDepth(depth, model, up);
    ASSERT_TRUE(image.ok()) << image.error().message;
    DetectorConfig config;
    config.min_height_m = 0.05 + 0.5 * u01(rng);
    config.max_height_m = config.min_height_m + 0.1 + 2.0 * u01(rng);
    config.min_slope_rad = 0.1 + 1.3 * u01(rng);
    config.region_slabs = 1 + static_cast<int>(rng() % 6);

    pairs_checked +=
        CheckEveryPartnerInside(*image, config, "pinhole trial " + std::to_string(trial));
  }
  EXPECT_GT(pairs_checked, 100000);  // the property was exercised, not vacuous
}

// A random spinning-LiDAR scan: every cell returns with probability 0.9 at a random range,
// its direction jittered off the nominal ring by up to jitter / 200 rad and off the column
// centre by up to jitter / 2 steps, into neighbouring columns (as
// beam offsets and motion do), the sensor tilted at random.
RangeImage RandomScan(std::mt19937& rng, const std::string& preset, int width, double jitter) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const SphericalModel model = *SphericalModel::Preset(preset, width);
  std::vector<Eigen::Vector3f> points;
  std::vector<std::int32_t> rows, cols;
  const double base = 1.0 + 10.0 * u01(rng);
  for (int r = 0; r < model.height(); ++r) {
    for (int c = 0; c < width; ++c) {
      if (u01(rng) < 0.1) continue;
      const double e = model.ring_elevation_rad[r] + jitter * 0.01 * (u01(rng) - 0.5);
      const double a =
          model.ColumnAzimuth(c) + jitter * model.azimuth_step_rad() * (u01(rng) - 0.5);
      const double range = base * (0.3 + 2.0 * u01(rng));
      points.emplace_back(range * std::cos(e) * std::cos(a), range * std::cos(e) * std::sin(a),
                          range * std::sin(e));
      rows.push_back(r);
      cols.push_back(c);
    }
  }
  const Eigen::Vector3d up(0.4 * (u01(rng) - 0.5), 0.4 * (u01(rng) - 0.5), 1.0);
  return *RangeImage::FromPoints(points, model, up, rows, cols);
}

TEST(SearchRegion, ContainsEveryCompatiblePartnerOnLidarScans) {
  std::mt19937 rng(2048);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::int64_t pairs_checked = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const RangeImage image = RandomScan(rng, trial % 2 ? "VLP-16" : "OS1-64", 48 + trial * 4,
                                        trial % 3 == 0 ? 0.0 : 4.0);
    DetectorConfig config;
    config.min_height_m = 0.05 + 0.5 * u01(rng);
    config.max_height_m = config.min_height_m + 0.1 + 2.0 * u01(rng);
    config.min_slope_rad = 0.1 + 1.3 * u01(rng);
    // Many thin slabs leave the least slack, so that the column offsets matter.
    config.region_slabs = trial % 2 ? 64 : 1 + static_cast<int>(rng() % 6);
    pairs_checked += CheckEveryPartnerInside(image, config, "lidar trial " + std::to_string(trial));
  }
  EXPECT_GT(pairs_checked, 100000);
}

// The level frame: R_level_sensor p for every point, in float as (r0 x + r1 y) + r2 z (to
// 1e-6 of the product in double), NaN for every hole, the same on any number of threads (the
// points run four at a time, in parts).
TEST(LevelPoints, AreTheTiltedPointsOnAnyThreads) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 4; ++trial) {
    const RangeImage image = RandomScan(rng, "OS1-64", 61 + trial * 7, 4.0 * trial);
    const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();  // as the detector rounds it
    const internal::LevelPoints one(image, 1), three(image, 3);
    int valid = 0;
    for (int i = 0; i < image.size(); ++i) {
      if (!image.valid(i)) {
        EXPECT_TRUE(std::isnan(one.x[i]) && std::isnan(one.y[i]) && std::isnan(one.z[i]));
        continue;
      }
      ++valid;
      const float p[3] = {image.x()[i], image.y()[i], image.z()[i]};
      const float* level[3] = {one.x.data(), one.y.data(), one.z.data()};
      const Eigen::Vector3d exact =
          image.R_level_sensor() * Eigen::Vector3f(p[0], p[1], p[2]).cast<double>();
      for (int a = 0; a < 3; ++a) {
        const float sum = R(a, 0) * p[0] + R(a, 1) * p[1] + R(a, 2) * p[2];
        ASSERT_EQ(level[a][i], sum) << "trial " << trial << ", pixel " << i << ", axis " << a;
        ASSERT_NEAR(level[a][i], exact[a], 1e-6 * (1.0 + exact.norm()));
      }
      ASSERT_EQ(three.x[i], one.x[i]);
      ASSERT_EQ(three.y[i], one.y[i]);
      ASSERT_EQ(three.z[i], one.z[i]);
    }
    EXPECT_GT(valid, 1000);
  }
}

// The features' slope angle: std::atan2 to 2e-10 rad over every octant piece, their
// borders, ratios from 1e-12 to 1e12, zeros and infinities; the loop of them (eight at a
// time with AVX-512F, four with AVX2, two at a time in SSE2) gives the same bits as one at a
// time.
TEST(Inclination, IsAtan2) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(0.0, kPi / 2), exponent(-12.0, 12.0);
  double worst = 0.0;
  std::vector<double> squares, verticals;
  const auto check = [&](double h, double v) {
    const double error = std::abs(internal::Inclination(h, v) - std::atan2(h, v));
    worst = std::max(worst, error);
    ASSERT_LT(error, 2e-10) << std::setprecision(17) << "h " << h << ", v " << v;
    squares.push_back(h * h);
    verticals.push_back(v);
  };
  for (int k = 0; k < 200000; ++k) {
    const double a = angle(rng), scale = std::pow(10.0, exponent(rng) / 4);
    check(scale * std::sin(a), scale * std::cos(a));
    const double ratio = std::pow(10.0, exponent(rng));
    check(ratio, 1.0);
    check(1.0, ratio);
  }
  for (double a : {0.0, kPi / 8, 3 * kPi / 8, kPi / 4, kPi / 2}) {
    for (double d : {-1e-15, 0.0, 1e-15})
      check(std::abs(std::sin(a + d)), std::abs(std::cos(a + d)));
  }
  const double inf = std::numeric_limits<double>::infinity();
  for (const auto& [h, v] : {std::pair{0.0, 1.0}, {1.0, 0.0}, {inf, 1.0}, {1.0, inf}, {0.0, inf}}) {
    check(h, v);
  }
  EXPECT_GT(worst, 0.0);  // a polynomial, not atan2 itself
  // All but the last one or more (to a count of 3 modulo 8), so that with AVX-512F or AVX2 the
  // last three go two through the SSE2 loop and one through the one-at-a-time tail; the zeros,
  // infinities and borders, checked last above, are among them. At every vector width.
  struct Uncap {
    ~Uncap() { internal::CapVectorLanes(0); }
  } uncap;
  const int size = static_cast<int>(squares.size());
  const int n = size - (size % 8 + 5) % 8;
  ASSERT_EQ(n % 8, 3);
  ASSERT_GE(n, size - 7);
  std::vector<double> many(n);
  for (const int lanes : {16, 8, 4, 1}) {
    internal::CapVectorLanes(lanes);
    internal::Inclinations(squares.data(), verticals.data(), many.data(), n);
    for (int j = 0; j < n; ++j) {
      const double one = internal::Inclination(std::sqrt(squares[j]), verticals[j]);
      ASSERT_EQ(std::memcmp(&many[j], &one, sizeof one), 0)
          << std::setprecision(17) << many[j] << " against " << one << " at " << j << ", " << lanes
          << " lanes";
    }
  }
}

TEST(SearchRegion, LidarDetectionEqualsBruteForce) {
  std::mt19937 rng(64);
  for (int trial = 0; trial < 6; ++trial) {
    const RangeImage image = RandomScan(rng, "VLP-16", 96, 4.0);
    DetectorConfig config;
    config.min_height_m = 0.2;
    config.max_height_m = 1.5;
    config.min_slope_rad = 0.6;
    const Detection exact = *DetectRegionScan(image, config);
    const Detection brute = *DetectBruteForce(image, config);
    EXPECT_EQ(exact.labels, brute.labels) << "trial " << trial;
    EXPECT_EQ(exact.stats.pairs_compatible, brute.stats.pairs_compatible) << "trial " << trial;
    EXPECT_GT(brute.stats.pairs_compatible, 0);
    // The exact search must do less than the brute force's all pairs.
    EXPECT_LT(exact.stats.pairs_tested, brute.stats.pairs_tested) << "trial " << trial;
  }
}

// A scan whose rings were measured on the data (FitRings), as for a KITTI scan without a
// preset: each beam sits up to 0.2 m above or below the origin, so the elevations seen from
// the origin scatter over more than the 0.4-degree ring spacing and neighbouring rows
// overlap in elevation. The region takes each row's span from the data: still exact.
RangeImage MeasuredRingScan(std::mt19937& rng, int rings, int width) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double step = 2.0 * 3.14159265358979323846 / width, deg = 3.14159265358979323846 / 180;
  std::vector<Eigen::Vector3f> points;
  std::vector<std::int32_t> ring;
  for (int r = 0; r < rings; ++r) {
    const double elevation = (2.0 - 0.4 * r) * deg, offset = 0.4 * (u01(rng) - 0.5);
    for (int c = 0; c < width; ++c) {
      if (u01(rng) < 0.1) continue;
      const double a = (c + 0.5 + 0.3 * (u01(rng) - 0.5)) * step, d = 1.0 + 14.0 * u01(rng);
      points.emplace_back(d * std::cos(elevation) * std::cos(a),
                          d * std::cos(elevation) * std::sin(a), d * std::sin(elevation) + offset);
      ring.push_back(r);
    }
  }
  Expected<RingFit> fit = FitRings(points, ring, rings, width);
  EXPECT_TRUE(fit.ok()) << fit.error().message;
  fit->model.azimuth_start_rad = FitAzimuthStart(points, width);
  std::vector<std::int32_t> cols(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    cols[i] = fit->model.Column(points[i].cast<double>());
  }
  const Eigen::Vector3d up(0.2 * (u01(rng) - 0.5), 0.2 * (u01(rng) - 0.5), 1.0);
  return *RangeImage::FromPoints(points, fit->model, up, fit->rows, cols);
}

TEST(SearchRegion, LidarDetectionEqualsBruteForceOnMeasuredOverlappingRings) {
  std::mt19937 rng(6464);
  for (int trial = 0; trial < 4; ++trial) {
    const RangeImage image = MeasuredRingScan(rng, 16, 90);
    DetectorConfig config;
    config.min_height_m = 0.2;
    config.max_height_m = 1.0 + trial * 0.5;
    config.min_slope_rad = 0.5 + 0.2 * trial;
    CheckEveryPartnerInside(image, config, "measured rings trial " + std::to_string(trial));
    const Detection exact = *DetectRegionScan(image, config);
    const Detection brute = *DetectBruteForce(image, config);
    EXPECT_EQ(exact.labels, brute.labels) << "trial " << trial;
    EXPECT_EQ(exact.stats.pairs_compatible, brute.stats.pairs_compatible) << "trial " << trial;
    EXPECT_GT(brute.stats.pairs_compatible, 0);
  }
}

TEST(RangeImage, LidarPointsGoBackToTheirCells) {
  const SphericalModel model = *SphericalModel::Preset("VLP-16", 360);
  std::vector<Eigen::Vector3f> points;
  for (int r = 0; r < model.height(); ++r) {
    for (int c = 0; c < model.width; c += 7) {
      const double e = model.ring_elevation_rad[r], a = model.ColumnAzimuth(c);
      const double range = 2.0 + 0.01 * c;
      points.emplace_back(range * std::cos(e) * std::cos(a), range * std::cos(e) * std::sin(a),
                          range * std::sin(e));
    }
  }
  points.emplace_back(0.0f, 0.0f, 0.0f);  // no return
  // Cells from the model alone (nearest ring, azimuth step): each point back in its cell,
  // its coordinates stored exactly.
  const RangeImage image = *RangeImage::FromPoints(points, model, Eigen::Vector3d::UnitZ());
  std::size_t i = 0;
  for (int r = 0; r < model.height(); ++r) {
    for (int c = 0; c < model.width; c += 7, ++i) {
      ASSERT_EQ(image.cell_of_point()[i], r * model.width + c) << "row " << r << " col " << c;
      EXPECT_EQ(image.point(r * model.width + c).cast<float>(), points[i]);
    }
  }
  EXPECT_EQ(image.cell_of_point().back(), -1);
  EXPECT_EQ(image.valid_count(), static_cast<int>(points.size()) - 1);
  // Cells outside the image are refused, naming the point.
  const auto bad = RangeImage::FromPoints(points, model, Eigen::Vector3d::UnitZ(),
                                          std::vector<std::int32_t>(points.size(), 16));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("point 0"), std::string::npos) << bad.error().message;
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
