// Stereo pairs: calibration files (three formats, clear errors), rectification, semi-global
// matching and depth with its uncertainty, against rendered ground truth (libsim) and real
// pairs (Middlebury Aloe with true disparity, the FoundationStereo desk with its K.txt).
#include "cairn/sim/stereo.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "cairn/eval/plane_fit.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"
#include "cairn_command.hpp"
#include "temp_dir.hpp"

namespace cairn::od::io {
namespace {

const std::filesystem::path kDatasets = CAIRN_SHARED_DATASETS;

#define SKIP_WITHOUT_DATASET(folder)                                                      \
  if (!std::filesystem::exists(kDatasets / folder)) {                                     \
    GTEST_SKIP() << (kDatasets / folder).string()                                         \
                 << " not found: this test needs ../shared/datasets (see its README.md)"; \
  }

testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return testing::AssertionSuccess();
  return testing::AssertionFailure() << "\"" << text << "\" does not contain \"" << part << "\"";
}

PinholeModel Model(int width, int height, double f) {
  PinholeModel m;
  m.width = width;
  m.height = height;
  m.fx = m.fy = f;
  m.cx = (width - 1) / 2.0;
  m.cy = (height - 1) / 2.0;
  return m;
}

GreyImage ToIo(const sim::GreyImage& image) {
  return GreyImage{image.width, image.height, image.data};
}

// ---------------------------------------------------------------------------------------
// Calibration files

TEST(StereoCalibrationYaml, ReadsEveryField) {
  Expected<StereoCalibration> c = ParseStereoCalibrationYaml(
      "width: 640\nheight: 480\nfx: 500\nfy: 501\ncx: 319.5\ncy: 239.5\nbaseline: 0.12\n"
      "pitch_deg: 10\n",
      "rig.yaml");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->model.width, 640);
  EXPECT_EQ(c->model.height, 480);
  EXPECT_DOUBLE_EQ(c->model.fx, 500.0);
  EXPECT_DOUBLE_EQ(c->model.fy, 501.0);
  EXPECT_DOUBLE_EQ(c->model.cx, 319.5);
  EXPECT_DOUBLE_EQ(c->model.cy, 239.5);
  EXPECT_DOUBLE_EQ(c->baseline_m, 0.12);
  EXPECT_DOUBLE_EQ(c->fx_baseline(), 60.0);
  ASSERT_TRUE(c->up.has_value());
  EXPECT_LT(
      (*c->up - Eigen::Vector3d(0.0, -std::cos(10 * kDegToRad), -std::sin(10 * kDegToRad))).norm(),
      1e-12);
  EXPECT_FALSE(c->rectification.has_value());
}

