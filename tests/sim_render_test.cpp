// The synthetic renderer against hand-computed projections and closed-form ray hits: the
// detector tests trust its depth and id images as ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/random_scene.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::sim {
namespace {

od::PinholeModel Model(int width, int height, double f, double cx, double cy) {
  od::PinholeModel m;
  m.width = width;
  m.height = height;
  m.fx = m.fy = f;
  m.cx = cx;
  m.cy = cy;
  return m;
}

DepthFrame Render(const Scene& scene, const Camera& camera, double max_range = 100.0) {
  RenderOptions options;
  options.max_range_m = max_range;
  Expected<DepthFrame> frame = RenderDepth(scene, camera, options);
  EXPECT_TRUE(frame.ok()) << (frame.ok() ? "" : frame.error().message);
  return std::move(frame).value();
}

// Unit ray direction (world) through pixel (col, row), and the factor from distance along
// that ray to z-depth, computed here from the pose rather than taken from the renderer.
struct TestRay {
  Eigen::Vector3d direction;
  double depth_per_metre;
};
TestRay RayOf(const Camera& camera, int col, int row) {
  const od::PinholeModel& m = camera.model;
  const Eigen::Vector3d v((col - m.cx) / m.fx, (row - m.cy) / m.fy, 1.0);
  return {camera.T_world_camera.linear() * v.normalized(), 1.0 / v.norm()};
}

TEST(Camera, UpVectorFollowsTheLevelingConvention) {
  const od::PinholeModel m = Model(64, 48, 50.0, 31.5, 23.5);
  for (double heading : {0.0, 1.3, -2.5}) {
    for (double pitch : {-0.2, 0.0, 0.14, 0.9}) {
      for (double roll : {-0.3, 0.0, 0.05, 0.5}) {
        const Camera camera =
            Camera::FromAttitude(m, Eigen::Vector3d(1, 2, 3), heading, pitch, roll);
        // leveling.hpp: up = (-cos(p) sin(r), -cos(p) cos(r), -sin(p)).
        const Eigen::Vector3d expected(-std::cos(pitch) * std::sin(roll),
                                       -std::cos(pitch) * std::cos(roll), -std::sin(pitch));
        EXPECT_LT((camera.UpOptical() - expected).norm(), 1e-12);
        EXPECT_LT((camera.UpOptical() - od::CameraUpFromPitchRoll(pitch, roll)).norm(), 1e-12);
        // The optical axis points along the heading, `pitch` below the horizontal.
        const Eigen::Vector3d axis = camera.T_world_camera.linear().col(2);
        EXPECT_LT((axis - Eigen::Vector3d(std::cos(heading) * std::cos(pitch),
                                          std::sin(heading) * std::cos(pitch), -std::sin(pitch)))
                      .norm(),
                  1e-12);
        EXPECT_NEAR(camera.T_world_camera.linear().determinant(), 1.0, 1e-12);
      }
    }
  }
}

TEST(Render, PixelLandsWhereTheProjectionSays) {
  // Level camera 1.5 m up. A ball centred at camera-frame (2, -1, 10) projects onto
  // col = 50 * 2 / 10 + 50 = 60, row = 50 * -1 / 10 + 40 = 35, whatever the heading.
  const od::PinholeModel m = Model(101, 81, 50.0, 50.0, 40.0);
  for (double heading : {0.0, 90.0 * kDegToRad}) {
    const Eigen::Vector3d forward(std::cos(heading), std::sin(heading), 0.0);
    const Eigen::Vector3d right(std::sin(heading), -std::cos(heading), 0.0);
    const Eigen::Vector3d centre =
        Eigen::Vector3d(0, 0, 1.5) + 10.0 * forward + 2.0 * right + Eigen::Vector3d(0, 0, 1.0);
    Scene scene;
    const int ball = scene.Add(Ellipsoid{centre, Eigen::Vector3d::Constant(0.2), 0.0}, true);
    const Camera camera = Camera::FromAttitude(m, {0, 0, 1.5}, heading, 0.0, 0.0);
    const DepthFrame frame = Render(scene, camera);
    const int at = 35 * m.width + 60;
    EXPECT_EQ(frame.object_id[at], ball);
    // The ray through the centre meets the ball r before it; z-depth = 10 / |c| of that.
    const double c = std::sqrt(105.0);
    EXPECT_NEAR(frame.depth_m[at], (c - 0.2) * 10.0 / c, 1e-5);
    // The ball is about 1 px in radius: 3 px away there is sky above the horizon.
    EXPECT_EQ(frame.object_id[35 * m.width + 63], kNoHitId);
    EXPECT_EQ(frame.object_id[32 * m.width + 60], kNoHitId);
    const auto projected = camera.ProjectWorld(centre);
    ASSERT_TRUE(projected.has_value());
    EXPECT_NEAR(projected->x(), 60.0, 1e-9);
    EXPECT_NEAR(projected->y(), 35.0, 1e-9);
    // Level camera, flat ground: rows below the horizon (row 40) see terrain, rows above none.
    EXPECT_EQ(frame.object_id[45 * m.width + 10], kTerrainId);
    EXPECT_EQ(frame.object_id[35 * m.width + 10], kNoHitId);
    EXPECT_EQ(frame.depth_m[35 * m.width + 10], 0.0f);
    // Ground seen 5 rows below the horizon: z-depth = 1.5 * 50 / 5 = 15 m.
    EXPECT_NEAR(frame.depth_m[45 * m.width + 10], 15.0, 1e-5);
  }
}

TEST(Render, OpticalAxisMeetsFlatGroundAtHeightOverSinPitch) {
  const od::PinholeModel m = Model(81, 61, 60.0, 40.0, 30.0);
  for (double pitch : {5.0 * kDegToRad, 20.0 * kDegToRad, 60.0 * kDegToRad}) {
    for (double roll : {0.0, 10.0 * kDegToRad, -25.0 * kDegToRad}) {
      const Camera camera = Camera::FromAttitude(m, {3, -1, 1.6}, 0.7, pitch, roll);
      const DepthFrame frame = Render(Scene(), camera, 200.0);
      const int centre = 30 * m.width + 40;
      EXPECT_EQ(frame.object_id[centre], kTerrainId);
      EXPECT_NEAR(frame.depth_m[centre], 1.6 / std::sin(pitch), 1e-5);
    }
  }
}

TEST(Render, RaysHitAPlaneAtTheAnalyticDistance) {
  // Terrain z = 0.2 + g . (x, y), rising at 20 deg towards heading 1.0; tilted camera.
  const double slope = 20.0 * kDegToRad, uphill = 1.0;
  const Eigen::Vector2d g = std::tan(slope) * Eigen::Vector2d(std::cos(uphill), std::sin(uphill));
  const Scene scene(Terrain::Slope(0.2, slope, uphill));
  const od::PinholeModel m = Model(64, 48, 40.0, 31.5, 23.5);
  const Camera camera = Camera::AboveGround(m, scene.terrain(), 0.5, -0.3, 1.7, 2.0,
                                            12.0 * kDegToRad, -7.0 * kDegToRad);
  const double max_range = 80.0;
  const DepthFrame frame = Render(scene, camera, max_range);
  const Eigen::Vector3d o = camera.Position();
  const Eigen::Vector3d normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
  int hits = 0, misses = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const TestRay ray = RayOf(camera, c, r);
      const Eigen::Vector3d& d = ray.direction;
      // o_z + t d_z = 0.2 + g . (o_xy + t d_xy)
      const double closing = g.dot(d.head<2>()) - d.z();
      const double t = (o.z() - 0.2 - g.dot(o.head<2>())) / closing;
      const int i = r * m.width + c;
      if (closing > 0.0 && t <= max_range) {
        ++hits;
        ASSERT_EQ(frame.object_id[i], kTerrainId) << c << "," << r;
        EXPECT_NEAR(frame.depth_m[i], t * ray.depth_per_metre, 2e-6 * t) << c << "," << r;
        EXPECT_LT((frame.normal[i].cast<double>() - normal).norm(), 1e-6);
      } else {
        ++misses;
        EXPECT_EQ(frame.object_id[i], kNoHitId) << c << "," << r;
        EXPECT_EQ(frame.depth_m[i], 0.0f);
      }
    }
  }
  EXPECT_GT(hits, 500);  // the scene exercises both cases
  EXPECT_GT(misses, 50);
}

