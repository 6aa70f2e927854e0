// World files, the gallery, stereo noise and the geometry the gallery needs (rods, bushes,
// ditches, banks), through the public API of cairn::sim.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"
#include "io/temp_dir.hpp"

namespace cairn::sim {
namespace {

std::filesystem::path GalleryDir() {
  return std::filesystem::path(CAIRN_SOURCE_DIR) / "datasets" / "worlds";
}

std::vector<std::filesystem::path> GalleryFiles() {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(GalleryDir())) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// ---- the gallery ------------------------------------------------------------------------

TEST(Gallery, EveryWorldLoadsAndRenders) {
  const std::vector<std::filesystem::path> files = GalleryFiles();
  ASSERT_GE(files.size(), 8u);
  for (const auto& file : files) {
    SCOPED_TRACE(file.string());
    Expected<World> world = LoadWorld(file.string());
    ASSERT_TRUE(world.ok()) << world.error().message;
    EXPECT_EQ(world->name, file.stem().string());
    EXPECT_GT(world->description.size(), 80u) << "the description states the claim";
    EXPECT_NE(world->description.find("Expected"), std::string::npos);
    ASSERT_FALSE(world->views.empty());
    std::set<int> seen_obstacles;
    for (int v = 0; v < static_cast<int>(world->views.size()); ++v) {
      Expected<DepthFrame> frame = RenderView(*world, v);
      ASSERT_TRUE(frame.ok()) << frame.error().message;
      EXPECT_EQ(frame->width(), world->camera.model.width);
      int valid = 0;
      for (int i = 0; i < frame->size(); ++i) {
        const int id = frame->object_id[i];
        EXPECT_EQ(frame->depth_m[i] > 0.0f, id != kNoHitId) << "pixel " << i;
        if (frame->depth_m[i] > 0.0f) ++valid;
        if (id > 0) {
          const Object* object = world->scene.Find(id);
          ASSERT_NE(object, nullptr) << "id " << id;
          if (object->is_obstacle) seen_obstacles.insert(id);
        }
      }
      EXPECT_GT(valid, frame->size() / 4) << "view " << v << " sees mostly nothing";
    }
    EXPECT_FALSE(seen_obstacles.empty()) << "no obstacle in sight";
    if (world->lidar) {
      // The LiDAR at view 0's place, level: returns with ids from the scene.
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = ViewCamera(*world, 0).Position();
      Expected<LidarScan> scan = RenderLidar(world->scene, *world->lidar, T, world->seed);
      ASSERT_TRUE(scan.ok()) << scan.error().message;
      EXPECT_GT(scan->points.size(), 1000u);
      for (std::int32_t id : scan->object_id) {
        ASSERT_TRUE(id == kTerrainId || world->scene.Find(id) != nullptr) << id;
      }
    }
  }
}

TEST(Gallery, DefaultCameraAndDriveOfTheUphillWorld) {
  Expected<World> world = LoadWorld((GalleryDir() / "uphill_tilted.yaml").string());
  ASSERT_TRUE(world.ok()) << world.error().message;
  EXPECT_EQ(world->camera.model.width, 320);
  EXPECT_EQ(world->camera.model.height, 240);
  EXPECT_DOUBLE_EQ(world->camera.model.fx, 260.0);
  ASSERT_TRUE(world->drive.has_value());
  EXPECT_TRUE(world->drive->Validate().ok());
  EXPECT_EQ(world->drive->waypoints.size(), 3u);
  EXPECT_NEAR(world->drive->sensor_pitch_rad, 8.0 * kDegToRad, 1e-12);
  EXPECT_NEAR(world->drive->odom_yaw_sigma_rad_per_m, 0.1 * kDegToRad, 1e-12);
  // Views on the slope are tilted: the up vector is not the image's -y.
  const Camera camera = ViewCamera(*world, 0);
  EXPECT_GT((camera.UpOptical() - Eigen::Vector3d(0, -1, 0)).norm(), 0.1);
}

// ---- world files ----------------------------------------------------------------------

class WorldFile : public ::testing::Test {
 protected:
  // A valid world with `objects` (YAML lines) and `extra` top-level lines appended.
  std::string Write(const std::string& extra, const std::string& objects = "") {
    std::string text =
        "description: a test world\n"
        "views:\n"
        "  - {x: 0, y: 0, height: 1.5, pitch: 10}\n" +
        extra;
    if (!objects.empty()) text += "objects:\n" + objects;
    return dir_.Write("w.yaml", text).string();
  }
  // The error of loading `path`; fails the test when it loads.
  std::string ErrorOf(const std::string& path) {
    Expected<World> world = LoadWorld(path);
    EXPECT_FALSE(world.ok()) << "loaded although it should not";
    return world.ok() ? std::string() : world.error().message;
  }
  test::TempDir dir_;
};

TEST_F(WorldFile, MinimalWorldTakesTheDefaults) {
  Expected<World> world = LoadWorld(Write(""));
  ASSERT_TRUE(world.ok()) << world.error().message;
  EXPECT_EQ(world->name, "w");
  EXPECT_EQ(world->seed, 1u);
  EXPECT_TRUE(world->scene.objects().empty());
  EXPECT_FALSE(world->lidar.has_value());
  EXPECT_FALSE(world->drive.has_value());
  EXPECT_EQ(world->camera.model.width, 320);
  EXPECT_DOUBLE_EQ(world->camera.model.cx, 159.5);
  EXPECT_NEAR(world->views[0].pitch_rad, 10.0 * kDegToRad, 1e-12);
  EXPECT_TRUE(world->camera.noise.IsZero());
}

TEST_F(WorldFile, DegreesInTheFileRadiansInTheStructs) {
  Expected<World> world = LoadWorld(Write(
      "terrain: {slope: 10, uphill_heading: 90}\n"
      "camera: {width: 64, height: 48, hfov: 90}\n"
      "lidar: {elevations: [10, 0, -10], azimuth_steps: 360}\n",
      "  - {kind: mound, obstacle: true, x: 5, y: 0, yaw: 30, top_length: 1, top_width: 0.2,\n"
      "     height: 0.5, left_slope: 70, right_slope: 50, end_slope: 20}\n"));
  ASSERT_TRUE(world.ok()) << world.error().message;
  const auto& ridge = std::get<Ridge>(world->scene.objects()[0].shape);
  EXPECT_NEAR(ridge.yaw_rad, 30 * kDegToRad, 1e-12);
  EXPECT_NEAR(ridge.left_slope_rad, 70 * kDegToRad, 1e-12);
  EXPECT_NEAR(ridge.right_slope_rad, 50 * kDegToRad, 1e-12);
  EXPECT_NEAR(ridge.end_slope_rad, 20 * kDegToRad, 1e-12);
  EXPECT_NEAR(world->camera.model.fx, 32.0, 1e-9);  // 90 deg across 64 px
  ASSERT_TRUE(world->lidar.has_value());
  EXPECT_NEAR(world->lidar->elevations_rad[2], -10 * kDegToRad, 1e-12);
  // The terrain rises at 10 deg towards +y.
  EXPECT_NEAR(world->scene.terrain().Height(0, 1), std::tan(10 * kDegToRad), 1e-12);
  EXPECT_NEAR(world->scene.terrain().Height(1, 0), 0.0, 1e-12);
}

TEST_F(WorldFile, ObjectsStandOnTheGroundWithTheirIds) {
  Expected<World> world = LoadWorld(Write(
      "terrain: {height: 2.0}\n",
      "  - {kind: tree, obstacle: true, x: 5, y: 0, radius: 0.2, height: 3}\n"
      "  - {kind: rock, obstacle: false, id: 7, x: 6, y: 1, radii: [0.3, 0.3, 0.2], height: 0.2}\n"
      "  - {kind: wire, obstacle: true, start: [4, -1, 0.7], end: [4, 1, 0.7], radius: 0.02}\n"
      "  - {kind: bush, obstacle: true, x: 8, y: 0, radii: [0.5, 0.5, 0.4], height: 0.7}\n"
      "  - {kind: ditch, obstacle: true, start: [12, -5], end: [12, 5], depth: 0.6,"
      " top_width: 2}\n"));
  ASSERT_TRUE(world.ok()) << world.error().message;
  const Scene& scene = world->scene;
  ASSERT_EQ(scene.objects().size(), 5u);
  // Ids in file order, skipping the explicit 7.
  const Object* tree = scene.Find(1);
  ASSERT_NE(tree, nullptr);
  EXPECT_EQ(tree->name, "tree");
  EXPECT_NEAR(Top(tree->shape), 5.0, 1e-12);
  EXPECT_FALSE(scene.Find(7)->is_obstacle);
  EXPECT_NEAR(Top(scene.Find(7)->shape), 2.2, 1e-12);
  const auto& wire = std::get<Rod>(scene.Find(2)->shape);
  EXPECT_NEAR(wire.start.z(), 2.7, 1e-12);
  EXPECT_NEAR(Top(scene.Find(3)->shape), 2.7, 1e-12);  // the bush's top
  ASSERT_TRUE(std::holds_alternative<Ditch>(scene.Find(4)->shape));
  EXPECT_NEAR(scene.terrain().Height(12, 0), 2.0 - 0.6, 1e-12);
  EXPECT_NEAR(scene.terrain().Height(20, 0), 2.0, 1e-12);
}

TEST_F(WorldFile, ErrorsNameTheFileAndTheField) {
  const std::string obstacle =
      "  - {kind: pole, obstacle: true, x: 5, y: 0, radius: 0.1, height: 1}\n";
  const struct {
    std::string extra, objects, expected;
  } cases[] = {
      {"bogus: 1\n", "", "bogus: unknown key"},
      {"", "  - {kind: pole, obstacle: true, x: 5, y: 0, radius: -1, height: 1}\n",
       "objects[0].radius: must be > 0"},
      {"", obstacle + "  - {kind: pole, obstacle: true, x: 5, y: 0, radius: 0.1, height: 0}\n",
       "objects[1].height: must be > 0"},
      {"", "  - {kind: dragon, obstacle: true}\n", "objects[0].kind: unknown kind 'dragon'"},
      {"", "  - {kind: pole, obstacle: true, x: 5, y: 0, radius: thick, height: 1}\n",
       "objects[0].radius: expected a number, got 'thick'"},
      {"", "  - {kind: pole, x: 5, y: 0, radius: 0.1, height: 1}\n",
       "objects[0].obstacle: missing"},
      {"", "  - {kind: pole, obstacle: maybe, x: 5, y: 0, radius: 0.1, height: 1}\n",
       "objects[0].obstacle: expected true or false"},
      {"", "  - {kind: pole, obstacle: true, x: 5, y: 0, radiu: 0.1, height: 1}\n",
       "objects[0].radiu: unknown key"},
      {"", "  - {kind: pole, obstacle: true, x: 5, y: 0, height: 1}\n",
       "objects[0].radius: missing"},
      {"", "  - {kind: rock, obstacle: true, x: 5, y: 0, radii: [0.2, 0.2], height: 0.3}\n",
       "objects[0].radii: expected a sequence of 3 numbers"},
      {"", "  - {kind: rock, obstacle: true, x: 5, y: 0, radii: [0.2, 0.2, 0.1], height: 0.3}\n",
       "objects[0].height: must be in (0, 2 * radii[2]]"},
      {"",
       "  - {kind: ditch, obstacle: true, start: [0, 0], end: [0, 5], depth: 2, top_width: 1}\n",
       "objects[0].top_width: too narrow"},
      {"",
       "  - {kind: bank, obstacle: true, x: 0, y: 0, uphill_heading: 0, rise: 1,"
       " face_slope: 89}\n",
       "objects[0].face_slope: must be in (0, 85] deg"},
      {"", "  - {kind: rod, obstacle: true, start: [1, 1, 1], end: [1, 1, 1], radius: 0.1}\n",
       "objects[0].end: must differ from start"},
      {"",
       obstacle + "  - {kind: pole, id: 3, obstacle: true, x: 9, y: 0, radius: 0.1, height: 1}\n" +
           "  - {kind: pole, id: 3, obstacle: true, x: 9, y: 5, radius: 0.1, height: 1}\n",
       "objects[2].id: is already used by objects[1]"},
      {"camera: {noise: {dropout_probability: 1.5}}\n", "",
       "camera.noise.dropout_probability: must be in [0, 1)"},
      {"camera: {width: 0}\n", "", "camera.width: must be in 2..8192"},
      {"camera: {fx: 100, hfov: 60}\n", "", "camera.hfov: give either fx or hfov"},
      {"lidar: {preset: HDL-32}\n", "", "lidar.preset: unknown preset 'HDL-32'"},
      {"lidar: {elevations: [0, 5]}\n", "", "lidar.elevations[1]: must be below the ring"},
      {"drive: {waypoints: [[0, 0], [10, 0]], speed: 0}\n", "", "drive.speed: must be"},
      {"drive: {waypoints: [[0, 0]]}\n", "", "drive.waypoints: needs at least two points"},
      {"drive: {waypoints: [[0, 0], [10, 0]], turn_radius: -2}\n", "",
       "drive.turn_radius: must be a finite number >= 0"},
      {"drive: {speed: 2}\n", "", "drive.waypoints: missing"},
      {"terrain: {waves: [{amplitude: 0.1, wavelength: 0}]}\n", "",
       "terrain.waves[0].wavelength: must be > 0"},
      {"terrain: {grid: {origin: [0, 0], resolution: 1, cols: 2, rows: 2, heights: [0, 0, 0]}}\n",
       "", "terrain.grid: height grid: heights has 3 values"},
      {"seed: -3\n", "", "seed: must be >= 0"},
      {"objects: {kind: pole}\n", "", "objects: expected a sequence"},
  };
  for (const auto& c : cases) {
    const std::string path = Write(c.extra, c.objects);
    const std::string message = ErrorOf(path);
    EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
    EXPECT_NE(message.find(c.expected), std::string::npos)
        << "expected '" << c.expected << "' in: " << message;
  }
}

TEST_F(WorldFile, MissingSectionsSyntaxAndFiles) {
  const std::string no_description = dir_.Write("a.yaml", "views: [{x: 0, y: 0}]\n").string();
  EXPECT_NE(ErrorOf(no_description).find("description: missing"), std::string::npos);
  const std::string no_views = dir_.Write("b.yaml", "description: x\n").string();
  EXPECT_NE(ErrorOf(no_views).find("views: missing"), std::string::npos);
  const std::string empty_views = dir_.Write("c.yaml", "description: x\nviews: []\n").string();
  EXPECT_NE(ErrorOf(empty_views).find("views: expected a sequence of at least one view"),
            std::string::npos);
  const std::string broken = dir_.Write("d.yaml", "description: [unclosed\n").string();
  EXPECT_NE(ErrorOf(broken).find("invalid YAML"), std::string::npos);
  EXPECT_NE(ErrorOf((dir_ / "none.yaml").string()).find("no such file"), std::string::npos);
  const std::string not_a_map = dir_.Write("e.yaml", "- 1\n- 2\n").string();
  EXPECT_NE(ErrorOf(not_a_map).find("expected a mapping"), std::string::npos);
}

// ---- views and rendering --------------------------------------------------------------

World FlatWorld() {
  World world;
  world.name = "flat";
  world.camera = RangeCameraSpec::Default();
  world.views.push_back(Viewpoint{});
  return world;
}

TEST(View, FollowTerrainTiltsTheCameraWithTheGround) {
  World world = FlatWorld();
  world.scene = Scene(Terrain::Slope(0.0, 12.0 * kDegToRad, 0.5));
  Viewpoint& v = world.views[0];
  v.x_m = 3.0;
  v.y_m = -2.0;
  v.heading_rad = 0.2;
  v.follow_terrain = true;
  const Eigen::Vector3d normal = world.scene.terrain().Normal(3.0, -2.0);
  Camera camera = ViewCamera(world, 0);
  // Level on the ground: the optical axis lies in the tangent plane and the image's -y is
  // the ground normal.
  const Eigen::Matrix3d R = camera.T_world_camera.linear();
  EXPECT_NEAR(R.col(2).dot(normal), 0.0, 1e-12);
  EXPECT_LT((-R.col(1) - normal).norm(), 1e-12);
  EXPECT_NEAR(camera.Position().z(), world.scene.terrain().Height(3.0, -2.0) + 1.6, 1e-12);
  // Pitched by 10 deg relative to the ground.
  v.pitch_rad = 10.0 * kDegToRad;
  camera = ViewCamera(world, 0);
  EXPECT_NEAR(camera.T_world_camera.linear().col(2).dot(normal), -std::sin(10.0 * kDegToRad),
              1e-12);
  // Without follow_terrain the attitude is absolute.
  v.follow_terrain = false;
  camera = ViewCamera(world, 0);
  EXPECT_NEAR(camera.T_world_camera.linear().col(2).z(), -std::sin(10.0 * kDegToRad), 1e-12);
}

TEST(View, RenderViewRejectsAMissingView) {
  const World world = FlatWorld();
  EXPECT_TRUE(RenderView(world, 0).ok());
  const Expected<DepthFrame> missing = RenderView(world, 1);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("view 1"), std::string::npos);
}

// ---- stereo noise -----------------------------------------------------------------------

// A wall square to the optical axis at z-depth `z`: every pixel sees depth z.
Scene WallAt(double z) {
  Scene scene(Terrain::Flat(-1000.0));
  scene.Add(Box{{z + 0.5, 0.0, 1.6}, {1.0, 10.0 * z, 10.0 * z}, 0.0}, true, "wall");
  return scene;
}

TEST(StereoNoise, DepthSigmaGrowsWithTheSquareOfDepth) {
  RangeCameraSpec spec = RangeCameraSpec::Default();
  spec.max_range_m = 100.0;
  spec.noise.depth_sigma_per_m2 = 0.002;
  const Camera camera = Camera::FromAttitude(spec.model, {0, 0, 1.6}, 0.0, 0.0, 0.0);
  for (double z : {4.0, 10.0, 20.0}) {
    SCOPED_TRACE(z);
    const Scene scene = WallAt(z);
    Expected<DepthFrame> frame = RenderRangeCamera(scene, spec, camera, 17);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    double sum = 0.0, sum2 = 0.0;
    int n = 0;
    for (float d : frame->depth_m) {
      ASSERT_GT(d, 0.0f);
      sum += d - z;
      sum2 += (d - z) * (d - z);
      ++n;
    }
    const double sigma = 0.002 * z * z;
    const double mean = sum / n;
    EXPECT_NEAR(std::sqrt(sum2 / n - mean * mean), sigma, 0.1 * sigma);
    EXPECT_NEAR(mean, 0.0, 5.0 * sigma / std::sqrt(n));
  }
}

TEST(StereoNoise, DropoutsHappenAtTheirRateAndLookLikeSky) {
  RangeCameraSpec spec = RangeCameraSpec::Default();
  spec.noise.dropout_probability = 0.05;
  const Camera camera = Camera::FromAttitude(spec.model, {0, 0, 1.6}, 0.0, 0.0, 0.0);
  const Scene scene = WallAt(10.0);
  Expected<DepthFrame> frame = RenderRangeCamera(scene, spec, camera, 5);
  ASSERT_TRUE(frame.ok());
  int dropped = 0;
  for (int i = 0; i < frame->size(); ++i) {
    if (frame->depth_m[i] == 0.0f) {
      ++dropped;
      EXPECT_EQ(frame->object_id[i], kNoHitId);
      EXPECT_EQ(frame->normal[i], Eigen::Vector3f::Zero());
    } else {
      EXPECT_EQ(frame->depth_m[i], 10.0f);  // no depth noise asked
      EXPECT_EQ(frame->object_id[i], 1);
    }
  }
  const double rate = static_cast<double>(dropped) / frame->size();
  // n = 76800: the binomial standard deviation is 0.08%.
  EXPECT_NEAR(rate, 0.05, 0.004);
}

TEST(StereoNoise, EdgesAreSmearedIntoMixedPixels) {
  // A near box covering the left half of the image in front of a far wall.
  RangeCameraSpec spec = RangeCameraSpec::Default();
  spec.max_range_m = 100.0;
  spec.noise.edge_smear_px = 2;
  spec.noise.edge_jump_m = 0.5;
  const Camera camera = Camera::FromAttitude(spec.model, {0, 0, 1.6}, 0.0, 0.0, 0.0);
  Scene scene = WallAt(12.0);
  scene.Add(Box{{5.0, 15.0, 1.6}, {1.0, 30.0, 20.0}, 0.0}, true, "near");  // y > 0: left
  const Expected<DepthFrame> clean = RenderDepth(scene, camera, {100.0, 1e-6, 0});
  const Expected<DepthFrame> smeared = RenderRangeCamera(scene, spec, camera, 1);
  ASSERT_TRUE(clean.ok() && smeared.ok());
  const int row = 120, width = spec.model.width;
  int edge = -1;  // last near column
  for (int c = 0; c + 1 < width; ++c) {
    if (clean->depth_m[row * width + c] < 5.0f && clean->depth_m[row * width + c + 1] > 11.0f) {
      edge = c;
    }
  }
  ASSERT_GT(edge, 2);
  // Columns edge-1 .. edge+2 straddle the jump: strictly between, increasing.
  float previous = clean->depth_m[row * width + edge - 2];
  EXPECT_EQ(smeared->depth_m[row * width + edge - 2], previous);
  for (int c = edge - 1; c <= edge + 2; ++c) {
    const float d = smeared->depth_m[row * width + c];
    EXPECT_GT(d, previous) << c;
    EXPECT_LT(d, 12.0f) << c;
    previous = d;
  }
  EXPECT_EQ(smeared->depth_m[row * width + edge + 3], 12.0f);
  // Ground truth ids are kept.
  EXPECT_EQ(smeared->object_id, clean->object_id);
}

TEST(StereoNoise, SeededByWorldSeedAndViewIndex) {
  World world = FlatWorld();
  world.camera.noise.depth_sigma_per_m2 = 0.01;
  world.camera.noise.dropout_probability = 0.1;
  world.views.push_back(world.views[0]);  // the same pose twice
  const Expected<DepthFrame> a = RenderView(world, 0), b = RenderView(world, 0);
  const Expected<DepthFrame> other_view = RenderView(world, 1);
  world.seed = 2;
  const Expected<DepthFrame> other_seed = RenderView(world, 0);
  ASSERT_TRUE(a.ok() && b.ok() && other_view.ok() && other_seed.ok());
  EXPECT_EQ(a->depth_m, b->depth_m);
  EXPECT_EQ(a->object_id, b->object_id);
  EXPECT_NE(a->depth_m, other_view->depth_m);
  EXPECT_NE(a->depth_m, other_seed->depth_m);
  EXPECT_NE(ViewNoiseSeed(1, 0), ViewNoiseSeed(1, 1));
  EXPECT_NE(ViewNoiseSeed(1, 0), ViewNoiseSeed(2, 0));
}

TEST(StereoNoise, ValidateNamesTheField) {
  StereoNoise noise;
  noise.depth_sigma_per_m2 = -1.0;
  EXPECT_NE(noise.Validate().message().find("depth_sigma_per_m2"), std::string::npos);
  noise = StereoNoise{};
  noise.edge_smear_px = 100;
  EXPECT_NE(noise.Validate().message().find("edge_smear_px"), std::string::npos);
  noise = StereoNoise{};
  noise.edge_jump_m = 0.0;
  EXPECT_NE(noise.Validate().message().find("edge_jump"), std::string::npos);
  EXPECT_TRUE(StereoNoise{}.Validate().ok());
}

// ---- geometry the gallery needs -------------------------------------------------------

Camera LevelCamera(const od::PinholeModel& model, const Eigen::Vector3d& at, double pitch_deg) {
  return Camera::FromAttitude(model, at, 0.0, pitch_deg * kDegToRad, 0.0);
}

TEST(Rod, RaysHitATiltedRodAtTheAnalyticDistance) {
  // A rod along (1, 1, 0.5) through the point c; rays from the origin along +x at heights.
  const Eigen::Vector3d a(4.0, -2.0, 0.0), b(8.0, 2.0, 2.0);
  const double radius = 0.3;
  Scene scene(Terrain::Flat(-100.0));
  const int id = scene.Add(Rod{a, b, radius}, true);
  const RayCaster caster(scene);
  const Eigen::Vector3d axis = (b - a).normalized();
  int hits = 0;
  for (double y = -1.0; y <= 1.0; y += 0.05) {
    for (double z = -0.5; z <= 2.5; z += 0.05) {
      const Ray ray{Eigen::Vector3d(0.0, y, z), Eigen::Vector3d::UnitX()};
      const auto hit = caster.Cast(ray, {});
      // Analytic: |(p - a) x axis| = r with p = o + t x, first root within the caps.
      const Eigen::Vector3d w = ray.origin - a;
      const Eigen::Vector3d dxa = ray.direction.cross(axis), wxa = w.cross(axis);
      const double qa = dxa.squaredNorm(), qb = 2.0 * dxa.dot(wxa);
      const double qc = wxa.squaredNorm() - radius * radius;
      const double disc = qb * qb - 4.0 * qa * qc;
      if (disc < 0.0) {
        EXPECT_FALSE(hit.has_value());
        continue;
      }
      const double t = (-qb - std::sqrt(disc)) / (2.0 * qa);
      const double along = (ray.At(t) - a).dot(axis);
      if (along < 1e-6 || along > (b - a).norm() - 1e-6) continue;  // a cap or beyond
      ++hits;
      ASSERT_TRUE(hit.has_value());
      EXPECT_EQ(hit->id, id);
      EXPECT_NEAR(hit->t, t, 1e-9);
      const Eigen::Vector3d p = ray.At(t);
      const Eigen::Vector3d radial = (p - a) - along * axis;
      EXPECT_LT((hit->normal - radial / radius).norm(), 1e-6);
    }
  }
  EXPECT_GT(hits, 50);
  EXPECT_NEAR(Top(Rod{a, b, radius}), 2.0 + radius * std::sqrt(1.0 - axis.z() * axis.z()), 1e-12);
}

TEST(Bush, IsLumpyDeterministicAndStandsAsTallAsAsked) {
  Scene scene(Terrain::Flat(0.5));
  const int id = scene.AddBush(5.0, 1.0, {0.6, 0.5, 0.4}, 0.7, 0.3, 8, 0.5, 99, true);
  const auto& bush = std::get<Cluster>(scene.Find(id)->shape);
  EXPECT_EQ(bush.parts.size(), 9u);
  EXPECT_NEAR(Top(bush), 1.2, 1e-12);
  EXPECT_LT(Bottom(bush), 0.5);  // the core is sunk into the ground
  const Cluster again = MakeBush(5.0, 1.0, 1.2, {0.6, 0.5, 0.4}, 0.3, 8, 0.5, 99);
  ASSERT_EQ(again.parts.size(), bush.parts.size());
  for (std::size_t i = 0; i < bush.parts.size(); ++i) {
    EXPECT_EQ(again.parts[i].centre, bush.parts[i].centre);
  }
  // A ray meets the nearest part.
  const RayCaster caster(scene);
  const auto hit = caster.Cast({Eigen::Vector3d(0.0, 1.0, 0.9), Eigen::Vector3d::UnitX()}, {});
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->id, id);
  double nearest = 1e9;
  for (const Ellipsoid& e : bush.parts) {
    if (auto h = Intersect(Shape(e), {Eigen::Vector3d(0.0, 1.0, 0.9), Eigen::Vector3d::UnitX()},
                           0.0, 100.0)) {
      nearest = std::min(nearest, h->t);
    }
  }
  EXPECT_NEAR(hit->t, nearest, 1e-12);
}