TEST(StereoCalibrationYaml, FyDefaultsToFxAndUpIsOptional) {
  Expected<StereoCalibration> c = ParseStereoCalibrationYaml(
      "width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\n", "rig.yaml");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_DOUBLE_EQ(c->model.fy, 50.0);
  EXPECT_FALSE(c->up.has_value());
  Expected<StereoCalibration> up = ParseStereoCalibrationYaml(
      "width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\nup: [0, -2, 0]\n",
      "rig.yaml");
  ASSERT_TRUE(up.ok()) << up.error().message;
  EXPECT_LT((*up->up - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
}

TEST(StereoCalibrationYaml, MissingOrBadFieldsNameFileAndField) {
  const std::string full = "width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\n";
  struct Case {
    std::string yaml;
    std::string message;
  };
  const Case cases[] = {
      {"width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\n",
       "rig.yaml: baseline: missing (expected the distance between the cameras [m])"},
      {"height: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\n",
       "rig.yaml: width: missing (expected a positive integer [px])"},
      {"width: 64\nheight: 48\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\n",
       "rig.yaml: fx: missing (expected a focal length [px])"},
      {"width: 64\nheight: 48\nfx: 50\ncy: 23.5\nbaseline: 0.3\n",
       "rig.yaml: cx: missing (expected a principal point column [px])"},
      {full + "baseline_mm: 3\n", "rig.yaml: baseline_mm: unknown key"},
      {"width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: -0.3\n",
       "rig.yaml: baseline: expected a positive baseline [m], got -0.3"},
      {"width: 64\nheight: 48\nfx: 50\ncx: 31.5\ncy: 23.5\nbaseline: 120\n",
       "rig.yaml: baseline: baseline 120 is implausible in metres"},
      {"width: 64\nheight: 48\nfx: abc\ncx: 31.5\ncy: 23.5\nbaseline: 0.3\n",
       "rig.yaml: fx: expected a number, got 'abc'"},
      {full + "up: [0, 0]\n", "rig.yaml: up: expected a sequence of 3 numbers"},
      {full + "roll_deg: 3\n", "rig.yaml: pitch_deg: missing: roll_deg is given"},
  };
  for (const Case& c : cases) {
    Expected<StereoCalibration> calib = ParseStereoCalibrationYaml(c.yaml, "rig.yaml");
    ASSERT_FALSE(calib.ok()) << c.yaml;
    EXPECT_TRUE(Contains(calib.error().message, c.message)) << c.yaml;
  }
}

TEST(FoundationStereoK, ReadsKAndBaselineWithoutASize) {
  Expected<StereoCalibration> c =
      ParseFoundationStereoK("700 0 320.5 0 701 240.5 0 0 1\n0.1\n", "K.txt");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_DOUBLE_EQ(c->model.fx, 700.0);
  EXPECT_DOUBLE_EQ(c->model.fy, 701.0);
  EXPECT_DOUBLE_EQ(c->model.cx, 320.5);
  EXPECT_DOUBLE_EQ(c->model.cy, 240.5);
  EXPECT_DOUBLE_EQ(c->baseline_m, 0.1);
  EXPECT_EQ(c->model.width, 0);  // from the images

  // The pair gives the size.
  Expected<StereoPair> prepared =
      PrepareStereoPair(GreyImage{32, 24, std::vector<std::uint8_t>(32 * 24, 7)},
                        GreyImage{32, 24, std::vector<std::uint8_t>(32 * 24, 7)}, *c);
  ASSERT_TRUE(prepared.ok()) << prepared.error().message;
  EXPECT_EQ(prepared->calibration.model.width, 32);
  EXPECT_EQ(prepared->calibration.model.height, 24);
}

TEST(FoundationStereoK, MalformedFilesNameTheLineAndField) {
  struct Case {
    std::string text;
    std::string message;
  };
  const Case cases[] = {
      {"700 0 320 0 700 240 0 0\n0.1\n",
       "K.txt: line 1: K: expected the 9 entries of the 3x3 intrinsic matrix, got 8 numbers"},
      {"700 0 320 0 700 240 0 0 1\n", "K.txt: line 2: baseline: missing"},
      {"700 0 320 0 700 240 0 0 1\n0.1 0.2\n", "K.txt: line 2: baseline: expected one number"},
      {"700 0 320 0 700 240 0 0 1\n0\n", "K.txt: line 2: baseline: expected a positive"},
      {"700 3 320 0 700 240 0 0 1\n0.1\n", "K.txt: line 1: K: expected [fx 0 cx; 0 fy cy; 0 0 1]"},
      {"700 0 320 0 x 240 0 0 1\n0.1\n", "K.txt: line 1: 'x' is not a number"},
  };
  for (const Case& c : cases) {
    Expected<StereoCalibration> calib = ParseFoundationStereoK(c.text, "K.txt");
    ASSERT_FALSE(calib.ok()) << c.text;
    EXPECT_TRUE(Contains(calib.error().message, c.message)) << c.text;
  }
}

TEST(FoundationStereoK, TheDeskCalibrationLoadsByContent) {
  SKIP_WITHOUT_DATASET("stereo-desk-foundationstereo");
  const std::filesystem::path file = kDatasets / "stereo-desk-foundationstereo" / "K.txt";
  Expected<StereoCalibration> c = LoadStereoCalibration(file);
  ASSERT_TRUE(c.ok()) << c.error().message;
  // README: fx 754.668, cx 489.379, cy 265.162, baseline 0.063 m.
  EXPECT_NEAR(c->model.fx, 754.668, 1e-3);
  EXPECT_NEAR(c->model.fy, 754.668, 1e-3);
  EXPECT_NEAR(c->model.cx, 489.379, 1e-3);
  EXPECT_NEAR(c->model.cy, 265.162, 1e-3);
  EXPECT_DOUBLE_EQ(c->baseline_m, 0.063);
}

/// An OpenCV stereo calibration file as cv::stereoCalibrate's users write it.
struct OpenCvRig {
  cv::Mat M1, D1, M2, D2, R, T;
  int width = 0, height = 0;
};

void WriteOpenCv(const std::filesystem::path& path, const OpenCvRig& rig,
                 const std::vector<std::string>& skip = {}) {
  cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
  const auto keep = [&](const std::string& key) {
    return std::find(skip.begin(), skip.end(), key) == skip.end();
  };
  if (keep("image_width")) fs << "image_width" << rig.width;
  if (keep("image_height")) fs << "image_height" << rig.height;
  if (keep("M1")) fs << "M1" << rig.M1;
  if (keep("D1")) fs << "D1" << rig.D1;
  if (keep("M2")) fs << "M2" << rig.M2;
  if (keep("D2")) fs << "D2" << rig.D2;
  if (keep("R")) fs << "R" << rig.R;
  if (keep("T")) fs << "T" << rig.T;
}

OpenCvRig ParallelRig() {
  OpenCvRig rig;
  rig.width = 320;
  rig.height = 240;
  rig.M1 = (cv::Mat_<double>(3, 3) << 256, 0, 159.5, 0, 256, 119.5, 0, 0, 1);
  rig.M2 = rig.M1.clone();
  rig.D1 = cv::Mat::zeros(1, 5, CV_64F);
  rig.D2 = cv::Mat::zeros(1, 5, CV_64F);
  rig.R = cv::Mat::eye(3, 3, CV_64F);
  rig.T = (cv::Mat_<double>(3, 1) << -0.25, 0, 0);
  return rig;
}

TEST(OpenCvStereoCalibration, AParallelRigKeepsItsCameraAndBaseline) {
  test::TempDir dir;
  for (const char* name : {"stereo.yml", "stereo.xml"}) {
    WriteOpenCv(dir / name, ParallelRig());
    Expected<StereoCalibration> c = LoadStereoCalibration(dir / name);
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_NEAR(c->baseline_m, 0.25, 1e-12) << name;
    EXPECT_NEAR(c->model.fx, 256.0, 1e-9) << name;
    EXPECT_NEAR(c->model.cx, 159.5, 1e-9) << name;
    EXPECT_NEAR(c->model.cy, 119.5, 1e-9) << name;
    EXPECT_EQ(c->model.width, 320);
    ASSERT_TRUE(c->rectification.has_value());
    EXPECT_EQ(c->rectification->raw_width, 320);
    EXPECT_LT((c->rectification->R1 - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  }
  // Plain YAML lists instead of !!opencv-matrix, no %YAML line, a rotation vector for R.
  dir.Write("plain.yaml",
            "image_size: [320, 240]\nM1: [256, 0, 159.5, 0, 256, 119.5, 0, 0, 1]\n"
            "M2: [256, 0, 159.5, 0, 256, 119.5, 0, 0, 1]\nD1: [0, 0, 0, 0]\n"
            "D2: [0, 0, 0, 0, 0]\nR: [0, 0, 0]\nT: [-0.2, 0, 0]\n");
  Expected<StereoCalibration> plain = LoadStereoCalibration(dir / "plain.yaml");
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_NEAR(plain->baseline_m, 0.2, 1e-12);
  EXPECT_NEAR(plain->model.fx, 256.0, 1e-9);
  EXPECT_EQ(plain->model.height, 240);
}

TEST(OpenCvStereoCalibration, MissingAndBadFieldsNameFileAndField) {
  test::TempDir dir;
  const std::string file = (dir / "stereo.yml").string();
  for (const std::string key : {"M1", "D1", "M2", "D2", "R", "T"}) {
    WriteOpenCv(file, ParallelRig(), {key});
    Expected<StereoCalibration> c = LoadStereoCalibration(file);
    ASSERT_FALSE(c.ok()) << key;
    EXPECT_TRUE(Contains(c.error().message, file + ": " + key + ": missing (expected ")) << key;
  }
  WriteOpenCv(file, ParallelRig(), {"image_width"});
  Expected<StereoCalibration> no_size = LoadStereoCalibration(file);
  ASSERT_FALSE(no_size.ok());
  EXPECT_TRUE(Contains(no_size.error().message, file + ": image_width: missing"));

  OpenCvRig swapped = ParallelRig();
  swapped.T.at<double>(0) = 0.25;  // camera 2 on the left
  WriteOpenCv(file, swapped);
  Expected<StereoCalibration> s = LoadStereoCalibration(file);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(Contains(s.error().message, file + ": T: camera 2 is left of camera 1"));

  OpenCvRig millimetres = ParallelRig();
  millimetres.T.at<double>(0) = -250.0;
  WriteOpenCv(file, millimetres);
  Expected<StereoCalibration> mm = LoadStereoCalibration(file);
  ASSERT_FALSE(mm.ok());
  EXPECT_TRUE(Contains(mm.error().message, "is implausible in metres"));

  OpenCvRig bad_d = ParallelRig();
  bad_d.D1 = cv::Mat::zeros(1, 3, CV_64F);
  WriteOpenCv(file, bad_d);
  Expected<StereoCalibration> d = LoadStereoCalibration(file);
  ASSERT_FALSE(d.ok());
  EXPECT_TRUE(Contains(d.error().message, file + ": D1: expected a vector of 4, 5, 8, 12 or 14"));

  OpenCvRig bad_r = ParallelRig();
  bad_r.R.at<double>(0, 0) = 2.0;
  WriteOpenCv(file, bad_r);
  Expected<StereoCalibration> r = LoadStereoCalibration(file);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(Contains(r.error().message, file + ": R: not a rotation matrix"));
}

TEST(StereoCalibrationFile, UnknownContentAndMissingFilesAreErrors) {
  test::TempDir dir;
  Expected<StereoCalibration> none = LoadStereoCalibration(dir / "none.yaml");
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.error().message, (dir / "none.yaml").string() + ": no such file");
  dir.Write("list.yaml", "- 1\n- 2\n");
  Expected<StereoCalibration> list = LoadStereoCalibration(dir / "list.yaml");
  ASSERT_FALSE(list.ok());
  EXPECT_TRUE(Contains(list.error().message, "not a stereo calibration"));
  dir.Write("broken.yml", "%YAML:1.0\n---\nM1: [1, 2\n");
  Expected<StereoCalibration> broken = LoadStereoCalibration(dir / "broken.yml");
  ASSERT_FALSE(broken.ok());
  EXPECT_TRUE(Contains(broken.error().message,
                       (dir / "broken.yml").string() + ": not a readable OpenCV calibration file"));
}

// ---------------------------------------------------------------------------------------
// Settings

TEST(StereoSettings, TheStereoSectionIsReadStrictly) {
  Expected<DetectSettings> s = ParseDetectSettings(
      "stereo:\n  min_depth: 2.5\n  max_depth: 40\n  block_size: 7\n  p1: 100\n  p2: 900\n"
      "  uniqueness: 5\n  speckle_window: 50\n  speckle_range: 1\n  disp12_max_diff: 2\n"
      "  pre_filter_cap: 31\n  mode: hh\n  min_texture: 3\n  disparity_sigma: 0.4\n",
      "cfg.yaml");
  ASSERT_TRUE(s.ok()) << s.error().message;
  const StereoConfig& read = s->stereo;
  EXPECT_DOUBLE_EQ(read.min_depth_m, 2.5);
  EXPECT_DOUBLE_EQ(read.max_depth_m, 40.0);
  EXPECT_EQ(read.block_size, 7);
  EXPECT_EQ(read.p1, 100);
  EXPECT_EQ(read.p2, 900);
  EXPECT_EQ(read.uniqueness, 5);
  EXPECT_EQ(read.speckle_window, 50);
  EXPECT_EQ(read.speckle_range, 1);
  EXPECT_EQ(read.disp12_max_diff, 2);
  EXPECT_EQ(read.pre_filter_cap, 31);
  EXPECT_EQ(read.mode, StereoMode::kHh);
  EXPECT_DOUBLE_EQ(read.min_texture, 3.0);
  EXPECT_DOUBLE_EQ(read.disparity_sigma_px, 0.4);

  struct Case {
    std::string yaml;
    std::string message;
  };
  const Case cases[] = {
      {"stereo:\n  blocksize: 5\n", "cfg.yaml: stereo.blocksize: unknown key in stereo"},
      {"stereo:\n  block_size: 6\n", "cfg.yaml: stereo.block_size: stereo config: block_size"},
      {"stereo:\n  num_disparities: 40\n", "cfg.yaml: stereo.num_disparities:"},
      {"stereo:\n  mode: fast\n", "cfg.yaml: stereo.mode: expected sgbm, sgbm_3way, hh or hh4"},
      {"stereo:\n  p1: 500\n  p2: 400\n", "cfg.yaml: stereo.p2:"},
      {"stereo:\n  min_depth: 0\n", "cfg.yaml: stereo.min_depth:"},
      {"stereo:\n  disparity_sigma: -1\n", "cfg.yaml: stereo.disparity_sigma:"},
  };
  for (const Case& c : cases) {
    Expected<DetectSettings> bad = ParseDetectSettings(c.yaml, "cfg.yaml");
    ASSERT_FALSE(bad.ok()) << c.yaml;
    EXPECT_TRUE(Contains(bad.error().message, c.message)) << c.yaml;
  }
}

TEST(StereoSettings, TheSearchRangeFollowsTheClosestDepth) {
  StereoConfig c;
  c.min_depth_m = 2.0;
  // fx B = 76.8 px m: 38.4 px at 2 m, rounded up to 48.
  Expected<int> n = c.NumDisparities(76.8, 320);
  ASSERT_TRUE(n.ok()) << n.error().message;
  EXPECT_EQ(*n, 48);
  c.min_depth_m = 76.8 / 32.0;  // exactly 32 px
  EXPECT_EQ(*c.NumDisparities(76.8, 320), 32);
  c.min_depth_m = 0.1;  // 768 px: more than the width
  Expected<int> too_near = c.NumDisparities(76.8, 320);
  ASSERT_FALSE(too_near.ok());
  EXPECT_TRUE(Contains(too_near.error().message, "raise min_depth"));
  c.num_disparities = 64;  // given: used as it is
  EXPECT_EQ(*c.NumDisparities(76.8, 320), 64);
}

// ---------------------------------------------------------------------------------------
// Matching against rendered truth

/// A flat field with textured obstacles and one untextured wall, seen by a 320x240 rig
/// (fx 256 px, 0.3 m baseline: 1 px of disparity is 0.3 m at 8.8 m, 2.6 m at 25 m).
struct RenderedScene {
  sim::Scene scene{sim::Terrain::Plane(0.0, Eigen::Vector2d(0.01, 0.02))};
  int plain_id = 0;
  sim::StereoRigSpec rig;
  sim::Camera camera;

  RenderedScene() {
    scene.AddPole(8, 1.5, 0.15, 1.5, true);
    scene.AddPole(14, -3, 0.2, 2.0, true);
    scene.AddRock(6, -1.5, {0.6, 0.5, 0.5}, 0.6, 0.3, true);
    scene.AddBox(18, 4, {1, 1, 1}, 0.5, true);
    plain_id = scene.AddBox(11, 2.5, {0.6, 2.5, 1.6}, 0.0, true, "untextured wall");
    rig.model = Model(320, 240, 256.0);
    rig.baseline_m = 0.3;
    rig.image.supersampling = 2;
    rig.image.texture.plain_ids = {plain_id};
    camera = sim::Camera::AboveGround(rig.model, scene.terrain(), 0, 0, 1.5, 0.0, 8 * kDegToRad, 0);
  }
};

/// Pixels whose whole neighbourhood of `radius` sees one untextured flat face (or the sky):
/// no window there holds anything to match.
std::vector<bool> UntexturedInterior(const sim::DepthFrame& truth, int plain_id, int radius) {
  const int w = truth.width(), h = truth.height();
  std::vector<bool> interior(static_cast<std::size_t>(w) * h, false);
  const auto plain = [&](int i) {
    return truth.object_id[i] == sim::kNoHitId || truth.object_id[i] == plain_id;
  };
  for (int r = radius; r < h - radius; ++r) {
    for (int c = radius; c < w - radius; ++c) {
      const int i = r * w + c;
      if (!plain(i)) continue;
      bool same = true;
      for (int dr = -radius; dr <= radius && same; ++dr) {
        for (int dc = -radius; dc <= radius && same; ++dc) {
          const int j = (r + dr) * w + c + dc;
          same = truth.object_id[j] == truth.object_id[i] &&
                 (truth.normal[j] - truth.normal[i]).norm() < 1e-4f;
        }
      }
      interior[i] = same;
    }
  }
  return interior;
}

TEST(StereoDepth, ARenderedPairMatchesItsTrueDepthWithinTheExpectedError) {
  const RenderedScene s;
  Expected<sim::StereoFrame> frame = sim::RenderStereoPair(s.scene, s.camera, s.rig, 7);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  Expected<StereoPair> pair = PrepareStereoPair(ToIo(frame->left), ToIo(frame->right),
                                                StereoCalibration{s.rig.model, s.rig.baseline_m});
  ASSERT_TRUE(pair.ok()) << pair.error().message;
  StereoConfig config;
  config.min_depth_m = 2.0;
  Expected<StereoDepth> stereo = ComputeStereoDepth(*pair, config);
  ASSERT_TRUE(stereo.ok()) << stereo.error().message;
  ASSERT_EQ(stereo->disparity.num_disparities, 48);

  const sim::DepthFrame& truth = frame->left_truth;
  const double fb = s.rig.model.fx * s.rig.baseline_m;
  const int n = truth.size();
  const int first_col = stereo->disparity.num_disparities;  // left of it: no match possible
  int valid = 0, within_3_sigma = 0, textured = 0, textured_holes = 0;
  std::vector<double> abs_disparity_error;
  for (int i = 0; i < n; ++i) {
    const double z_true = truth.depth_m[i], z = stereo->depth_m.data[i];
    const bool is_textured = z_true > 0.0 && truth.object_id[i] != s.plain_id;
    if (is_textured && i % truth.width() >= first_col) {
      ++textured;
      if (!(z > 0.0)) ++textured_holes;
    }
    if (!(z > 0.0)) {
      EXPECT_EQ(stereo->sigma_m.data[i], 0.0f);
      EXPECT_EQ(stereo->disparity.disparity_px.data[i], 0.0f);
      continue;
    }
    // sigma_z = z^2 / (fx B) sigma_d, from the depth itself.
    EXPECT_NEAR(stereo->sigma_m.data[i], z * z / fb * config.disparity_sigma_px, 1e-5 * z);
    EXPECT_NEAR(z, fb / stereo->disparity.disparity_px.data[i], 1e-5 * z);
    if (!(z_true > 0.0)) continue;  // sky next to the horizon: counted by the next check
    ++valid;
    if (std::abs(z - z_true) <= 3.0 * stereo->sigma_m.data[i]) ++within_3_sigma;
    abs_disparity_error.push_back(std::abs(stereo->disparity.disparity_px.data[i] - fb / z_true));
  }
  ASSERT_GT(valid, n / 3);
  std::sort(abs_disparity_error.begin(), abs_disparity_error.end());
  const double sigma_d_measured = 1.4826 * abs_disparity_error[abs_disparity_error.size() / 2];
  const double fraction_3_sigma = static_cast<double>(within_3_sigma) / valid;
  const double textured_hole_fraction = static_cast<double>(textured_holes) / textured;
  std::cout << "rendered pair: " << valid << " valid pixels, " << fraction_3_sigma
            << " within 3 sigma, robust sigma_d " << sigma_d_measured << " px (assumed "
            << config.disparity_sigma_px << "), holes " << stereo->hole_fraction()
            << " of the image, " << textured_hole_fraction
            << " of the textured pixels right of column " << first_col << "\n";
  // The expected error holds: the measured disparity noise is within the assumed sigma_d,
  // and at least 95% of the valid pixels are within 3 sigma_z of the truth. Measured over
  // noise seeds 1..12 and texture seeds 1..6: sigma_d 0.163..0.167 px, 98.5..98.7% within
  // 3 sigma, 0.4..0.6% holes on textured surfaces right of the search band.
  EXPECT_LE(sigma_d_measured, config.disparity_sigma_px);
  EXPECT_GE(fraction_3_sigma, 0.95);
  EXPECT_FALSE(stereo->disparity.range_too_short()) << stereo->disparity.range_end_fraction;
  // Holes where there is texture stay few (occlusions at depth edges).
  EXPECT_LE(textured_hole_fraction, 0.02);

  // Untextured surfaces are holes, not ranges: nowhere inside the wall or the sky is there
  // a depth. Inside means farther from anything textured than the texture test reaches:
  // half a window, one pixel for the gradient, one for a pixel that mixes an edge.
  const std::vector<bool> interior =
      UntexturedInterior(truth, s.plain_id, config.block_size / 2 + 2);
  int interior_count = 0, interior_valid = 0;
  for (int i = 0; i < n; ++i) {
    if (!interior[i]) continue;
    ++interior_count;
    if (stereo->depth_m.data[i] > 0.0f) ++interior_valid;
  }
  EXPECT_GT(interior_count, n / 4);
  EXPECT_EQ(interior_valid, 0);
}

TEST(StereoDepth, UncertaintyGrowsWithTheSquareOfRange) {
  // Constant disparity fields by construction: the right image is the left (random
  // texture) shifted by `shift` px, so every match has d = shift, up to the matcher's
  // sub-pixel step of 1/16 px, and z = fx B / d.
  const int w = 160, h = 120;
  GreyImage left{w, h, std::vector<std::uint8_t>(static_cast<std::size_t>(w) * h)};
  std::uint64_t state = 12345;
  for (auto& p : left.data) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    p = static_cast<std::uint8_t>(state >> 56);
  }
  const double fb = 100.0 * 0.2;  // fx 100 px, baseline 0.2 m
  StereoConfig config;
  config.num_disparities = 32;
  std::vector<double> median_sigma;
  for (const int shift : {4, 8, 16}) {
    GreyImage right = left;
    for (int r = 0; r < h; ++r) {
      for (int c = 0; c < w; ++c) right.at(r, c) = left.at(r, std::min(w - 1, c + shift));
    }
    Expected<StereoPair> pair =
        PrepareStereoPair(left, right, StereoCalibration{Model(w, h, 100.0), 0.2});
    ASSERT_TRUE(pair.ok()) << pair.error().message;
    Expected<StereoDepth> stereo = ComputeStereoDepth(*pair, config);
    ASSERT_TRUE(stereo.ok()) << stereo.error().message;
    std::vector<double> sigma;
    for (int r = 10; r < h - 10; ++r) {
      for (int c = 40; c < w - 20; ++c) {
        const float z = stereo->depth_m.at(r, c);
        if (z <= 0.0f) continue;
        const float d = stereo->disparity.disparity_px.at(r, c);
        EXPECT_NEAR(d, shift, 1.0 / 16.0) << r << " " << c;
        EXPECT_NEAR(z, fb / d, 1e-5 * z);
        EXPECT_NEAR(stereo->sigma_m.at(r, c), z * z / fb * config.disparity_sigma_px, 1e-5 * z);
        sigma.push_back(stereo->sigma_m.at(r, c));
      }
    }
    EXPECT_GT(sigma.size(), static_cast<std::size_t>((h - 20) * (w - 60) * 9 / 10));
    std::sort(sigma.begin(), sigma.end());
    median_sigma.push_back(sigma[sigma.size() / 2]);
  }
  // Half the disparity is twice the range and four times the uncertainty.
  EXPECT_NEAR(median_sigma[0] / median_sigma[1], 4.0, 0.1);
  EXPECT_NEAR(median_sigma[1] / median_sigma[2], 4.0, 0.1);
  EXPECT_NEAR(median_sigma[1], std::pow(fb / 8.0, 2) / fb * config.disparity_sigma_px, 1e-3);
}

TEST(StereoDepth, MaxDepthTurnsFarPixelsIntoHoles) {
  const RenderedScene s;
  Expected<sim::StereoFrame> frame = sim::RenderStereoPair(s.scene, s.camera, s.rig, 3);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  Expected<StereoPair> pair = PrepareStereoPair(ToIo(frame->left), ToIo(frame->right),
                                                StereoCalibration{s.rig.model, s.rig.baseline_m});
  ASSERT_TRUE(pair.ok());
  StereoConfig config;
  config.min_depth_m = 2.0;
  Expected<StereoDepth> all = ComputeStereoDepth(*pair, config);
  config.max_depth_m = 10.0;
  Expected<StereoDepth> near = ComputeStereoDepth(*pair, config);
  ASSERT_TRUE(all.ok() && near.ok());
  int cut = 0;
  for (std::size_t i = 0; i < all->depth_m.data.size(); ++i) {
    const float z = all->depth_m.data[i];
    if (z > 10.0f) {
      ++cut;
      EXPECT_EQ(near->depth_m.data[i], 0.0f);
      EXPECT_EQ(near->disparity.hole.data[i], static_cast<std::uint8_t>(StereoHole::kOutOfRange));
    } else {
      EXPECT_EQ(near->depth_m.data[i], z);
    }
  }
  EXPECT_GT(cut, 1000);
  EXPECT_EQ(near->disparity.holes.out_of_range, all->disparity.holes.out_of_range + cut);
}

TEST(StereoDepth, RawCamerasAreRectifiedByTheOpenCvCalibration) {
  // Two raw cameras that are neither parallel nor alike (yaw, roll, different focal
  // lengths). The OpenCV calibration file describes them; after rectification the depth
  // must match the truth rendered from the rectified left camera.
  const RenderedScene s;
  const PinholeModel raw1 = Model(320, 240, 256.0);
  PinholeModel raw2 = Model(320, 240, 248.0);
  raw2.cx = 162.0;
  const sim::Camera left = sim::Camera::AboveGround(
      raw1, s.scene.terrain(), 0, 0, 1.5, 1.5 * kDegToRad, 8 * kDegToRad, 0.5 * kDegToRad);
  sim::Camera right = sim::Camera::FromAttitude(
      raw2, left.Position() + left.T_world_camera.linear() * Eigen::Vector3d(0.3, 0.01, -0.005),
      -1.0 * kDegToRad, 7.5 * kDegToRad, -0.3 * kDegToRad);
  sim::TexturedImageSpec image = s.rig.image;
  Expected<sim::GreyImage> left_raw = sim::RenderGrey(s.scene, left, image, 1);
  Expected<sim::GreyImage> right_raw = sim::RenderGrey(s.scene, right, image, 2);
  ASSERT_TRUE(left_raw.ok() && right_raw.ok());

  // OpenCV's convention: p_right = R p_left + T.
  const Eigen::Matrix3d R_w1 = left.T_world_camera.linear(), R_w2 = right.T_world_camera.linear();
  const Eigen::Matrix3d R = R_w2.transpose() * R_w1;
  const Eigen::Vector3d T = R_w2.transpose() * (left.Position() - right.Position());
  OpenCvRig rig;
  rig.width = 320;
  rig.height = 240;
  rig.M1 = (cv::Mat_<double>(3, 3) << raw1.fx, 0, raw1.cx, 0, raw1.fy, raw1.cy, 0, 0, 1);
  rig.M2 = (cv::Mat_<double>(3, 3) << raw2.fx, 0, raw2.cx, 0, raw2.fy, raw2.cy, 0, 0, 1);
  rig.D1 = cv::Mat::zeros(1, 5, CV_64F);
  rig.D2 = cv::Mat::zeros(1, 5, CV_64F);
  rig.R = cv::Mat(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rig.R.at<double>(r, c) = R(r, c);
  }
  rig.T = (cv::Mat_<double>(3, 1) << T.x(), T.y(), T.z());
  test::TempDir dir;
  WriteOpenCv(dir / "stereo.yml", rig);
  Expected<StereoCalibration> calib = LoadStereoCalibration(dir / "stereo.yml");
  ASSERT_TRUE(calib.ok()) << calib.error().message;
  EXPECT_NEAR(calib->baseline_m, T.norm(), 1e-9);

  Expected<StereoPair> pair = PrepareStereoPair(ToIo(*left_raw), ToIo(*right_raw), *calib);
  ASSERT_TRUE(pair.ok()) << pair.error().message;
  EXPECT_FALSE(pair->calibration.rectification.has_value());
  StereoConfig config;
  config.min_depth_m = 2.0;
  Expected<StereoDepth> stereo = ComputeStereoDepth(*pair, config);
  ASSERT_TRUE(stereo.ok()) << stereo.error().message;

  // The rectified left camera: the raw one turned by R1 (p_rect = R1 p_raw).
  sim::Camera rectified = left;
  rectified.model = pair->calibration.model;
  rectified.T_world_camera.linear() = R_w1 * calib->rectification->R1.transpose();
  sim::RenderOptions options;
  options.max_range_m = image.max_range_m;
  Expected<sim::DepthFrame> truth = sim::RenderDepth(s.scene, rectified, options);
  ASSERT_TRUE(truth.ok());
  int valid = 0, within = 0;
  for (int i = 0; i < truth->size(); ++i) {
    const double z = stereo->depth_m.data[i], z_true = truth->depth_m[i];
    if (!(z > 0.0) || !(z_true > 0.0)) continue;
    ++valid;
    if (std::abs(z - z_true) <= 3.0 * stereo->sigma_m.data[i]) ++within;
  }
  const double fraction = static_cast<double>(within) / valid;
  std::cout << "rectified pair: " << valid << " valid pixels, " << fraction
            << " within 3 sigma, holes " << stereo->hole_fraction() << "\n";
  // Measured: 93-94% (resampling by remap blurs a little).
  EXPECT_GT(valid, truth->size() / 3);
  EXPECT_GE(fraction, 0.90);
}

TEST(StereoPairs, SizesMustAgree) {
  const GreyImage a{32, 24, std::vector<std::uint8_t>(32 * 24, 1)};
  const GreyImage b{30, 24, std::vector<std::uint8_t>(30 * 24, 1)};
  Expected<StereoPair> mismatch =
      PrepareStereoPair(a, b, StereoCalibration{Model(32, 24, 30), 0.1}, "l.png", "r.png");
  ASSERT_FALSE(mismatch.ok());
  EXPECT_EQ(mismatch.error().message, "r.png: is 30x24 px, the left image l.png is 32x24");
  Expected<StereoPair> calib =
      PrepareStereoPair(a, a, StereoCalibration{Model(64, 48, 30), 0.1}, "l.png", "r.png");
  ASSERT_FALSE(calib.ok());
  EXPECT_EQ(calib.error().message, "l.png: is 32x24 px, the stereo calibration says 64x48");
}

TEST(GreyImages, ReadAnyFormatAndNameBrokenFiles) {
  test::TempDir dir;
  GreyImage image{3, 2, {0, 50, 100, 150, 200, 250}};
  ASSERT_TRUE(WriteGreyPng(dir / "g.png", image).ok());
  Expected<GreyImage> back = ReadGreyImage(dir / "g.png");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->data, image.data);
  Expected<GreyImage> missing = ReadGreyImage(dir / "none.png");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().message, (dir / "none.png").string() + ": no such file");
  dir.Write("text.png", "not an image");
  Expected<GreyImage> text = ReadGreyImage(dir / "text.png");
  ASSERT_FALSE(text.ok());
  EXPECT_TRUE(Contains(text.error().message, "unreadable image"));
}

