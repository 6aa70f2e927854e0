// The spinning LiDAR model against its presets and closed-form ray hits: rings and azimuths
// are the preset's, returns lie at the analytic distance on planes, spheres and cylinders,
// a point lands in the (ring, column) the analytic projection gives, noise is seeded. And
// the other way: rings measured on rendered scans (libod's FindElevationRings, FitRings,
// MeasureAzimuthSteps) give back the sensor's rings and columns.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {
namespace {

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

// Preset names in any case, as the settings files (config/sensors/os1-64.yaml) spell them.
TEST(SphericalModel, PresetNamesAreAcceptedInAnyCase) {
  for (const std::string name : {"HDL-64E", "VLP-16", "VLP-32C", "OS1-64"}) {
    std::string lower = name;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const Expected<od::SphericalModel> a = od::SphericalModel::Preset(name);
    const Expected<od::SphericalModel> b = od::SphericalModel::Preset(lower);
    ASSERT_TRUE(a.ok() && b.ok()) << lower;
    EXPECT_EQ(a->ring_elevation_rad, b->ring_elevation_rad) << lower;
    EXPECT_EQ(a->width, b->width) << lower;
  }
  const Expected<od::SphericalModel> bad = od::SphericalModel::Preset("os2-128");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("'os2-128'"), std::string::npos) << bad.error().message;
}