TEST(Render, RaysHitASphereAtTheAnalyticDistance) {
  const Eigen::Vector3d centre(6.0, 0.8, 1.2);
  const double radius = 0.9;
  Scene scene(Terrain::Flat(-100.0));  // out of range: only the sphere is seen
  const int id = scene.Add(Ellipsoid{centre, Eigen::Vector3d::Constant(radius), 0.4}, true);
  const od::PinholeModel m = Model(64, 48, 45.0, 31.5, 23.5);
  const Camera camera = Camera::FromAttitude(m, {0, 0, 1.5}, 0.1, 3.0 * kDegToRad, 5.0 * kDegToRad);
  const DepthFrame frame = Render(scene, camera, 50.0);
  const Eigen::Vector3d o = camera.Position();
  int hits = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const TestRay ray = RayOf(camera, c, r);
      const double b = ray.direction.dot(centre - o);
      const double disc = b * b - ((centre - o).squaredNorm() - radius * radius);
      const int i = r * m.width + c;
      if (disc > 1e-9) {
        ++hits;
        const double t = b - std::sqrt(disc);
        ASSERT_EQ(frame.object_id[i], id) << c << "," << r;
        EXPECT_NEAR(frame.depth_m[i], t * ray.depth_per_metre, 2e-6 * t);
        const Eigen::Vector3d p = o + t * ray.direction;
        EXPECT_LT((frame.normal[i].cast<double>() - (p - centre) / radius).norm(), 1e-5);
      } else if (disc < -1e-9) {
        EXPECT_EQ(frame.object_id[i], kNoHitId) << c << "," << r;
      }
    }
  }
  EXPECT_GT(hits, 100);  // radius 0.9 m at 6 m, f = 45 px: about 145 px
}