// ---------------------------------------------------------------------------------------
// Real pairs

TEST(Middlebury, AloeBadPixelRatesAgainstTheTrueDisparity) {
  SKIP_WITHOUT_DATASET("stereo-aloe-middlebury");
  const std::filesystem::path dir = kDatasets / "stereo-aloe-middlebury";
  Expected<GreyImage> left = ReadGreyImage(dir / "aloeL.jpg");
  Expected<GreyImage> right = ReadGreyImage(dir / "aloeR.jpg");
  Expected<GreyImage> truth = ReadGreyImage(dir / "aloeGT.png");
  ASSERT_TRUE(left.ok() && right.ok() && truth.ok());
  // The 8-bit truth is in pixels of these 1282x1110 images (1 unit = 1 px, 0 = unknown):
  // its values run 43..211, and SGBM's disparities over the matched pixels have a median
  // ratio of 1.002 to it (ratios 0.5, 1/3, 2 or 3 give more than 99% bad pixels).
  ASSERT_EQ(truth->width, left->width);
  ASSERT_EQ(truth->height, left->height);
  StereoConfig config;  // the defaults, with the search range the truth needs
  Expected<StereoDisparity> d = ComputeDisparity(*left, *right, config, 224);
  ASSERT_TRUE(d.ok()) << d.error().message;
  EXPECT_FALSE(d->range_too_short()) << d->range_end_fraction;  // 224 px covers the scene
  long known = 0, matched = 0, bad1 = 0, bad2 = 0, bad4 = 0;
  for (std::size_t i = 0; i < truth->data.size(); ++i) {
    const int t = truth->data[i];
    if (t == 0) continue;
    ++known;
    const float v = d->disparity_px.data[i];
    if (!(v > 0.0f)) continue;
    ++matched;
    const double e = std::abs(v - t);
    bad1 += e > 1.0;
    bad2 += e > 2.0;
    bad4 += e > 4.0;
  }
  const double density = static_cast<double>(matched) / known;
  const double r1 = static_cast<double>(bad1) / matched, r2 = static_cast<double>(bad2) / matched,
               r4 = static_cast<double>(bad4) / matched;
  std::cout << "Aloe: density " << density << ", bad > 1 px " << r1 << ", > 2 px " << r2
            << ", > 4 px " << r4 << " (of the matched pixels with known truth)\n";
  // Measured with the defaults (sgbm_3way, block 5, min_texture 1.5): density 0.587, bad1
  // 0.054, bad2 0.028, bad4 0.022. Without the texture test (min_texture 0) density is 0.720
  // and bad1 0.066: the low-texture pixels it removes are mostly right on this pair, which
  // has texture nearly everywhere.
  EXPECT_GE(density, 0.56);
  EXPECT_LE(r1, 0.065);
  EXPECT_LE(r2, 0.035);
  EXPECT_LE(r4, 0.028);
}