TEST(LidarSpec, PresetsHaveTheirRings) {
  const LidarSpec vlp = Noiseless("VLP-16");
  ASSERT_EQ(vlp.rings(), 16);
  for (int r = 0; r < 16; ++r)
    EXPECT_NEAR(vlp.elevations_rad[r], (15.0 - 2.0 * r) * kDegToRad, 1e-12);
  EXPECT_EQ(vlp.azimuth_steps, 1024);
  EXPECT_TRUE(vlp.Validate().ok());

  const LidarSpec hdl = Noiseless("HDL-64E");
  ASSERT_EQ(hdl.rings(), 64);
  EXPECT_NEAR(hdl.elevations_rad.front(), 2.0 * kDegToRad, 1e-12);
  EXPECT_NEAR(hdl.elevations_rad.back(), -24.8 * kDegToRad, 1e-12);
  EXPECT_NEAR(hdl.elevations_rad[1] - hdl.elevations_rad[0], -kDegToRad / 3.0, 1e-12);  // upper
  EXPECT_NEAR(hdl.elevations_rad[32], -8.83 * kDegToRad, 1e-12);                        // lower
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
  EXPECT_LT(
      (forward_top - Eigen::Vector3d(std::cos(15 * kDegToRad), 0, std::sin(15 * kDegToRad))).norm(),
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
  EXPECT_NEAR(std::asin(dir.z()), 5.0 * kDegToRad, 1e-12);
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

// A sensor 1.8 m above flat ground inside a ring of tall trunks, so that every ring, the
// upward ones too, has returns.
Scene TrunkRing() {
  Scene scene(Terrain::Flat(0.0));
  for (int k = 0; k < 36; ++k) {
    const double a = k * 10.0 * kDegToRad;
    scene.Add(Cylinder{Eigen::Vector3d(14.0 * std::cos(a), 14.0 * std::sin(a), 0.0), 1.0, 30.0},
              true);
  }
  return scene;
}

TEST(RingFinding, RenderedScansGiveBackTheSensorsRingsAndColumns) {
  for (const char* preset : {"VLP-16", "HDL-64E"}) {
    SCOPED_TRACE(preset);
    Expected<LidarSpec> spec = LidarSpec::Preset(preset);  // with its range noise
    ASSERT_TRUE(spec.ok());
    Expected<LidarScan> scan = RenderLidar(TrunkRing(), *spec, Pose({0, 0, 1.8}, 0.3, 0, 0), 5);
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    // Unordered, as a merged or filtered cloud comes: only the elevations are left.
    std::vector<std::size_t> order(scan->points.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::mt19937 rng(6);
    std::shuffle(order.begin(), order.end(), rng);
    std::vector<Eigen::Vector3f> points;
    std::vector<std::int32_t> ring, column;
    for (std::size_t i : order) {
      points.push_back(scan->points[i]);
      ring.push_back(scan->ring[i]);
      column.push_back(scan->column[i]);
    }
    Expected<od::RingFit> fit = od::FindElevationRings(points, spec->azimuth_steps);
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    ASSERT_EQ(fit->model.height(), spec->rings());
    EXPECT_EQ(fit->rows, ring);  // every point in its own ring, top first
    for (int r = 0; r < spec->rings(); ++r) {
      // Range noise moves points along their rays: the elevations stay the beam's.
      EXPECT_NEAR(fit->model.ring_elevation_rad[r], spec->elevations_rad[r], 1e-6) << r;
    }
    // From known rings the same model.
    Expected<od::RingFit> known = od::FitRings(points, ring, spec->rings(), spec->azimuth_steps);
    ASSERT_TRUE(known.ok());
    EXPECT_EQ(known->model.ring_elevation_rad, fit->model.ring_elevation_rad);
    EXPECT_EQ(known->rows, ring);

    // Columns: the azimuth step measured, column 0 fitted to the returns: the renderer's
    // columns up to a turn of the numbering.
    Expected<int> steps = od::MeasureAzimuthSteps(points, fit->rows);
    ASSERT_TRUE(steps.ok());
    EXPECT_EQ(*steps, spec->azimuth_steps);
    od::SphericalModel model = fit->model;
    model.azimuth_start_rad = od::FitAzimuthStart(points, model.width);
    const int shift =
        (column[0] - model.Column(points[0].cast<double>()) + model.width) % model.width;
    std::size_t same = 0;
    std::vector<std::int32_t> cols(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      cols[i] = model.Column(points[i].cast<double>());
      same += (cols[i] + shift) % model.width == column[i];
    }
    EXPECT_EQ(same, points.size());
    // One return per cell, each stored exactly.
    Expected<od::RangeImage> image =
        od::RangeImage::FromPoints(points, model, Eigen::Vector3d::UnitZ(), fit->rows, cols);
    ASSERT_TRUE(image.ok());
    EXPECT_EQ(image->valid_count(), static_cast<int>(points.size()));
    for (std::size_t i = 0; i < points.size(); ++i) {
      ASSERT_EQ(image->point(image->cell_of_point()[i]).cast<float>(), points[i]) << i;
    }
  }
}

TEST(RingFinding, ScansWithoutRingsAreToldApart) {
  // A cloud with elevations spread evenly (a tilting 2-D laser) has no rings.
  std::vector<Eigen::Vector3f> points;
  for (int k = 0; k < 20000; ++k) {
    const double el = -0.3 + 0.6 * k / 20000.0, az = 0.37 * k;
    points.emplace_back(static_cast<float>(5 * std::cos(el) * std::cos(az)),
                        static_cast<float>(5 * std::cos(el) * std::sin(az)),
                        static_cast<float>(5 * std::sin(el)));
  }
  Expected<od::RingFit> rings = od::FindElevationRings(points, 1000);
  ASSERT_FALSE(rings.ok());
  EXPECT_NE(rings.error().message.find("do not split into separate rings"), std::string::npos)
      << rings.error().message;
  // Uniform bins instead: square cells, every point in the bin of its elevation.
  Expected<od::RingFit> bins = od::UniformElevationBins(points, 1000);
  ASSERT_TRUE(bins.ok()) << bins.error().message;
  const double bin = 2 * kPi / 1000;
  EXPECT_EQ(bins->model.height(), static_cast<int>(std::floor(0.6 * (19999.0 / 20000) / bin)) + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double el = std::atan2(points[i].z(), std::hypot(points[i].x(), points[i].y()));
    // Half a bin, and the float coordinates' rounding.
    ASSERT_LE(std::abs(el - bins->model.ring_elevation_rad[bins->rows[i]]), 0.5 * bin + 1e-6) << i;
  }
}

}  // namespace
}  // namespace cairn::sim
