// KITTI odometry sequences: calib.txt, poses.txt and times.txt parsed to the digit (values
// from ../shared/datasets/kitti-seq00-0-10), their errors naming file, line and key, frame
// selection, detection on the scans (cars, poles and walls found, the road not), and
// `cairn detect --kitti` end to end. Cases on the shared data are skipped without it.
#include "cairn/od/io/kitti.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn_command.hpp"
#include "temp_dir.hpp"

namespace cairn {
namespace {

using od::io::KittiCalibration;
using od::io::KittiFrame;
using od::io::KittiSequence;

const std::filesystem::path kDatasets = CAIRN_SHARED_DATASETS;
const std::filesystem::path kSequence = kDatasets / "kitti-seq00-0-10";

#define SKIP_WITHOUT_SEQUENCE()                                                            \
  if (!std::filesystem::exists(kSequence)) {                                               \
    GTEST_SKIP() << kSequence.string() << " not found (see ../shared/datasets/README.md)"; \
  }

bool Contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// calib.txt of sequence 00, as shipped.
const char* const kCalib =
    "P0: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
    "P1: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.861448000000e+02 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
    "P2: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 4.538225000000e+01 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 -1.130887000000e-01 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 3.779761000000e-03\n"
    "P3: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 -3.372877000000e+02 "
    "0.000000000000e+00 7.188560000000e+02 1.852157000000e+02 2.369057000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 4.915215000000e-03\n"
    "Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 "
    "-7.210626507497e-03 8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 "
    "9.999738645903e-01 4.859485810390e-04 -7.206933692422e-03 -2.921968648686e-01\n";

void ExpectSequence00Calibration(const KittiCalibration& c) {
  const Eigen::Matrix4d Tr = c.T_cam0_velodyne.matrix();
  EXPECT_EQ(Tr(0, 0), 4.276802385584e-04);
  EXPECT_EQ(Tr(0, 1), -9.999672484946e-01);
  EXPECT_EQ(Tr(0, 3), -1.198459927713e-02);
  EXPECT_EQ(Tr(1, 3), -5.403984729748e-02);
  EXPECT_EQ(Tr(2, 0), 9.999738645903e-01);
  EXPECT_EQ(Tr(2, 3), -2.921968648686e-01);
  EXPECT_EQ(Tr.row(3), Eigen::RowVector4d(0, 0, 0, 1));
  EXPECT_EQ(c.P[0](0, 0), 7.188560000000e+02);
  EXPECT_EQ(c.P[0](1, 2), 1.852157000000e+02);
  EXPECT_EQ(c.P[1](0, 3), -3.861448000000e+02);  // -fx * baseline: 0.537 m
  EXPECT_EQ(c.P[2](1, 3), -1.130887000000e-01);
  EXPECT_EQ(c.P[3](2, 3), 4.915215000000e-03);
}

TEST(KittiCalibration, ParsesEveryMatrixToTheDigit) {
  test::TempDir dir;
  Expected<KittiCalibration> c = od::io::ReadKittiCalibration(dir.Write("calib.txt", kCalib));
  ASSERT_TRUE(c.ok()) << c.error().message;
  ExpectSequence00Calibration(*c);
}

TEST(KittiCalibration, MissingOrBadFieldsAreNamed) {
  test::TempDir dir;
  std::string text = kCalib;
  const std::size_t tr = text.find("Tr:");
  const std::size_t p2 = text.find("P2:"), p3 = text.find("P3:");
  const std::string p2_line = text.substr(p2, p3 - p2);
  std::string p2_short = p2_line;
  p2_short.erase(p2_short.rfind(' '));  // 11 numbers
  std::string p1_word = kCalib;
  p1_word.replace(p1_word.find("6.071928000000e+02"), 18, "six");
  std::string not_rotation = kCalib;
  not_rotation.replace(not_rotation.find("4.276802385584e-04"), 18, "4.276802385584e-01");
  struct Case {
    std::string name, text, expected;
  };
  const std::vector<Case> cases = {
      {"no_tr.txt", text.substr(0, tr), "key 'Tr' is missing"},
      {"no_p2.txt", text.substr(0, p2) + text.substr(p3), "key 'P2' is missing"},
      {"short_p2.txt", text.substr(0, p2) + p2_short + "\n" + text.substr(p3),
       "line 3 (P2): 11 values, expected 12"},
      {"word.txt", p1_word, "line 1 (P0): value 3 'six' is not a finite number"},
      {"rotation.txt", not_rotation, "line 5 (Tr): the 3x3 part is not a rotation"},
      {"twice.txt", text + p2_line, "line 6: key 'P2' appears twice (first on line 3)"},
      {"junk.txt", "calibration follows\n" + text, "line 1: expected 'KEY: 12 numbers'"},
  };
  for (const Case& c : cases) {
    const auto path = dir.Write(c.name, c.text);
    Expected<KittiCalibration> calib = od::io::ReadKittiCalibration(path);
    ASSERT_FALSE(calib.ok()) << c.name;
    EXPECT_TRUE(Contains(calib.error().message, path.string())) << calib.error().message;
    EXPECT_TRUE(Contains(calib.error().message, c.expected)) << calib.error().message;
  }
  Expected<KittiCalibration> missing = od::io::ReadKittiCalibration(dir / "none.txt");
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(Contains(missing.error().message, (dir / "none.txt").string() + ": no such file"))
      << missing.error().message;
}

TEST(KittiPoses, BadLinesAreNamed) {
  test::TempDir dir;
  const std::string identity = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {identity + "1 0 0 0 0 1 0 0 0 0 1\n", "line 2: 11 values, expected 12"},
      {identity + identity + "1 0 0 0 0 1 0 0 0 0 2 0\n", "line 3: the 3x3 part is not a rotation"},
      {identity + "1 0 0 x 0 1 0 0 0 0 1 0\n", "line 2: value 4 'x' is not a finite number"},
      {identity + "\n" + identity, "line 3: a pose after an empty line"},
      {"", "no poses"},
  };
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const auto path = dir.Write("poses" + std::to_string(k) + ".txt", cases[k].text);
    Expected<std::vector<Eigen::Isometry3d>> poses = od::io::ReadKittiPoses(path);
    ASSERT_FALSE(poses.ok()) << k;
    EXPECT_TRUE(Contains(poses.error().message, path.string())) << poses.error().message;
    EXPECT_TRUE(Contains(poses.error().message, cases[k].expected)) << poses.error().message;
  }
}