TEST(FoundationStereoDesk, RunsEndToEndWithItsKTxt) {
  SKIP_WITHOUT_DATASET("stereo-desk-foundationstereo");
  const std::filesystem::path dir = kDatasets / "stereo-desk-foundationstereo";
  Expected<StereoCalibration> calib = LoadStereoCalibration(dir / "K.txt");
  ASSERT_TRUE(calib.ok()) << calib.error().message;
  Expected<GreyImage> left = ReadGreyImage(dir / "left.png");
  Expected<GreyImage> right = ReadGreyImage(dir / "right.png");
  ASSERT_TRUE(left.ok() && right.ok());
  Expected<StereoPair> pair = PrepareStereoPair(*left, *right, *calib);
  ASSERT_TRUE(pair.ok()) << pair.error().message;
  EXPECT_EQ(pair->calibration.model.width, 960);
  EXPECT_EQ(pair->calibration.model.height, 540);
  // With the default range (depth from 1 m) the desk, about 0.5 m away, is too near: the
  // matches pile up at the end of the range (measured: 42% of them), and that is said.
  Expected<StereoDepth> too_short = ComputeStereoDepth(*pair, StereoConfig());
  ASSERT_TRUE(too_short.ok()) << too_short.error().message;
  EXPECT_TRUE(too_short->disparity.range_too_short()) << too_short->disparity.range_end_fraction;
  StereoConfig config;
  config.min_depth_m = 0.35;  // the nearest desk edge is about 0.37 m away
  Expected<StereoDepth> stereo = ComputeStereoDepth(*pair, config);
  ASSERT_TRUE(stereo.ok()) << stereo.error().message;
  EXPECT_FALSE(stereo->disparity.range_too_short()) << stereo->disparity.range_end_fraction;
  std::vector<float> z;
  for (float v : stereo->depth_m.data) {
    if (v > 0.0f) z.push_back(v);
  }
  ASSERT_FALSE(z.empty());
  std::sort(z.begin(), z.end());
  const auto q = [&](double f) { return z[static_cast<std::size_t>(f * (z.size() - 1))]; };
  const double valid = static_cast<double>(z.size()) / stereo->depth_m.size();
  std::cout << "desk: " << valid << " valid, depth p5 " << q(0.05) << " median " << q(0.5)
            << " p95 " << q(0.95) << " m\n";
  // A desk seen from about half a metre: keyboard, mug and monitor.
  // Measured: 34% valid, p5 0.40 m, median 0.51 m, p95 0.83 m.
  EXPECT_GE(valid, 0.30);
  EXPECT_GT(q(0.05), 0.33);
  EXPECT_NEAR(q(0.5), 0.52, 0.06);
  EXPECT_LT(q(0.95), 1.2);

  // The depth goes on like any depth image (the detection itself: DetectStereoCli below).
  Expected<RangeImage> image = RangeImage::FromDepth(stereo->depth_m.data, pair->calibration.model,
                                                     Eigen::Vector3d(0.0, -1.0, 0.0));
  ASSERT_TRUE(image.ok()) << image.error().message;
  EXPECT_EQ(image->valid_count(), static_cast<int>(z.size()));

  // datasets/real/desk-rig.yaml: K.txt's camera and baseline, and the up vector its comment
  // says was measured on this depth, the plane through the keyboard.
  Expected<StereoCalibration> rig = LoadStereoCalibration(
      std::filesystem::path(CAIRN_SOURCE_DIR) / "datasets" / "real" / "desk-rig.yaml");
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_NEAR(rig->model.fx, calib->model.fx, 1e-9);
  EXPECT_NEAR(rig->model.cx, calib->model.cx, 1e-9);
  EXPECT_NEAR(rig->model.cy, calib->model.cy, 1e-9);
  EXPECT_NEAR(rig->baseline_m, calib->baseline_m, 1e-12);
  ASSERT_TRUE(rig->up.has_value());
  std::vector<Eigen::Vector3d> keyboard;
  for (int r = 330; r < 470; r += 2) {
    for (int c = 300; c < 900; c += 2) {
      if (image->valid(r * 960 + c)) keyboard.push_back(image->point(r * 960 + c));
    }
  }
  const eval::PlaneFit plane = eval::FitPlane(keyboard, 2);
  EXPECT_NEAR(plane.points, 9336, 50);
  EXPECT_LT(plane.rms_m, 0.002);
  EXPECT_NEAR(plane.height_m, 0.284, 0.003);
  EXPECT_LT(std::acos(std::min(1.0, plane.normal.dot(rig->up->normalized()))), 0.2 * M_PI / 180)
      << "keyboard normal " << plane.normal.transpose();
}