TEST(Ditch, ProfileWallsAndGroundTruth) {
  Ditch ditch;
  ditch.start = {10.0, -20.0};
  ditch.end = {10.0, 20.0};
  ditch.depth_m = 1.0;
  ditch.top_width_m = 3.0;
  ditch.wall_slope_rad = 60.0 * kDegToRad;
  ASSERT_TRUE(ValidateDitch(ditch).ok());
  Scene scene;
  const int id = scene.AddDitch(ditch, true);
  const Terrain& terrain = scene.terrain();
  const double half_floor = 0.5 * ditch.FloorWidth();  // 1.5 - 1 / tan(60 deg)
  EXPECT_NEAR(half_floor, 1.5 - 1.0 / std::tan(60.0 * kDegToRad), 1e-12);
  EXPECT_NEAR(terrain.Height(10.0, 0.0), -1.0, 1e-12);
  EXPECT_NEAR(terrain.Height(10.0 + half_floor, 3.0), -1.0, 1e-12);
  EXPECT_NEAR(terrain.Height(10.0 + 1.5, 0.0), 0.0, 1e-12);
  EXPECT_NEAR(terrain.Height(10.0 + 1.5 - 0.1, 0.0), -0.1 * std::tan(60.0 * kDegToRad), 1e-12);
  EXPECT_NEAR(terrain.Height(10.0, 21.0), -(1.5 - 1.0) * std::tan(60.0 * kDegToRad), 1e-12);  // end
  EXPECT_NEAR(terrain.Height(14.0, 0.0), 0.0, 1e-12);
  EXPECT_EQ(terrain.IdAt(10.0 + 1.2, 0.0), id);    // wall
  EXPECT_EQ(terrain.IdAt(10.0, 0.0), kTerrainId);  // floor
  EXPECT_EQ(terrain.IdAt(12.0, 0.0), kTerrainId);  // beyond the rim
  EXPECT_NEAR(terrain.Normal(11.2, 0.0).dot(
                  Eigen::Vector3d(-std::sin(60 * kDegToRad), 0, std::cos(60 * kDegToRad))),
              1.0, 1e-9);
  EXPECT_TRUE(std::isfinite(Bound(Shape(ditch)).radius_m));

  // Rendered: hits lie on the surface; the far wall is seen and carries the id, the floor
  // and the near wall are terrain or hidden.
  od::PinholeModel m;
  m.width = 160;
  m.height = 120;
  m.fx = m.fy = 130.0;
  m.cx = 79.5;
  m.cy = 59.5;
  const Camera camera = LevelCamera(m, {0.0, 0.0, 1.6}, 10.0);
  Expected<DepthFrame> frame = RenderDepth(scene, camera);
  ASSERT_TRUE(frame.ok());
  int wall = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const int i = r * m.width + c;
      if (frame->object_id[i] == kNoHitId) continue;
      const Eigen::Vector3d p = camera.UnprojectWorld(c, r, frame->depth_m[i]);
      EXPECT_NEAR(p.z(), terrain.Height(p.x(), p.y()), 2e-5) << c << "," << r;
      if (frame->object_id[i] == id) {
        ++wall;
        EXPECT_GT(p.x(), 10.0);  // only the far wall faces the camera
        EXPECT_LT(p.z(), 1e-4);
      }
    }
  }
  EXPECT_GT(wall, 100);
}