TEST(KittiTimes, BadLinesAreNamed) {
  test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"0.0\n0.1\n0.05\n", "line 3: stamp 0.05 is earlier than the line before"},
      {"0.0\n0.1 0.2\n", "line 2: expected one finite time stamp"},
      {"0.0\nnan\n", "line 2: expected one finite time stamp"},
      {"", "no time stamps"},
  };
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const auto path = dir.Write("times" + std::to_string(k) + ".txt", cases[k].first);
    Expected<std::vector<double>> times = od::io::ReadKittiTimes(path);
    ASSERT_FALSE(times.ok()) << k;
    EXPECT_TRUE(Contains(times.error().message, path.string())) << times.error().message;
    EXPECT_TRUE(Contains(times.error().message, cases[k].second)) << times.error().message;
  }
}

TEST(KittiSequence, OpensTheSharedSequenceWithItsPosesAndStamps) {
  SKIP_WITHOUT_SEQUENCE();
  Expected<KittiSequence> sequence = od::io::OpenKittiSequence(kSequence);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  ExpectSequence00Calibration(sequence->calibration);
  ASSERT_EQ(sequence->frames.size(), 11u);
  EXPECT_TRUE(sequence->has_poses);
  for (int k = 0; k <= 10; ++k) {
    EXPECT_EQ(sequence->frames[k].index, k);
    EXPECT_TRUE(std::filesystem::is_regular_file(sequence->frames[k].scan));
  }
  const KittiFrame& f1 = sequence->frames[1];
  EXPECT_EQ(f1.stamp_s, 1.037359e-01);  // times.txt line 2
  EXPECT_EQ(sequence->frames[10].stamp_s, 1.036910e+00);
  // poses.txt line 2, as written.
  ASSERT_TRUE(f1.T_cam0start_cam0.has_value());
  EXPECT_EQ(f1.T_cam0start_cam0->translation(),
            Eigen::Vector3d(-4.690294e-02, -2.839928e-02, 8.586941e-01));
  EXPECT_EQ(f1.T_cam0start_cam0->linear()(0, 1), 5.272628e-04);
  // The velodyne's pose: Pose * Tr, in cam0 of frame 0 (z forward).
  const Eigen::Isometry3d& Tr = sequence->calibration.T_cam0_velodyne;
  const Eigen::Vector3d expected =
      f1.T_cam0start_cam0->linear() * Tr.translation() + f1.T_cam0start_cam0->translation();
  EXPECT_LT((f1.T_cam0start_velodyne->translation() - expected).norm(), 1e-12);
  // In the z-up map frame (velodyne of frame 0): frame 0 at the origin (its pose is the
  // identity to the file's 7 digits), the car 0.86 m ahead at frame 1, level.
  EXPECT_LT((sequence->frames[0].T_map_velodyne->matrix() - Eigen::Matrix4d::Identity())
                .cwiseAbs()
                .maxCoeff(),
            1e-6);
  const Eigen::Vector3d t1 = f1.T_map_velodyne->translation();
  EXPECT_NEAR(t1.x(), 0.8588, 1e-3);
  EXPECT_NEAR(t1.y(), 0.0465, 1e-3);
  EXPECT_NEAR(t1.z(), 0.0222, 1e-3);
  EXPECT_NEAR(sequence->frames[10].T_map_velodyne->translation().x(), 8.584, 1e-3);
}