TEST(StereoPreset, TheVehicleRigFindsThePolesAndTreesOfAGalleryWorld) {
  // config/sensors/stereo-vehicle.yaml on a rendered pair of poles_and_rocks, view 0, as its
  // comment says: every pole and tree within max_depth found, no rock, at most one false
  // obstacle.
  const std::filesystem::path source(CAIRN_SOURCE_DIR);
  Expected<sim::World> world =
      sim::LoadWorld((source / "datasets" / "worlds" / "poles_and_rocks.yaml").string());
  ASSERT_TRUE(world.ok()) << world.error().message;
  Expected<DetectSettings> settings =
      LoadDetectSettings(source / "config" / "sensors" / "stereo-vehicle.yaml");
  ASSERT_TRUE(settings.ok()) << settings.error().message;
  sim::StereoRigSpec rig;
  rig.model = Model(640, 480, 520.0);
  rig.baseline_m = 0.3;
  const sim::Camera camera = sim::ViewCamera(*world, 0);
  Expected<sim::StereoFrame> frame = sim::RenderStereoPair(world->scene, camera, rig, 1);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  Expected<StereoPair> pair =
      PrepareStereoPair(ToIo(frame->left), ToIo(frame->right),
                        StereoCalibration{rig.model, rig.baseline_m, frame->left_truth.up_optical});
  ASSERT_TRUE(pair.ok()) << pair.error().message;
  Expected<StereoDepth> stereo = ComputeStereoDepth(*pair, settings->stereo);
  ASSERT_TRUE(stereo.ok()) << stereo.error().message;
  Expected<RangeImage> image =
      RangeImage::FromDepth(stereo->depth_m.data, rig.model, *pair->calibration.up);
  ASSERT_TRUE(image.ok()) << image.error().message;
  Expected<Detection> detection = Detect(*image, settings->detector);
  ASSERT_TRUE(detection.ok()) << detection.error().message;
  Expected<Classification> classification = Classify(*detection, settings->rules);
  ASSERT_TRUE(classification.ok()) << classification.error().message;
  const std::vector<std::uint8_t> classes = ClassImage(*detection, *classification);

  const sim::DepthFrame& truth = frame->left_truth;
  const double max_depth = settings->stereo.max_depth_m;
  int false_segments = 0;
  for (std::size_t s = 0; s < detection->segments.size(); ++s) {
    if (classification->verdicts[s].cls != SegmentClass::kKept) continue;
    bool on_obstacle = false;
    for (int i = 0; i < truth.size() && !on_obstacle; ++i) {
      const sim::Object* o = world->scene.Find(truth.object_id[i]);
      on_obstacle = detection->labels[i] == static_cast<int>(s) + 1 && o && o->is_obstacle;
    }
    false_segments += on_obstacle ? 0 : 1;
  }
  int obstacles_in_range = 0;
  for (const sim::Object& o : world->scene.objects()) {
    int seen = 0, kept = 0;
    for (int i = 0; i < truth.size(); ++i) {
      if (truth.object_id[i] != o.id || truth.depth_m[i] > max_depth) continue;
      ++seen;
      if (classes[i] == 1) ++kept;
    }
    if (seen == 0) continue;
    std::cout << o.name << ": " << kept << " of " << seen << " pixels kept\n";
    if (o.is_obstacle) {
      ++obstacles_in_range;
      EXPECT_GE(kept, seen / 2) << o.name;
    } else {
      EXPECT_EQ(kept, 0) << o.name;
    }
  }
  std::cout << "false segments: " << false_segments << "\n";
  EXPECT_EQ(obstacles_in_range, 4);
  EXPECT_LE(false_segments, 1);
}

