// End to end: runs the built `cairn detect` on a frame rendered here (flat ground and a
// box, seen by a pinhole camera 1.5 m above the ground pitched down 10 deg) and on bad
// inputs.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/units.hpp"
#include "cairn_command.hpp"
#include "temp_dir.hpp"

#ifndef CAIRN_EXE
#error "CAIRN_EXE must name the cairn executable"
#endif

namespace cairn {
namespace {

constexpr int kWidth = 160, kHeight = 120;
constexpr double kFocal = 150.0, kCx = 79.5, kCy = 59.5;
constexpr double kCameraHeight = 1.5, kPitchDeg = 10.0;
constexpr double kDepthScale = 0.001;  // [m per unit], 65 m range
// The box, in the level frame (x forward, y left, z up from the camera): 1 m wide,
// 0.5 m deep, 0.7 m tall (taller than 2 HT, so that every face point has a partner).
constexpr double kBoxNear = 5.0, kBoxFar = 5.5, kBoxHalfWidth = 0.5, kBoxTall = 0.7;

enum class Hit { kNone, kGround, kBox };

struct Scene {
  od::Grid<float> depth{kWidth, kHeight, {}};
  std::vector<Hit> hit;
  std::vector<Eigen::Vector3d> level_point;  ///< where each pixel's ray hits [m]
};

/// Ray casting in the level frame, z-depth out.
Scene Render() {
  const double pitch = kPitchDeg * kPi / 180.0;
  // Optical frame (x right, y down, z forward) to level frame (x forward, y left, z up).
  const Eigen::Vector3d up(0.0, -std::cos(pitch), -std::sin(pitch));
  const Eigen::Vector3d forward =
      (Eigen::Vector3d::UnitZ() - up.z() * up).normalized();  // heading on the level plane
  const Eigen::Vector3d left = up.cross(forward);
  Scene scene;
  for (int r = 0; r < kHeight; ++r) {
    for (int c = 0; c < kWidth; ++c) {
      const Eigen::Vector3d ray_cam((c - kCx) / kFocal, (r - kCy) / kFocal, 1.0);  // z = 1
      const Eigen::Vector3d ray(ray_cam.dot(forward), ray_cam.dot(left), ray_cam.dot(up));
      double t_best = std::numeric_limits<double>::infinity();
      Hit hit = Hit::kNone;
      if (ray.z() < 0.0) {
        t_best = -kCameraHeight / ray.z();
        hit = Hit::kGround;
      }
      // Slab test against the box.
      const Eigen::Vector3d lo(kBoxNear, -kBoxHalfWidth, -kCameraHeight);
      const Eigen::Vector3d hi(kBoxFar, kBoxHalfWidth, -kCameraHeight + kBoxTall);
      double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        if (std::abs(ray[k]) < 1e-12) {
          if (0.0 < lo[k] || 0.0 > hi[k]) t0 = std::numeric_limits<double>::infinity();
          continue;
        }
        double a = lo[k] / ray[k], b = hi[k] / ray[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
      }
      if (t0 <= t1 && t0 < t_best) {
        t_best = t0;
        hit = Hit::kBox;
      }
      if (t_best > 40.0) hit = Hit::kNone;
      scene.depth.data.push_back(hit == Hit::kNone ? 0.0f : static_cast<float>(t_best));
      scene.hit.push_back(hit);
      scene.level_point.push_back(t_best * ray);
    }
  }
  return scene;
}

/// Horizontal distance from a level-frame point to the box's footprint [m].
double DistanceToBox(const Eigen::Vector3d& p) {
  const double dx = std::max({kBoxNear - p.x(), 0.0, p.x() - kBoxFar});
  const double dy = std::max({-kBoxHalfWidth - p.y(), 0.0, p.y() - kBoxHalfWidth});
  return std::hypot(dx, dy);
}

using RunResult = test::CommandResult;

RunResult RunCairn(const std::vector<std::string>& args) {
  return test::RunProgram(CAIRN_EXE, args);
}

const char* kIntrinsics =
    "width: 160\nheight: 120\nfx: 150\nfy: 150\ncx: 79.5\ncy: 59.5\n"
    "depth_scale: 0.001\npitch_deg: 10\n";

const char* kConfig =
    "detector:\n  min_height: 0.3\n  max_height: 1.0\n  min_slope: 45\n  search: exact\n"
    "rules:\n  min_points: 10\n  min_height_max: 0.3\n  min_volume: 0.005\n";

class DetectCli : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = Render();
    ASSERT_TRUE(od::io::WriteDepthPng(dir_ / "depth.png", scene_.depth, kDepthScale).ok());
    intrinsics_ = dir_.Write("cam.yaml", kIntrinsics);
    config_ = dir_.Write("cfg.yaml", kConfig);
  }