/// A sequence folder with `scans` tiny scans, `times` stamps and `poses` poses (-1: no
/// poses.txt).
std::filesystem::path FakeSequence(const test::TempDir& dir, const std::string& name, int scans,
                                   int times, int poses) {
  const std::filesystem::path folder = dir / name;
  std::filesystem::create_directories(folder / "velodyne");
  for (int k = 0; k < scans; ++k) {
    char file[32];
    std::snprintf(file, sizeof(file), "%06d.bin", k);
    od::PointCloud cloud;
    cloud.points = {{1.f, 2.f, 3.f}};
    EXPECT_TRUE(od::io::WriteKittiBin(folder / "velodyne" / file, cloud).ok());
  }
  std::ofstream(folder / "calib.txt") << kCalib;
  std::ofstream t(folder / "times.txt");
  for (int k = 0; k < times; ++k) t << 0.1 * k << "\n";
  if (poses >= 0) {
    std::ofstream p(folder / "poses.txt");
    for (int k = 0; k < poses; ++k) p << "1 0 0 0 0 1 0 0 0 0 1 " << k << "\n";
  }
  return folder;
}

TEST(KittiSequence, ShortFilesAndBadNamesAreErrors) {
  test::TempDir dir;
  Expected<KittiSequence> ok = od::io::OpenKittiSequence(FakeSequence(dir, "ok", 3, 5, -1));
  ASSERT_TRUE(ok.ok()) << ok.error().message;
  EXPECT_FALSE(ok->has_poses);  // test sequences have no poses.txt
  EXPECT_FALSE(ok->frames[2].T_map_velodyne.has_value());
  EXPECT_DOUBLE_EQ(ok->frames[2].stamp_s, 0.2);

  Expected<KittiSequence> bad = od::io::OpenKittiSequence(FakeSequence(dir, "times", 3, 2, 3));
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "times.txt: 2 stamps, but scan 2 needs line 3"))
      << bad.error().message;
  bad = od::io::OpenKittiSequence(FakeSequence(dir, "poses", 3, 3, 1));
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "poses.txt: 1 poses, but scan 2 needs line 3"))
      << bad.error().message;
  const std::filesystem::path no_calib = FakeSequence(dir, "nocalib", 1, 1, 1);
  std::filesystem::remove(no_calib / "calib.txt");
  bad = od::io::OpenKittiSequence(no_calib);
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "calib.txt: no such file")) << bad.error().message;
  const std::filesystem::path named = FakeSequence(dir, "named", 1, 1, 1);
  std::ofstream(named / "velodyne" / "first.bin") << "";
  bad = od::io::OpenKittiSequence(named);
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "first.bin: scan name is not a frame number"))
      << bad.error().message;
  bad = od::io::OpenKittiSequence(dir / "nowhere");
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "not a folder")) << bad.error().message;
}

TEST(KittiFrames, SelectsAnInclusiveRange) {
  test::TempDir dir;
  Expected<KittiSequence> sequence = od::io::OpenKittiSequence(FakeSequence(dir, "s", 11, 11, 11));
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  auto indices = [&](const std::string& range) {
    std::vector<int> out;
    Expected<std::vector<KittiFrame>> frames = od::io::SelectKittiFrames(*sequence, range);
    if (frames) {
      for (const KittiFrame& f : *frames) out.push_back(f.index);
    }
    return out;
  };
  EXPECT_EQ(indices("2:4"), (std::vector<int>{2, 3, 4}));
  EXPECT_EQ(indices("9:"), (std::vector<int>{9, 10}));
  EXPECT_EQ(indices(":1"), (std::vector<int>{0, 1}));
  EXPECT_EQ(indices("5"), (std::vector<int>{5}));
  for (const char* bad : {"4:2", "x", "1:y", "20:30", "-1:3"}) {
    Expected<std::vector<KittiFrame>> frames = od::io::SelectKittiFrames(*sequence, bad);
    ASSERT_FALSE(frames.ok()) << bad;
    EXPECT_TRUE(Contains(frames.error().message, std::string("--frames '") + bad + "'"))
        << frames.error().message;
  }
}