#ifdef CAIRN_EXE
using RunResult = test::CommandResult;

RunResult RunCairn(const std::string& args) {
  return test::RunShell(test::ShellQuote(CAIRN_EXE) + " " + args);
}

TEST(DetectStereoCli, TheDeskPairGivesDepthAndObstacles) {
  SKIP_WITHOUT_DATASET("stereo-desk-foundationstereo");
  const std::filesystem::path data = kDatasets / "stereo-desk-foundationstereo";
  test::TempDir dir;
  dir.Write("desk.yaml", "stereo:\n  min_depth: 0.35\n");
  const RunResult run =
      RunCairn("detect --left '" + (data / "left.png").string() + "' --right '" +
               (data / "right.png").string() + "' --stereo-calib '" + (data / "K.txt").string() +
               "' --config '" + (dir / "desk.yaml").string() + "' --out '" +
               (dir / "out").string() + "' --method column");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(Contains(run.output, "holes: "));
  EXPECT_TRUE(Contains(run.output, "time: stereo "));
  EXPECT_TRUE(Contains(run.output, "up: not in the calibration, camera assumed level"));
  for (const char* name :
       {"depth.tiff", "depth_sigma.tiff", "disparity.png", "disparity_color.png", "intrinsics.yaml",
        "segments.png", "classes.png", "segments.json", "overlay.png", "segments_color.png"}) {
    EXPECT_TRUE(std::filesystem::exists(dir / "out" / name)) << name;
  }
  EXPECT_FALSE(Contains(run.output, "warning")) << run.output;

  // With the built-in range (depth from 1 m) the desk is too near, and the run says so.
  const RunResult too_short =
      RunCairn("detect --left '" + (data / "left.png").string() + "' --right '" +
               (data / "right.png").string() + "' --stereo-calib '" + (data / "K.txt").string() +
               "' --out '" + (dir / "out2").string() + "' --method column");
  ASSERT_EQ(too_short.exit_code, 0) << too_short.output;
  EXPECT_TRUE(Contains(too_short.output, "warning: ")) << too_short.output;
  EXPECT_TRUE(Contains(too_short.output, "lower stereo.min_depth")) << too_short.output;
}

TEST(DetectStereoCli, AMissingCalibrationFieldIsAClearError) {
  test::TempDir dir;
  dir.Write("rig.yaml", "width: 32\nheight: 24\nfx: 30\ncx: 15.5\ncy: 11.5\n");
  const GreyImage image{32, 24, std::vector<std::uint8_t>(32 * 24, 9)};
  ASSERT_TRUE(WriteGreyPng(dir / "l.png", image).ok());
  const RunResult run =
      RunCairn("detect --left '" + (dir / "l.png").string() + "' --right '" +
               (dir / "l.png").string() + "' --stereo-calib '" + (dir / "rig.yaml").string() +
               "' --out '" + (dir / "out").string() + "'");
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(Contains(
      run.output, "cairn detect: error: " + (dir / "rig.yaml").string() + ": baseline: missing"));
}
#endif

}  // namespace
}  // namespace cairn::od::io