  std::vector<std::string> Args(const std::filesystem::path& depth,
                                const std::filesystem::path& intrinsics,
                                const std::filesystem::path& config) const {
    return {
        "detect",   "--depth",       depth.string(), "--intrinsics",         intrinsics.string(),
        "--config", config.string(), "--out",        (dir_ / "out").string()};
  }

  /// Expects a clean failure (exit 1, no crash) whose message contains `needle`.
  void ExpectFailure(const std::vector<std::string>& args, const std::string& needle) {
    const RunResult run = RunCairn(args);
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find(needle), std::string::npos)
        << "expected \"" << needle << "\" in: " << run.output;
  }

  test::TempDir dir_;
  Scene scene_;
  std::filesystem::path intrinsics_, config_;
};

TEST_F(DetectCli, FindsTheBoxAndNotTheGround) {
  int box_pixels = 0, far_ground_pixels = 0;
  for (const Hit h : scene_.hit) box_pixels += h == Hit::kBox;
  ASSERT_GT(box_pixels, 200);  // the scene is what this test thinks it is

  const RunResult run = RunCairn(Args(dir_ / "depth.png", intrinsics_, config_));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("kept"), std::string::npos) << run.output;
  const std::filesystem::path out = dir_ / "out";
  for (const char* name :
       {"segments.png", "classes.png", "segments.json", "overlay.png", "segments_color.png"}) {
    EXPECT_TRUE(std::filesystem::is_regular_file(out / name)) << name;
  }

  Expected<od::Grid<std::uint8_t>> classes = od::io::ReadClassesPng(out / "classes.png");
  ASSERT_TRUE(classes.ok()) << classes.error().message;
  ASSERT_EQ(classes->width, kWidth);
  ASSERT_EQ(classes->height, kHeight);
  for (int i = 0; i < kWidth * kHeight; ++i) {
    const int row = i / kWidth, col = i % kWidth;
    if (scene_.hit[i] == Hit::kBox) {
      EXPECT_EQ(classes->data[i], 1) << "box pixel row " << row << ", col " << col;
    } else if (scene_.hit[i] == Hit::kGround && DistanceToBox(scene_.level_point[i]) > 1.1) {
      // Ground within Hmax of the box's foot may pair with its face: that is the base.
      ++far_ground_pixels;
      EXPECT_EQ(classes->data[i], 0) << "ground pixel row " << row << ", col " << col;
    } else if (scene_.hit[i] == Hit::kNone) {
      EXPECT_EQ(classes->data[i], 0) << "empty pixel row " << row << ", col " << col;
    }
  }
  EXPECT_GT(far_ground_pixels, 5000);

  std::ifstream in(out / "segments.json");
  const nlohmann::json doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["method"], "cone");
  EXPECT_EQ(doc["summary"]["kept"], 1);
  EXPECT_EQ(doc["inputs"]["config"], config_.string());
}