TEST(Bank, RaisesTheGroundAndMarksItsFace) {
  Bank bank;
  bank.centre = {20.0, 0.0};
  bank.uphill_heading_rad = 0.0;
  bank.rise_m = 1.2;
  bank.face_slope_rad = 70.0 * kDegToRad;
  Scene scene(Terrain::Flat(0.3));
  const int id = scene.AddBank(bank, true);
  const Terrain& terrain = scene.terrain();
  const double half = 0.5 * bank.FaceWidth();
  EXPECT_NEAR(terrain.Height(0.0, 5.0), 0.3, 1e-12);
  EXPECT_NEAR(terrain.Height(30.0, -5.0), 1.5, 1e-12);
  EXPECT_NEAR(terrain.Height(20.0, 3.0), 0.9, 1e-12);
  EXPECT_NEAR(terrain.Height(20.0 + 0.5 * half, 0.0), 0.3 + 0.75 * 1.2, 1e-12);
  EXPECT_EQ(terrain.IdAt(20.0, 7.0), id);
  EXPECT_EQ(terrain.IdAt(20.0 + half + 0.01, 7.0), kTerrainId);
  EXPECT_NEAR(terrain.MaxGradient(), std::tan(70.0 * kDegToRad), 1e-12);
  EXPECT_NEAR(terrain.MaxGradientNear({0.0, 0.0}, 1.0), 0.0, 1e-12);
  // The base terrain can be replaced; the bank is carved in again.
  scene.set_terrain(Terrain::Flat(-1.0));
  EXPECT_NEAR(scene.terrain().Height(30.0, 0.0), 0.2, 1e-12);
  EXPECT_NEAR(scene.base_terrain().Height(30.0, 0.0), -1.0, 1e-12);
  // A ray along +x at 1 m meets the face where the ground reaches 1 m.
  const RayCaster caster(scene);
  const auto hit = caster.Cast({Eigen::Vector3d(0.0, 0.0, 0.0), Eigen::Vector3d::UnitX()}, {});
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->id, id);
  EXPECT_NEAR(hit->t, 20.0 + half * (1.0 / 1.2 * 2.0 - 1.0), 1e-5);
}