TEST(Render, RaysHitACylinderAtTheAnalyticDistance) {
  // Eye level lies between the caps, so only the side is seen.
  const Eigen::Vector3d base(5.0, -0.7, 0.0);
  const double radius = 0.6, height = 3.0;
  Scene scene(Terrain::Flat(-100.0));
  const int id = scene.Add(Cylinder{base, radius, height}, true);
  const od::PinholeModel m = Model(64, 48, 40.0, 31.5, 23.5);
  const Camera camera =
      Camera::FromAttitude(m, {0, 0, 1.5}, -0.1, 2.0 * kDegToRad, -4.0 * kDegToRad);
  const DepthFrame frame = Render(scene, camera, 50.0);
  const Eigen::Vector3d o = camera.Position();
  int hits = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const TestRay ray = RayOf(camera, c, r);
      const Eigen::Vector2d d = ray.direction.head<2>(), oc = o.head<2>() - base.head<2>();
      const double a = d.squaredNorm(), b = oc.dot(d), k = oc.squaredNorm() - radius * radius;
      const double disc = b * b - a * k;
      const int i = r * m.width + c;
      if (disc <= 1e-9) {
        if (disc < -1e-9) {
          EXPECT_EQ(frame.object_id[i], kNoHitId);
        }
        continue;
      }
      const double t = (-b - std::sqrt(disc)) / a;
      const double z = o.z() + t * ray.direction.z();
      if (z > 1e-6 && z < height - 1e-6) {
        ++hits;
        ASSERT_EQ(frame.object_id[i], id) << c << "," << r;
        EXPECT_NEAR(frame.depth_m[i], t * ray.depth_per_metre, 2e-6 * t);
      } else if (z < -1e-6 || z > height + 1e-6) {
        EXPECT_EQ(frame.object_id[i], kNoHitId) << c << "," << r;
      }
    }
  }
  EXPECT_GT(hits, 200);
}

// Largest distance from a rendered point to the surface z = h(x, y), over terrain pixels.
double WorstTerrainResidual(const Scene& scene, const Camera& camera, const DepthFrame& frame,
                            int* terrain_pixels) {
  double worst = 0.0;
  *terrain_pixels = 0;
  for (int r = 0; r < frame.height(); ++r) {
    for (int c = 0; c < frame.width(); ++c) {
      const int i = r * frame.width() + c;
      if (frame.object_id[i] != kTerrainId) continue;
      ++*terrain_pixels;
      const Eigen::Vector3d p = camera.UnprojectWorld(c, r, frame.depth_m[i]);
      worst = std::max(worst, std::abs(p.z() - scene.terrain().Height(p.x(), p.y())));
    }
  }
  return worst;
}

TEST(Render, MarchedHeightfieldHitsLieOnTheSurface) {
  Scene scene(Terrain::Hills(0.0, {{0.5, 6.0, 0.4, 0.3}, {0.2, 2.5, 2.0, 1.0}}));
  const od::PinholeModel m = Model(96, 72, 60.0, 47.5, 35.5);
  const Camera camera =
      Camera::AboveGround(m, scene.terrain(), 0, 0, 1.2, 0.3, 15.0 * kDegToRad, 4.0 * kDegToRad);
  const DepthFrame frame = Render(scene, camera, 60.0);
  int pixels = 0;
  // Bisection to 1e-6 m along the ray, then float depth (7 digits at <= 60 m).
  EXPECT_LT(WorstTerrainResidual(scene, camera, frame, &pixels), 2e-5);
  EXPECT_GT(pixels, m.width * m.height / 2);
}

