// RefineTilt: a frame's ground points matched to known terrain recover the attitude error of
// the prior, about the world axes, on sloped and undulating ground, with obstacles present.
#include "cairn/map/tilt_refiner.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "cairn/eval/drift_run.hpp"
#include "cairn/od/units.hpp"

namespace cairn::map {
namespace {

double Terrain(double x, double y) {
  return 0.15 * x + 0.3 * std::sin(0.5 * y) + 0.2 * std::cos(0.7 * x);
}

ElevationPatch TerrainPatch(double resolution_m = 0.2) {
  ElevationPatch patch;
  patch.resolution_m = resolution_m;
  patch.origin_m = Eigen::Vector2d(-5.0, -20.0);
  const int rows = static_cast<int>(40.0 / resolution_m), cols = static_cast<int>(40.0 / resolution_m);
  patch.z.resize(rows, cols);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      patch.z(r, c) = Terrain(patch.origin_m.x() + (c + 0.5) * resolution_m,
                              patch.origin_m.y() + (r + 0.5) * resolution_m);
    }
  }
  return patch;
}

/// The true pose of a LiDAR-frame sensor (x forward, z up) 1.5 m above the terrain at the
/// origin, yawed, pitched up the slope and rolled a little.
Eigen::Isometry3d TruePose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(-8.0 * kDegToRad, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(3.0 * kDegToRad, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.0, 0.0, Terrain(0.0, 0.0) + 1.5);
  return T;
}

/// Ground points 3..20 m ahead, in the sensor frame of `T_world_sensor`; a fraction of them
/// lifted 0.4..1.0 m (obstacles the detector missed, or map errors).
std::vector<Eigen::Vector3f> GroundPoints(const Eigen::Isometry3d& T_world_sensor,
                                          double outlier_fraction = 0.0) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lift(0.4, 1.0), unit(0.0, 1.0);
  std::vector<Eigen::Vector3f> points;
  for (double x = 3.0; x <= 20.0; x += 0.25) {
    for (double y = -8.0; y <= 8.0; y += 0.25) {
      double z = Terrain(x, y);
      if (unit(rng) < outlier_fraction) z += lift(rng);
      points.push_back((T_world_sensor.inverse() * Eigen::Vector3d(x, y, z)).cast<float>());
    }
  }
  return points;
}