TEST_F(DetectCli, BenchTimesEveryMethodAndChecksTheExactOneAgainstTheDefinition) {
  // 160x120 with a box: small enough for the brute force, which must agree.
  const RunResult run = RunCairn({"bench", "--depth", (dir_ / "depth.png").string(),
                                  "--intrinsics", intrinsics_.string(), "--config",
                                  config_.string(), "--repeat", "3", "--rate", "10"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* line :
       {"cone exact, 1 thread", "cone exact, every core", "region scan (reference)",
        "cone paper window, 1 thread", "column baseline", "brute force (the definition)",
        "exact = region scan = brute force: yes",
        "cone exact, every core over 1 thread: ", "at 10.0 Hz a frame has 100.0 ms"}) {
    EXPECT_NE(run.output.find(line), std::string::npos) << line << " missing in:\n" << run.output;
  }
  // The reference row is its own unit.
  EXPECT_NE(run.output.find("1.00x"), std::string::npos) << run.output;
  ExpectFailure({"bench", "--depth", (dir_ / "none.png").string(), "--intrinsics",
                 intrinsics_.string()},
                "none.png");
  ExpectFailure({"bench"}, "give one input: a frame (--depth");
}

TEST_F(DetectCli, WithoutRulesEveryObstaclePointIsKept) {
  std::vector<std::string> args = Args(dir_ / "depth.png", intrinsics_, config_);
  args.push_back("--no-rules");
  const RunResult run = RunCairn(args);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Expected<od::Grid<std::int32_t>> segments =
      od::io::ReadSegmentsPng(dir_ / "out" / "segments.png");
  Expected<od::Grid<std::uint8_t>> classes = od::io::ReadClassesPng(dir_ / "out" / "classes.png");
  ASSERT_TRUE(segments.ok() && classes.ok());
  int obstacle_points = 0;
  for (std::size_t i = 0; i < classes->data.size(); ++i) {
    EXPECT_EQ(classes->data[i], segments->data[i] != 0 ? 1 : 0) << i;
    obstacle_points += segments->data[i] != 0;
  }
  EXPECT_GT(obstacle_points, 200);
}

TEST_F(DetectCli, ColumnMethodFindsTheBoxFace) {
  std::vector<std::string> args = Args(dir_ / "depth.png", intrinsics_, config_);
  args.insert(args.end(), {"--method", "column"});
  const RunResult run = RunCairn(args);
  ASSERT_EQ(run.exit_code, 0) << run.output;
  Expected<od::Grid<std::uint8_t>> classes = od::io::ReadClassesPng(dir_ / "out" / "classes.png");
  ASSERT_TRUE(classes.ok());
  int box = 0, box_kept = 0;
  for (std::size_t i = 0; i < classes->data.size(); ++i) {
    if (scene_.hit[i] != Hit::kBox) continue;
    ++box;
    box_kept += classes->data[i] == 1;
  }
  EXPECT_GT(box_kept, box * 9 / 10);
}

TEST_F(DetectCli, MissingDepthFile) {
  ExpectFailure(Args(dir_ / "none.png", intrinsics_, config_),
                (dir_ / "none.png").string() + ": no such file");
}

TEST_F(DetectCli, DepthOfTheWrongSize) {
  const od::Grid<float> small{80, 60, std::vector<float>(80 * 60, 2.0f)};
  ASSERT_TRUE(od::io::WriteDepthPng(dir_ / "small.png", small, kDepthScale).ok());
  ExpectFailure(Args(dir_ / "small.png", intrinsics_, config_), "width 160");
}

TEST_F(DetectCli, NonFiniteFocalLength) {
  std::string text = kIntrinsics;
  text.replace(text.find("fx: 150"), 7, "fx: .nan");
  const auto bad = dir_.Write("bad.yaml", text);
  ExpectFailure(Args(dir_ / "depth.png", bad, config_), bad.string() + ": fx: ");
}

TEST_F(DetectCli, ZeroUpVector) {
  std::string text = kIntrinsics;
  text.replace(text.find("pitch_deg: 10"), 13, "up: [0, 0, 0]");
  const auto bad = dir_.Write("bad.yaml", text);
  ExpectFailure(Args(dir_ / "depth.png", bad, config_), bad.string() + ": up: ");
}

TEST_F(DetectCli, UnknownConfigKey) {
  const auto bad = dir_.Write("bad_cfg.yaml", "detector:\n  min_heigth: 0.3\n");
  ExpectFailure(Args(dir_ / "depth.png", intrinsics_, bad),
                bad.string() + ": detector.min_heigth: unknown key");
}

TEST_F(DetectCli, MinHeightAboveMaxHeight) {
  const auto bad = dir_.Write("bad_cfg.yaml", "detector:\n  min_height: 1.2\n  max_height: 1.0\n");
  ExpectFailure(Args(dir_ / "depth.png", intrinsics_, bad),
                bad.string() + ": detector.max_height: ");
}

TEST_F(DetectCli, UnknownMethodAndMissingOptionAreUsageErrors) {
  std::vector<std::string> args = Args(dir_ / "depth.png", intrinsics_, config_);
  args.insert(args.end(), {"--method", "magic"});
  RunResult run = RunCairn(args);
  EXPECT_GT(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("--method"), std::string::npos) << run.output;
  run = RunCairn({"detect", "--depth", (dir_ / "depth.png").string()});
  EXPECT_GT(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("--intrinsics"), std::string::npos) << run.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out"));
}

}  // namespace
}  // namespace cairn