TEST(Terrain, RoughHillsWithAFeatureRenderOnTheSurface) {
  // Waves, a grid and a ditch together: the marcher with pieces and envelopes must still
  // land every hit on the surface.
  Terrain terrain = Terrain::Hills(0.0, {{0.3, 12.0, 0.4, 0.0}, {0.05, 1.5, 2.0, 1.0}});
  Scene scene(terrain);
  Ditch ditch;
  ditch.start = {6.0, -10.0};
  ditch.end = {9.0, 10.0};
  ditch.depth_m = 0.7;
  ditch.top_width_m = 2.5;
  scene.AddDitch(ditch, true);
  Bank bank;
  bank.centre = {25.0, 0.0};
  bank.uphill_heading_rad = 0.3;
  scene.AddBank(bank, true);
  od::PinholeModel m;
  m.width = 96;
  m.height = 72;
  m.fx = m.fy = 70.0;
  m.cx = 47.5;
  m.cy = 35.5;
  const Camera camera = LevelCamera(m, {0.0, 0.0, 1.8}, 8.0);
  Expected<DepthFrame> frame = RenderDepth(scene, camera);
  ASSERT_TRUE(frame.ok());
  int terrain_pixels = 0;
  for (int r = 0; r < m.height; ++r) {
    for (int c = 0; c < m.width; ++c) {
      const int i = r * m.width + c;
      if (frame->object_id[i] == kNoHitId) continue;
      ++terrain_pixels;
      const Eigen::Vector3d p = camera.UnprojectWorld(c, r, frame->depth_m[i]);
      EXPECT_NEAR(p.z(), scene.terrain().Height(p.x(), p.y()), 3e-5);
      EXPECT_EQ(frame->object_id[i], scene.terrain().IdAt(p.x(), p.y()));
    }
  }
  EXPECT_GT(terrain_pixels, m.width * m.height / 2);
}

}  // namespace
}  // namespace cairn::sim