// --- Detection on the sequence's scans ---------------------------------------------------

/// What the detector makes of one KITTI scan, measured against the road plane as a weak
/// truth: the sensor stands 1.73 m above the road (the devkit's figure), so returns within
/// 0.15 m of z = -1.73 are road, and those more than a metre (horizontally) from any return
/// 0.3-3 m above the road are road far from every object, which no obstacle should claim
/// (road at an obstacle's foot pairs with it by the method's definition). Returns 0.5-2.5 m
/// above the road within 20 m are cars, walls, poles, trees and people.
struct KittiScore {
  std::size_t far_road = 0, far_road_kept = 0, tall = 0, tall_kept = 0;
  int cars = 0, poles = 0, walls = 0;  ///< kept segments within 20 m shaped like them
  int rings = 0;
};

KittiScore DetectKittiScan(const std::filesystem::path& scan) {
  KittiScore score;
  Expected<od::PointCloud> cloud = od::io::ReadKittiBin(scan);
  EXPECT_TRUE(cloud.ok()) << cloud.error().message;
  if (!cloud) return score;
  Expected<od::FoundLayout> layout = od::FindLayout(*cloud, {}, scan.string());
  EXPECT_TRUE(layout.ok()) << layout.error().message;
  if (!layout) return score;
  score.rings = layout->model.height();
  Expected<od::RangeImage> image = od::RangeImage::FromPoints(
      cloud->points, layout->model, Eigen::Vector3d::UnitZ(), layout->rows, layout->cols);
  Expected<od::io::DetectSettings> settings = od::io::LoadDetectSettings(
      std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "hdl-64e.yaml");
  EXPECT_TRUE(image.ok() && settings.ok());
  if (!image || !settings) return score;
  Expected<od::Detection> detection = od::Detect(*image, settings->detector);
  EXPECT_TRUE(detection.ok());
  if (!detection) return score;
  Expected<od::Classification> classes = od::Classify(*detection, settings->rules);
  Expected<std::vector<std::uint32_t>> labels = od::io::PointLabels(*image, *detection, *classes);
  EXPECT_TRUE(classes.ok() && labels.ok());
  if (!labels) return score;

  constexpr double kRoad = -1.73, kCell = 0.5;
  std::map<std::pair<int, int>, int> tall_cells;  // 0.5 m cells holding a return 0.3-3 m up
  auto cell_of = [&](double v) { return static_cast<int>(std::floor(v / kCell)); };
  for (const Eigen::Vector3f& p : cloud->points) {
    if (p.z() > kRoad + 0.3 && p.z() < kRoad + 3.0) ++tall_cells[{cell_of(p.x()), cell_of(p.y())}];
  }
  for (std::size_t i = 0; i < cloud->points.size(); ++i) {
    const Eigen::Vector3f& p = cloud->points[i];
    const bool kept = ((*labels)[i] & 0xFFFFu) == 1u;
    const double horizontal = std::hypot(p.x(), p.y());
    if (std::abs(p.z() - kRoad) < 0.15 && horizontal < 25.0) {
      bool near_object = false;
      for (int dx = -2; dx <= 2 && !near_object; ++dx) {
        for (int dy = -2; dy <= 2 && !near_object; ++dy) {
          near_object = tall_cells.count({cell_of(p.x()) + dx, cell_of(p.y()) + dy}) > 0;
        }
      }
      if (!near_object) {
        ++score.far_road;
        score.far_road_kept += kept;
      }
    }
    if (p.z() > kRoad + 0.5 && p.z() < kRoad + 2.5 && horizontal < 20.0) {
      ++score.tall;
      score.tall_kept += kept;
    }
  }
  for (const od::SegmentFeatures& s : detection->segments) {
    if (classes->verdicts[s.id - 1].cls != od::SegmentClass::kKept) continue;
    if (s.range_min_m > 20.0) continue;
    const Eigen::Vector3d size = s.bbox_max - s.bbox_min;
    const double longest = std::max(size.x(), size.y()), shortest = std::min(size.x(), size.y());
    // Footprints include the road at the foot, which pairs with the object.
    score.cars += s.height_max_m > 1.2 && s.height_max_m < 2.2 && shortest > 1.5 && longest < 6.0;
    score.poles += s.height_max_m > 1.0 && longest < 0.6;
    score.walls += s.height_max_m > 2.0 && longest > 10.0;
  }
  return score;
}

