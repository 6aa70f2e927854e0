// The spinning LiDAR model against its presets and closed-form ray hits: rings and azimuths
// are the preset's, returns lie at the analytic distance on planes, spheres and cylinders,
// a point lands in the (ring, column) the analytic projection gives, noise is seeded.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {
namespace {

constexpr double kPi = 3.141592653589793;
constexpr double kDeg = kPi / 180.0;

LidarSpec Noiseless(const std::string& preset) {
  Expected<LidarSpec> spec = LidarSpec::Preset(preset);
  EXPECT_TRUE(spec.ok());
  LidarSpec s = std::move(spec).value();
  s.range_sigma_m = 0.0;
  return s;
}

Eigen::Isometry3d Pose(const Eigen::Vector3d& position, double yaw, double pitch, double roll) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = position;
  return T;
}

TEST(LidarSpec, PresetsHaveTheirRings) {
  const LidarSpec vlp = Noiseless("VLP-16");
  ASSERT_EQ(vlp.rings(), 16);
  for (int r = 0; r < 16; ++r) EXPECT_NEAR(vlp.elevations_rad[r], (15.0 - 2.0 * r) * kDeg, 1e-12);
  EXPECT_EQ(vlp.azimuth_steps, 1024);
  EXPECT_TRUE(vlp.Validate().ok());

  const LidarSpec hdl = Noiseless("HDL-64E");
  ASSERT_EQ(hdl.rings(), 64);
  EXPECT_NEAR(hdl.elevations_rad.front(), 2.0 * kDeg, 1e-12);
  EXPECT_NEAR(hdl.elevations_rad.back(), -24.8 * kDeg, 1e-12);
  EXPECT_NEAR(hdl.elevations_rad[1] - hdl.elevations_rad[0], -kDeg / 3.0, 1e-12);  // upper
  EXPECT_NEAR(hdl.elevations_rad[32], -8.83 * kDeg, 1e-12);                        // lower
  for (int r = 1; r < 64; ++r) EXPECT_LT(hdl.elevations_rad[r], hdl.elevations_rad[r - 1]);
  EXPECT_EQ(hdl.azimuth_steps, 2048);
  EXPECT_TRUE(hdl.Validate().ok());

  EXPECT_FALSE(LidarSpec::Preset("HDL-32E").ok());
}

TEST(LidarSpec, ColumnsSweepClockwiseFromBehind) {
  const LidarSpec spec = Noiseless("VLP-16");
  const int n = spec.azimuth_steps;
  EXPECT_NEAR(spec.AzimuthRad(0), kPi, 1e-12);                 // backwards
  EXPECT_NEAR(spec.AzimuthRad(n / 4), 0.5 * kPi, 1e-12);       // left
  EXPECT_NEAR(spec.AzimuthRad(n / 2), 0.0, 1e-12);             // forward
  EXPECT_NEAR(spec.AzimuthRad(3 * n / 4), -0.5 * kPi, 1e-12);  // right
  const Eigen::Vector3d forward_top = spec.RayDirection(0, n / 2);
  EXPECT_NEAR(forward_top.norm(), 1.0, 1e-12);
  EXPECT_LT((forward_top - Eigen::Vector3d(std::cos(15 * kDeg), 0, std::sin(15 * kDeg))).norm(),
            1e-12);
}

TEST(LidarSpec, ValidateNamesTheField) {
  LidarSpec spec = Noiseless("VLP-16");
  spec.elevations_rad.clear();
  EXPECT_NE(spec.Validate().message().find("elevations"), std::string::npos);
  spec = Noiseless("VLP-16");
  std::swap(spec.elevations_rad[3], spec.elevations_rad[4]);
  EXPECT_NE(spec.Validate().message().find("elevations[4]"), std::string::npos);
  spec = Noiseless("VLP-16");
  spec.azimuth_steps = 0;
  EXPECT_NE(spec.Validate().message().find("azimuth_steps"), std::string::npos);
  spec = Noiseless("VLP-16");
  spec.range_sigma_m = -0.1;
  EXPECT_NE(spec.Validate().message().find("range_sigma"), std::string::npos);
  EXPECT_FALSE(RenderLidar(Scene(), spec, Eigen::Isometry3d::Identity(), 1).ok());
}