TEST(Render, GridOfAPlaneRendersLikeThePlane) {
  // Bilinear interpolation reproduces a plane exactly, so the marched grid and the
  // closed-form plane must agree to the march's tolerance.
  const Eigen::Vector2d g(0.15, -0.35);
  HeightGrid grid;
  grid.cols = grid.rows = 41;
  grid.resolution_m = 1.0;
  grid.origin = {-20.0, -20.0};
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      grid.heights.push_back(0.3 + g.x() * (grid.origin.x() + c) + g.y() * (grid.origin.y() + r));
    }
  }
  Expected<Terrain> marched = Terrain::FromGrid(grid);
  ASSERT_TRUE(marched.ok());
  EXPECT_FALSE(marched->IsPlanar());
  const od::PinholeModel m = Model(64, 48, 40.0, 31.5, 23.5);
  const Camera camera =
      Camera::FromAttitude(m, {0, 0, 2.0}, 0.4, 10.0 * kDegToRad, 3.0 * kDegToRad);
  const DepthFrame a = Render(Scene(*marched), camera, 18.0);  // stays inside the grid
  const DepthFrame b = Render(Scene(Terrain::Plane(0.3, g)), camera, 18.0);
  int both = 0;
  for (int i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.object_id[i], b.object_id[i]) << i;
    if (a.object_id[i] != kTerrainId) continue;
    ++both;
    EXPECT_NEAR(a.depth_m[i], b.depth_m[i], 5e-6 * b.depth_m[i] + 2e-6);
  }
  EXPECT_GT(both, 1000);
}

TEST(Render, BoxAndRidgeHitsLieOnTheirFaces) {
  Scene scene;
  const int box = scene.Add(Box{{6.0, 1.0, 0.4}, {1.2, 0.8, 0.8}, 0.5}, true);
  Ridge ridge;
  ridge.base_centre = {7.0, -1.5, 0.0};
  ridge.yaw_rad = 0.2;
  ridge.top_length_m = 2.0;
  ridge.top_width_m = 0.3;
  ridge.height_m = 0.7;
  ridge.left_slope_rad = 70.0 * kDegToRad;
  ridge.right_slope_rad = 40.0 * kDegToRad;
  ridge.end_slope_rad = 25.0 * kDegToRad;
  const int ridge_id = scene.Add(ridge, true);
  const od::PinholeModel m = Model(96, 72, 70.0, 47.5, 35.5);
  const Camera camera = Camera::FromAttitude(m, {0, 0, 1.6}, 0.0, 12.0 * kDegToRad, 0.0);
  const DepthFrame frame = Render(scene, camera);
  // Faces in each solid's frame: n . (p - origin) = d, with the yaw undone.
  auto local = [](const Eigen::Vector3d& p, const Eigen::Vector3d& origin, double yaw) {
    const Eigen::Vector3d q = p - origin;
    return Eigen::Vector3d(std::cos(yaw) * q.x() + std::sin(yaw) * q.y(),
                           -std::sin(yaw) * q.x() + std::cos(yaw) * q.y(), q.z());
  };
  int box_pixels = 0, ridge_pixels = 0, steep_face_pixels = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const int i = r * m.width + c;
      const Eigen::Vector3d p = camera.UnprojectWorld(c, r, frame.depth_m[i]);
      if (frame.object_id[i] == box) {
        ++box_pixels;
        const Eigen::Vector3d q = local(p, {6.0, 1.0, 0.4}, 0.5).cwiseAbs();
        // On the surface: inside every slab, on one of them.
        const double outside = (q - Eigen::Vector3d(0.6, 0.4, 0.4)).maxCoeff();
        EXPECT_NEAR(outside, 0.0, 1e-5);
      } else if (frame.object_id[i] == ridge_id) {
        ++ridge_pixels;
        const Eigen::Vector3d q = local(p, ridge.base_centre, ridge.yaw_rad);
        const double a = ridge.left_slope_rad, e = ridge.end_slope_rad;
        const double b = ridge.right_slope_rad;
        const double gaps[] = {std::sin(e) * (std::abs(q.x()) - 1.0) + std::cos(e) * (q.z() - 0.7),
                               std::sin(a) * (q.y() - 0.15) + std::cos(a) * (q.z() - 0.7),
                               std::sin(b) * (-q.y() - 0.15) + std::cos(b) * (q.z() - 0.7),
                               q.z() - 0.7, -q.z()};
        EXPECT_NEAR(*std::max_element(std::begin(gaps), std::end(gaps)), 0.0, 1e-5);
        // The left face (local +y) leans back at 70 deg; its normal says so.
        const Eigen::Vector3d n = frame.normal[i].cast<double>();
        if (std::abs(n.z() - std::cos(a)) < 1e-6) {
          ++steep_face_pixels;
          EXPECT_NEAR(n.x(), -std::sin(ridge.yaw_rad) * std::sin(a), 1e-6);
          EXPECT_NEAR(n.y(), std::cos(ridge.yaw_rad) * std::sin(a), 1e-6);
        }
      }
    }
  }
  EXPECT_GT(box_pixels, 100);
  EXPECT_GT(ridge_pixels, 100);
  EXPECT_GT(steep_face_pixels, 20);
}