TEST(KittiDetection, FindsCarsPolesAndWallsButNotTheRoad) {
  SKIP_WITHOUT_SEQUENCE();
  for (int frame : {0, 5, 10}) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.bin", frame);
    const KittiScore s = DetectKittiScan(kSequence / "velodyne" / name);
    std::printf(
        "frame %d: %d rings; road far from objects: %zu returns, %.3f%% kept; returns "
        "0.5-2.5 m above the road within 20 m: %zu, %.1f%% kept; kept within 20 m: "
        "%d car-, %d pole-, %d wall-shaped segments\n",
        frame, s.rings, s.far_road, 100.0 * s.far_road_kept / s.far_road, s.tall,
        100.0 * s.tall_kept / s.tall, s.cars, s.poles, s.walls);
    EXPECT_EQ(s.rings, 64) << name;
    EXPECT_GT(s.far_road, 20000u) << name;
    EXPECT_LT(s.far_road_kept, s.far_road / 1000) << name;  // under 0.1%
    EXPECT_GT(s.tall_kept, s.tall * 95 / 100) << name;      // over 95%
    EXPECT_GE(s.cars, 1) << name;
    EXPECT_GE(s.walls, 1) << name;
    if (frame == 0) {
      EXPECT_GE(s.poles, 1) << name;
    }
  }
}

// --- cairn detect --kitti end to end --------------------------------------------------------

#if defined(CAIRN_EXE)

int RunCairn(const std::vector<std::string>& args, std::string* output) {
  const test::CommandResult run = test::RunProgram(CAIRN_EXE, args);
  *output += run.output;
  return run.exit_code;
}

TEST(DetectKittiCli, WritesAFolderPerFrameAndASummary) {
  SKIP_WITHOUT_SEQUENCE();
  test::TempDir dir;
  std::string output;
  const int code =
      RunCairn({"detect", "--kitti", kSequence.string(), "--frames", "3:4", "--config",
                (std::filesystem::path(CAIRN_SOURCE_DIR) / "config/sensors/hdl-64e.yaml").string(),
                "--out", (dir / "out").string()},
               &output);
  ASSERT_EQ(code, 0) << output;
  EXPECT_TRUE(Contains(output, "frame 000003 (1/2): 124167 points, 64 rings (ring breaks)"))
      << output;
  EXPECT_TRUE(Contains(output, "frame 000004 (2/2)")) << output;
  EXPECT_TRUE(Contains(output, "2 of 2 frames")) << output;
  EXPECT_EQ(dir.List(dir / "out"), (std::vector<std::string>{"000003", "000004", "summary.csv"}));
  for (const char* frame : {"000003", "000004"}) {
    EXPECT_EQ(
        dir.List(dir / "out" / frame),
        (std::vector<std::string>{"birds_eye.png", "classes.png", "labels.label", "overlay.png",
                                  "segments.json", "segments.png", "segments_color.png"}));
  }
  Expected<std::vector<std::uint32_t>> labels =
      od::io::ReadLabelFile(dir / "out" / "000003" / "labels.label");
  ASSERT_TRUE(labels.ok());
  EXPECT_EQ(labels->size(), 124167u);  // one per input point

  std::ifstream csv(dir / "out" / "summary.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(csv, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0].rfind("frame,stamp_s,points,rings,columns,ring_source,segments,kept,", 0), 0u);
  EXPECT_EQ(lines[1].rfind("3,0.311075,124167,64,", 0), 0u) << lines[1];
  // Frame 4's velodyne, 3.43 m ahead of frame 0's in the z-up map frame (Tr^-1 Pose Tr).
  EXPECT_TRUE(Contains(lines[2], ",3.4330,0.1859,0.0889,")) << lines[2];

  output.clear();
  EXPECT_EQ(RunCairn({"detect", "--kitti", kSequence.string(), "--frames", "20:30", "--out",
                      (dir / "none").string()},
                     &output),
            1);
  EXPECT_TRUE(Contains(output, "--frames '20:30': no scan")) << output;
}

#endif

}  // namespace
}  // namespace cairn