TEST(RenderLidar, RaysHitAPlaneAtTheAnalyticDistance) {
  // Ground z = 0.3 + g . (x, y); the sensor tilted and turned above it.
  const Eigen::Vector2d g(0.1, -0.05);
  Scene scene(Terrain::Plane(0.3, g));
  const LidarSpec spec = Noiseless("VLP-16");
  const Eigen::Isometry3d T = Pose({1.0, 2.0, 2.2}, 0.7, 0.05, -0.08);
  Expected<LidarScan> scan = RenderLidar(scene, spec, T, 1);
  ASSERT_TRUE(scan.ok()) << scan.error().message;
  const std::size_t n = scan->points.size();
  ASSERT_EQ(scan->ring.size(), n);
  ASSERT_EQ(scan->column.size(), n);
  ASSERT_EQ(scan->object_id.size(), n);
  const Eigen::Vector3d o = T.translation();
  int expected_hits = 0;
  for (int r = 0; r < spec.rings(); ++r) {
    for (int c = 0; c < spec.azimuth_steps; ++c) {
      const Eigen::Vector3d d = T.linear() * spec.RayDirection(r, c);
      const double closing = g.dot(d.head<2>()) - d.z();
      const double t = (o.z() - 0.3 - g.dot(o.head<2>())) / closing;
      if (closing > 0.0 && t <= spec.max_range_m) ++expected_hits;
    }
  }
  EXPECT_EQ(static_cast<int>(n), expected_hits);
  EXPECT_GT(n, 4000u);  // the lower half of the rings, roughly
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_EQ(scan->object_id[i], kTerrainId);
    const Eigen::Vector3d dir = spec.RayDirection(scan->ring[i], scan->column[i]);
    const Eigen::Vector3d d = T.linear() * dir;
    const double t = (o.z() - 0.3 - g.dot(o.head<2>())) / (g.dot(d.head<2>()) - d.z());
    const Eigen::Vector3d p = scan->points[i].cast<double>();
    EXPECT_NEAR(p.norm(), t, 2e-6 * t);
    EXPECT_LT((p.normalized() - dir).norm(), 1e-6);  // along its own ray
    const Eigen::Vector3d w = T * p;
    EXPECT_NEAR(w.z(), 0.3 + g.dot(w.head<2>()), 2e-5);
  }
}

TEST(RenderLidar, RaysHitASphereAndACylinderAtTheAnalyticDistance) {
  Scene scene(Terrain::Flat(-200.0));  // out of range: only the solids are seen
  const Eigen::Vector3d centre(6.0, 2.0, 0.5);
  const double radius = 1.2;
  const int ball = scene.Add(Ellipsoid{centre, Eigen::Vector3d::Constant(radius), 0.3}, true);
  const Eigen::Vector3d base(-5.0, -3.0, -3.0);
  const double pole_radius = 0.8;
  const int pole = scene.Add(Cylinder{base, pole_radius, 6.0}, true);
  const LidarSpec spec = Noiseless("HDL-64E");
  const Eigen::Isometry3d T = Pose({0.0, 0.0, 0.4}, 0.2, 0.0, 0.03);
  Expected<LidarScan> scan = RenderLidar(scene, spec, T, 1);
  ASSERT_TRUE(scan.ok());
  const Eigen::Vector3d o = T.translation();
  int ball_hits = 0, pole_hits = 0;
  for (std::size_t i = 0; i < scan->points.size(); ++i) {
    const Eigen::Vector3d d = T.linear() * spec.RayDirection(scan->ring[i], scan->column[i]);
    const double range = scan->points[i].cast<double>().norm();
    if (scan->object_id[i] == ball) {
      ++ball_hits;
      const double b = d.dot(centre - o);
      const double disc = b * b - ((centre - o).squaredNorm() - radius * radius);
      ASSERT_GE(disc, 0.0);
      EXPECT_NEAR(range, b - std::sqrt(disc), 1e-5);
    } else {
      ASSERT_EQ(scan->object_id[i], pole);
      const Eigen::Vector2d dh = d.head<2>(), oc = o.head<2>() - base.head<2>();
      const double a = dh.squaredNorm(), b = oc.dot(dh);
      const double k = oc.squaredNorm() - pole_radius * pole_radius;
      const double disc = b * b - a * k;
      ASSERT_GE(disc, 0.0);
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + t * d.z();
      if (z > base.z() + 1e-6 && z < base.z() + 6.0 - 1e-6) {
        ++pole_hits;
        EXPECT_NEAR(range, t, 1e-5);
      }
    }
  }
  EXPECT_GT(ball_hits, 200);
  EXPECT_GT(pole_hits, 200);
}