TEST(Render, NearerSurfaceWins) {
  // A ball in front of a thick pole, both on the optical axis: the centre sees the ball.
  Scene scene;
  const int pole = scene.AddPole(10.0, 0.0, 1.0, 3.0, true);
  const int ball = scene.Add(Ellipsoid{{5.0, 0.0, 1.5}, Eigen::Vector3d::Constant(0.3), 0}, true);
  const od::PinholeModel m = Model(41, 31, 30.0, 20.0, 15.0);
  const DepthFrame frame = Render(scene, Camera::FromAttitude(m, {0, 0, 1.5}, 0, 0, 0));
  EXPECT_EQ(frame.object_id[15 * 41 + 20], ball);
  EXPECT_NEAR(frame.depth_m[15 * 41 + 20], 4.7, 1e-5);
  // 2 px to the side the ray passes 0.33 m from the ball's centre (radius 0.3) and
  // 0.6 m from the pole's axis (radius 1.0).
  EXPECT_EQ(frame.object_id[15 * 41 + 22], pole);
}

TEST(Scene, StandsObjectsOnTheTerrain) {
  Scene scene(Terrain::Hills(0.3, {{0.4, 5.0, 0.0, 0.0}}));
  const int pole = scene.AddPole(1.0, 2.0, 0.2, 1.5, true);
  const int rock = scene.AddRock(3.0, -1.0, {0.4, 0.3, 0.25}, 0.35, 0.0, false);
  const double ground_pole = scene.terrain().Height(1.0, 2.0);
  const double ground_rock = scene.terrain().Height(3.0, -1.0);
  EXPECT_NEAR(Top(scene.Find(pole)->shape), ground_pole + 1.5, 1e-12);
  EXPECT_NEAR(Top(scene.Find(rock)->shape), ground_rock + 0.35, 1e-12);
  // The pole's base is below the ground everywhere under it.
  const double bottom = Bottom(scene.Find(pole)->shape);
  for (double a = 0; a < 6.3; a += 0.1) {
    EXPECT_LT(bottom, scene.terrain().Height(1.0 + 0.2 * std::cos(a), 2.0 + 0.2 * std::sin(a)));
  }
  EXPECT_FALSE(scene.Find(rock)->is_obstacle);
  EXPECT_TRUE(scene.Validate().ok());
}

TEST(Scene, RejectsBadIdsAndShapes) {
  Scene scene;
  EXPECT_FALSE(scene.Add(Object{0, true, Cylinder{}, "zero"}).ok());
  ASSERT_TRUE(scene.Add(Object{7, true, Cylinder{}, "seven"}).ok());
  const Status repeated = scene.Add(Object{7, true, Cylinder{}, "again"});
  ASSERT_FALSE(repeated.ok());
  EXPECT_NE(repeated.message().find("7"), std::string::npos);
  Cylinder flat;
  flat.radius_m = 0.0;
  const Status bad = scene.Add(Object{8, true, flat, "flat"});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("radius_m"), std::string::npos) << bad.message();
  EXPECT_EQ(scene.Add(Box{}, true), 8);  // next free id

  od::PinholeModel broken = Model(10, 10, 0.0, 5, 5);
  EXPECT_FALSE(RenderDepth(scene, Camera::FromAttitude(broken, {0, 0, 1}, 0, 0, 0)).ok());
}

TEST(RandomScene, SameSeedSameFrame) {
  RandomSceneOptions options;
  options.width = 48;
  options.height = 36;
  const RandomView a = MakeRandomView(42, options), b = MakeRandomView(42, options);
  const RandomView c = MakeRandomView(43, options);
  const DepthFrame fa = Render(a.scene, a.camera), fb = Render(b.scene, b.camera);
  const DepthFrame fc = Render(c.scene, c.camera);
  EXPECT_EQ(fa.depth_m, fb.depth_m);
  EXPECT_EQ(fa.object_id, fb.object_id);
  EXPECT_NE(fa.depth_m, fc.depth_m);
}

}  // namespace
}  // namespace cairn::sim