/// The prior: the true attitude turned about the world axes through the sensor origin.
Eigen::Isometry3d Perturbed(const Eigen::Isometry3d& T, double roll_rad, double pitch_rad,
                            double dz_m) {
  Eigen::Isometry3d P = T;
  P.linear() = (Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix() *
               T.linear();
  P.translation().z() += dz_m;
  return P;
}

using eval::TiltBetween;  // the tilt error (yaw is not observable from heights)

TEST(TiltRefiner, RecoversTheAttitudeErrorOnSlopedUndulatingGround) {
  const Eigen::Isometry3d truth = TruePose();
  const Eigen::Isometry3d prior = Perturbed(truth, 1.5 * kDegToRad, -2.0 * kDegToRad, 0.10);
  ASSERT_GT(TiltBetween(prior.linear(), truth.linear()), 2.4 * kDegToRad);  // the error to undo
  Expected<TiltEstimate> estimate =
      RefineTilt(GroundPoints(truth), prior, TerrainPatch(), TiltRefinerConfig{});
  ASSERT_TRUE(estimate) << estimate.error().message;
  ASSERT_TRUE(estimate->usable) << estimate->report;
  EXPECT_LT(TiltBetween(estimate->T_world_sensor.linear(), truth.linear()), 0.05 * kDegToRad);
  EXPECT_NEAR(estimate->T_world_sensor.translation().z(), truth.translation().z(), 0.01);
  EXPECT_NEAR(estimate->roll_rad, -1.5 * kDegToRad, 0.1 * kDegToRad);
  EXPECT_NEAR(estimate->pitch_rad, 2.0 * kDegToRad, 0.1 * kDegToRad);
  EXPECT_GT(estimate->rms_before_m, 0.2);
  EXPECT_LT(estimate->rms_after_m, 0.01);
  // Yaw and the horizontal position are not touched.
  EXPECT_DOUBLE_EQ(estimate->T_world_sensor.translation().x(), prior.translation().x());
  EXPECT_DOUBLE_EQ(estimate->T_world_sensor.translation().y(), prior.translation().y());
}

TEST(TiltRefiner, ObstaclePointsAmongTheGroundDoNotPullTheEstimate) {
  const Eigen::Isometry3d truth = TruePose();
  const Eigen::Isometry3d prior = Perturbed(truth, -1.0 * kDegToRad, 1.5 * kDegToRad, 0.0);
  Expected<TiltEstimate> estimate =
      RefineTilt(GroundPoints(truth, 0.15), prior, TerrainPatch(), TiltRefinerConfig{});
  ASSERT_TRUE(estimate);
  ASSERT_TRUE(estimate->usable) << estimate->report;
  EXPECT_LT(TiltBetween(estimate->T_world_sensor.linear(), truth.linear()), 0.1 * kDegToRad);
}

TEST(TiltRefiner, WithoutKnownTerrainThePriorIsKept) {
  const Eigen::Isometry3d truth = TruePose();
  const Eigen::Isometry3d prior = Perturbed(truth, 1.0 * kDegToRad, 1.0 * kDegToRad, 0.0);
  ElevationPatch unknown = TerrainPatch();
  unknown.z.setConstant(std::nan(""));
  Expected<TiltEstimate> estimate =
      RefineTilt(GroundPoints(truth), prior, unknown, TiltRefinerConfig{});
  ASSERT_TRUE(estimate);
  EXPECT_FALSE(estimate->usable);
  EXPECT_EQ(estimate->points_used, 0);
  EXPECT_TRUE(estimate->T_world_sensor.isApprox(prior));
  EXPECT_NE(estimate->report.find("prior kept"), std::string::npos) << estimate->report;
}

TEST(TiltRefiner, HolesInTheTerrainAreNotInterpolatedThrough) {
  // Known terrain only where x < 10: points beyond are not used, and the estimate from the
  // rest is still right.
  const Eigen::Isometry3d truth = TruePose();
  const Eigen::Isometry3d prior = Perturbed(truth, 1.0 * kDegToRad, -1.0 * kDegToRad, 0.05);
  ElevationPatch patch = TerrainPatch();
  for (int c = 0; c < patch.z.cols(); ++c) {
    if (patch.origin_m.x() + (c + 0.5) * patch.resolution_m >= 10.0) patch.z.col(c).setConstant(NAN);
  }
  const std::vector<Eigen::Vector3f> points = GroundPoints(truth);
  Expected<TiltEstimate> estimate = RefineTilt(points, prior, patch, TiltRefinerConfig{});
  ASSERT_TRUE(estimate);
  ASSERT_TRUE(estimate->usable) << estimate->report;
  EXPECT_LT(TiltBetween(estimate->T_world_sensor.linear(), truth.linear()), 0.05 * kDegToRad);
  Expected<TiltEstimate> all = RefineTilt(points, prior, TerrainPatch(), TiltRefinerConfig{});
  ASSERT_TRUE(all);
  EXPECT_LT(estimate->points_used, all->points_used);
}

// The height alone, the tilt held: with obstacle points among the ground and a prior whose
// tilt is 1 deg off, RefineHeight gives the dz that RefineTilt gives with its tilt held by
// a tight prior, and that a brute-force search of the one-unknown Huber cost gives; with the
// true tilt it finds the true height among 15% outliers.
TEST(TiltRefiner, TheHeightAloneMatchesTheFitWithTheTiltHeldAndTheBruteForceMinimum) {
  const Eigen::Isometry3d truth = TruePose();
  const std::vector<Eigen::Vector3f> points = GroundPoints(truth, 0.15);
  TiltRefinerConfig config;
  const Expected<TiltEstimate> exact =
      RefineHeight(GroundPoints(truth), Perturbed(truth, 0.0, 0.0, 0.12), TerrainPatch(), config);
  ASSERT_TRUE(exact && exact->usable) << (exact ? exact->report : exact.error().message);
  EXPECT_NEAR(exact->dz_m, -0.12, 0.001);
  // Among 15% of points lifted 0.4-1.0 m, each pulls with the Huber scale's weight (5 cm):
  // about 0.15 x 5 cm / 0.85 = 9 mm, as RefineTilt's loss does.
  const Expected<TiltEstimate> lifted =
      RefineHeight(points, Perturbed(truth, 0.0, 0.0, 0.12), TerrainPatch(), config);
  ASSERT_TRUE(lifted && lifted->usable);
  EXPECT_NEAR(lifted->dz_m, -0.12, 0.012);
  EXPECT_EQ(exact->roll_rad, 0.0);
  EXPECT_EQ(exact->pitch_rad, 0.0);

  const Eigen::Isometry3d prior = Perturbed(truth, 1.0 * kDegToRad, 0.0, 0.12);
  const Expected<TiltEstimate> height = RefineHeight(points, prior, TerrainPatch(), config);
  ASSERT_TRUE(height && height->usable);
  TiltRefinerConfig held = config;
  held.prior_sigma_rad = 1e-9;
  const Expected<TiltEstimate> tilt = RefineTilt(points, prior, TerrainPatch(), held);
  ASSERT_TRUE(tilt && tilt->usable);
  EXPECT_EQ(height->points_used, tilt->points_used);
  EXPECT_NEAR(height->dz_m, tilt->dz_m, 3e-4);  // Ceres stops at its function tolerance
  EXPECT_TRUE(height->T_world_sensor.linear().isApprox(prior.linear(), 1e-12));

  // Brute force: the same Huber cost on the same points' heights over the analytic terrain
  // at the prior (every point here is in range and over known terrain: RefineHeight's
  // selection is the in-range points thinned evenly to max_points), searched on a 0.1 mm
  // grid; once with the default height prior and once with one of 1 cm, which pulls dz
  // towards 0 by a known share.
  std::printf("[ figures  ] dz: height alone %.5f m, held-tilt fit %.5f m\n", height->dz_m,
              tilt->dz_m);
  for (const double prior_sigma_m : {config.prior_sigma_z_m, 0.01}) {
    TiltRefinerConfig c = config;
    c.prior_sigma_z_m = prior_sigma_m;
    const Expected<TiltEstimate> fit = RefineHeight(points, prior, TerrainPatch(), c);
    ASSERT_TRUE(fit && fit->usable);
    const std::size_t step = std::max<std::size_t>(1, points.size() / c.max_points);
    std::vector<double> a;
    for (std::size_t k = 0; k < points.size(); k += step) {
      const Eigen::Vector3d p = prior * points[k].cast<double>();
      a.push_back(p.z() - Terrain(p.x(), p.y()));
    }
    ASSERT_EQ(static_cast<int>(a.size()), fit->points_used);
    const double h = c.huber_m;
    auto huber_cost = [&](double dz) {
      double sum = (dz / c.prior_sigma_z_m) * (dz / c.prior_sigma_z_m);
      for (const double ai : a) {
        const double s2 = (ai + dz) * (ai + dz) / (h * h);
        sum += s2 <= 1.0 ? s2 : 2.0 * std::sqrt(s2) - 1.0;
      }
      return sum;
    };
    double best = 0.0, best_cost = huber_cost(0.0);
    for (double dz = -0.5; dz <= 0.5; dz += 1e-4) {
      if (const double cost = huber_cost(dz); cost < best_cost) {
        best_cost = cost;
        best = dz;
      }
    }
    std::printf("[ figures  ] height prior %.2f m: dz %.5f m, brute force %.5f m\n", prior_sigma_m,
                fit->dz_m, best);
    EXPECT_NEAR(fit->dz_m, best, 2e-4);  // the grid, and the bicubic patch of the terrain
  }
}

TEST(TiltRefiner, AnInvalidConfigNamesTheField) {
  TiltRefinerConfig config;
  config.huber_m = 0.0;
  Expected<TiltEstimate> estimate = RefineTilt({}, Eigen::Isometry3d::Identity(), TerrainPatch(), config);
  ASSERT_FALSE(estimate);
  EXPECT_NE(estimate.error().message.find("huber_m"), std::string::npos);
}

}  // namespace
}  // namespace cairn::map