TEST(RenderLidar, APointLandsInTheRingAndColumnOfItsDirection) {
  // A small ball straight at ring 5, column 300 (VLP-16: elevation +5 deg, azimuth
  // pi (1 - 600 / 1024)) from a level sensor: the return is in that cell, and nowhere else
  // far from it.
  const LidarSpec spec = Noiseless("VLP-16");
  const Eigen::Vector3d dir = spec.RayDirection(5, 300);
  EXPECT_NEAR(std::asin(dir.z()), 5.0 * kDeg, 1e-12);
  EXPECT_NEAR(std::atan2(dir.y(), dir.x()), kPi * (1.0 - 600.0 / 1024.0), 1e-12);
  const Eigen::Vector3d sensor(3.0, -1.0, 1.8);
  Scene scene(Terrain::Flat(-200.0));
  const int id =
      scene.Add(Ellipsoid{sensor + 10.0 * dir, Eigen::Vector3d::Constant(0.02), 0.0}, true);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = sensor;
  Expected<LidarScan> scan = RenderLidar(scene, spec, T, 1);
  ASSERT_TRUE(scan.ok());
  ASSERT_EQ(scan->points.size(), 1u);  // 2 cm at 10 m: one ray of 0.35 deg spacing meets it
  EXPECT_EQ(scan->ring[0], 5);
  EXPECT_EQ(scan->column[0], 300);
  EXPECT_EQ(scan->object_id[0], id);
  EXPECT_NEAR(scan->points[0].cast<double>().norm(), 9.98, 1e-5);
}

TEST(RenderLidar, RangeNoiseIsSeededAndHasItsSigma) {
  Scene scene(Terrain::Flat(0.0));
  LidarSpec spec = Noiseless("VLP-16");
  spec.range_sigma_m = 0.05;
  const Eigen::Isometry3d T = Pose({0.0, 0.0, 1.8}, 0.0, 0.0, 0.0);
  const Expected<LidarScan> a = RenderLidar(scene, spec, T, 42);
  const Expected<LidarScan> b = RenderLidar(scene, spec, T, 42);
  const Expected<LidarScan> c = RenderLidar(scene, spec, T, 43);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  ASSERT_EQ(a->points.size(), b->points.size());
  for (std::size_t i = 0; i < a->points.size(); ++i) ASSERT_EQ(a->points[i], b->points[i]);
  ASSERT_EQ(a->points.size(), c->points.size());
  int differ = 0;
  double sum2 = 0.0;
  for (std::size_t i = 0; i < a->points.size(); ++i) {
    if (a->points[i] != c->points[i]) ++differ;
    const Eigen::Vector3d dir = spec.RayDirection(a->ring[i], a->column[i]);
    const double truth = 1.8 / -dir.z();  // flat ground 1.8 m below
    const double error = a->points[i].cast<double>().norm() - truth;
    sum2 += error * error;
  }
  EXPECT_GT(differ, static_cast<int>(a->points.size()) * 9 / 10);
  const double sigma = std::sqrt(sum2 / a->points.size());
  EXPECT_NEAR(sigma, 0.05, 0.005);  // 7 rings reach the ground: 7168 returns, 1% error
}

}  // namespace
}  // namespace cairn::sim
