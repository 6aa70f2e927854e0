// LiDAR point clouds: KITTI .bin reading and its errors, organised-layout detection, the
// exact projection round trip, SemanticKITTI .label layout, and `cairn detect --points` end
// to end on the RELLIS-3D frame (skipped when ../shared/datasets is not there).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"
#include "temp_dir.hpp"

namespace cairn {
namespace {

using od::io::OrganisedMode;
using od::io::PointCloud;

constexpr double kPi = 3.14159265358979323846;

bool Contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

/// An organised Ouster-order scan (index = col * rings + ring) of `model`'s rings: ranges
/// 3..40 m, directions jittered around the nominal ones by up to a fifth of a step (as real
/// beams scatter), every seventh point no return (0, 0, 0).
PointCloud OrganisedScan(const od::SphericalModel& model, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> range(3.0, 40.0), jitter(-0.2, 0.2);
  const double az_step = model.azimuth_step_rad();
  PointCloud cloud;
  for (int c = 0; c < model.width; ++c) {
    for (int r = 0; r < model.height(); ++r) {
      const std::size_t i = cloud.points.size();
      cloud.intensity.push_back(static_cast<float>(r));
      if (i % 7 == 3) {
        cloud.points.emplace_back(0.f, 0.f, 0.f);
        continue;
      }
      const double ring_step = r + 1 < model.height()
                                   ? model.ring_elevation_rad[r] - model.ring_elevation_rad[r + 1]
                                   : model.ring_elevation_rad[r - 1] - model.ring_elevation_rad[r];
      const double el = model.ring_elevation_rad[r] + jitter(rng) * ring_step;
      const double az = model.ColumnAzimuth(c) + jitter(rng) * az_step;
      const double d = range(rng);
      cloud.points.emplace_back(static_cast<float>(d * std::cos(el) * std::cos(az)),
                                static_cast<float>(d * std::cos(el) * std::sin(az)),
                                static_cast<float>(d * std::sin(el)));
    }
  }
  return cloud;
}

od::SphericalModel Os1(int width) {
  Expected<od::SphericalModel> model = od::SphericalModel::Preset("OS1-64", width);
  EXPECT_TRUE(model.ok());
  return *model;
}

TEST(KittiBin, RoundTripIsBitExact) {
  test::TempDir dir;
  PointCloud cloud;
  cloud.points = {{1.5f, -2.25f, 0.125f}, {0.f, 0.f, 0.f}, {-80.0f, 1e-7f, -3.5f}};
  cloud.intensity = {0.01f, 0.f, 0.75f};
  ASSERT_TRUE(od::io::WriteKittiBin(dir / "scan.bin", cloud).ok());
  EXPECT_EQ(std::filesystem::file_size(dir / "scan.bin"), 3u * 16u);
  Expected<PointCloud> back = od::io::ReadKittiBin(dir / "scan.bin");
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->points.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back->points[i], cloud.points[i]) << i;
    EXPECT_EQ(back->intensity[i], cloud.intensity[i]) << i;
  }
}

TEST(KittiBin, TruncatedFileErrorNamesTheFile) {
  test::TempDir dir;
  const auto path = dir.Write("cut.bin", std::string(16 * 3 + 5, '\0'));
  Expected<PointCloud> cloud = od::io::ReadKittiBin(path);
  ASSERT_FALSE(cloud.ok());
  EXPECT_TRUE(Contains(cloud.error().message, path.string())) << cloud.error().message;
  EXPECT_TRUE(Contains(cloud.error().message, "truncated")) << cloud.error().message;
}

TEST(KittiBin, MissingFileErrorNamesTheFile) {
  test::TempDir dir;
  Expected<PointCloud> cloud = od::io::ReadKittiBin(dir / "nothing.bin");
  ASSERT_FALSE(cloud.ok());
  EXPECT_TRUE(Contains(cloud.error().message, (dir / "nothing.bin").string()))
      << cloud.error().message;
}

TEST(KittiBin, NonFiniteValueErrorNamesFileAndPoint) {
  test::TempDir dir;
  PointCloud cloud;
  cloud.points = {{1.f, 2.f, 3.f}, {1.f, std::numeric_limits<float>::quiet_NaN(), 3.f}};
  ASSERT_TRUE(od::io::WriteKittiBin(dir / "nan.bin", cloud).ok());
  Expected<PointCloud> back = od::io::ReadKittiBin(dir / "nan.bin");
  ASSERT_FALSE(back.ok());
  EXPECT_TRUE(Contains(back.error().message, (dir / "nan.bin").string())) << back.error().message;
  EXPECT_TRUE(Contains(back.error().message, "point 1")) << back.error().message;
}

TEST(PointLayout, OrganisedOusterScanIsRecognised) {
  const PointCloud cloud = OrganisedScan(Os1(256), 1);
  // The preset's width is only the default for unorganised scans: columns come from the count.
  Expected<od::io::PointLayout> layout =
      od::io::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_TRUE(layout->organised);
  EXPECT_EQ(layout->model.width, 256);
  ASSERT_EQ(layout->rows.size(), cloud.points.size());
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    ASSERT_EQ(layout->rows[i], static_cast<int>(i % 64));
    ASSERT_EQ(layout->cols[i], static_cast<int>(i / 64));
  }
  // The fitted column-0 azimuth is the nominal one (0) up to the jitter.
  EXPECT_NEAR(std::remainder(layout->model.azimuth_start_rad, 2.0 * kPi), 0.0, 0.01);
}

TEST(PointLayout, ShuffledScanIsNotOrganised) {
  PointCloud cloud = OrganisedScan(Os1(256), 2);
  std::mt19937 rng(3);
  std::shuffle(cloud.points.begin(), cloud.points.end(), rng);  // count still 64 x 256
  Expected<od::io::PointLayout> layout =
      od::io::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_FALSE(layout->organised);
  EXPECT_EQ(layout->model.width, 2048);
  EXPECT_TRUE(layout->rows.empty());
  // Forced: the caller knows better.
  layout = od::io::ResolveLayout(cloud, Os1(2048), OrganisedMode::kYes, "scan");
  ASSERT_TRUE(layout.ok());
  EXPECT_TRUE(layout->organised);
}

TEST(PointLayout, ForcedOrganisedNeedsAMultipleOfTheRings) {
  PointCloud cloud = OrganisedScan(Os1(16), 4);
  cloud.points.pop_back();
  Expected<od::io::PointLayout> layout =
      od::io::ResolveLayout(cloud, Os1(2048), OrganisedMode::kYes, "scan.bin");
  ASSERT_FALSE(layout.ok());
  EXPECT_TRUE(Contains(layout.error().message, "scan.bin")) << layout.error().message;
  EXPECT_TRUE(Contains(layout.error().message, "64 rings")) << layout.error().message;
}

/// Every return is stored, bit for bit, in its own cell; no return maps to -1.
void ExpectEveryPointBack(const PointCloud& cloud, const od::RangeImage& image,
                          const std::vector<std::int32_t>& expected_cell) {
  const std::vector<std::int32_t>& cell = image.cell_of_point();
  ASSERT_EQ(cell.size(), cloud.points.size());
  std::set<std::int32_t> used;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    if (p.isZero()) {
      EXPECT_EQ(cell[i], -1) << i;
      continue;
    }
    ASSERT_GE(cell[i], 0) << i;
    if (!expected_cell.empty()) {
      EXPECT_EQ(cell[i], expected_cell[i]) << i;
    }
    EXPECT_TRUE(used.insert(cell[i]).second) << "two points in cell " << cell[i];
    EXPECT_TRUE(image.valid(cell[i]));
    EXPECT_EQ(image.x()[cell[i]], p.x()) << i;
    EXPECT_EQ(image.y()[cell[i]], p.y()) << i;
    EXPECT_EQ(image.z()[cell[i]], p.z()) << i;
  }
}

TEST(PointLayout, OrganisedProjectionGivesBackEveryPointExactly) {
  const PointCloud cloud = OrganisedScan(Os1(512), 5);
  Expected<od::io::PointLayout> layout =
      od::io::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
  ASSERT_TRUE(layout.ok() && layout->organised);
  Expected<od::RangeImage> image = od::RangeImage::FromPoints(
      cloud.points, layout->model, Eigen::Vector3d::UnitZ(), layout->rows, layout->cols);
  ASSERT_TRUE(image.ok()) << image.error().message;
  std::vector<std::int32_t> expected(cloud.points.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    expected[i] = static_cast<std::int32_t>((i % 64) * 512 + i / 64);  // row * width + col
  }
  ExpectEveryPointBack(cloud, *image, expected);
}

TEST(PointLayout, UnorganisedProjectionGivesBackEveryPointExactly) {
  // One point per cell, near the cell's nominal direction, in random order: the model alone
  // (nearest ring, azimuth step) must put each into its own cell.
  for (const char* sensor : {"HDL-64E", "VLP-16", "OS1-64"}) {
    Expected<od::SphericalModel> model = od::SphericalModel::Preset(sensor, 360);
    ASSERT_TRUE(model.ok());
    // Jitter stays under half of every ring gap, also at HDL-64E's block boundary.
    PointCloud cloud = OrganisedScan(*model, 6);
    std::mt19937 rng(7);
    std::shuffle(cloud.points.begin(), cloud.points.end(), rng);
    Expected<od::io::PointLayout> layout =
        od::io::ResolveLayout(cloud, *model, OrganisedMode::kNo, "scan");
    ASSERT_TRUE(layout.ok() && !layout->organised);
    Expected<od::RangeImage> image =
        od::RangeImage::FromPoints(cloud.points, layout->model, Eigen::Vector3d::UnitZ());
    ASSERT_TRUE(image.ok()) << image.error().message;
    SCOPED_TRACE(sensor);
    ExpectEveryPointBack(cloud, *image, {});
  }
}

TEST(PointLabels, ClassInLowBitsSegmentInHighBits) {
  // Two rings x four columns; eight points in input order, one of them no return, two in
  // one cell would be ambiguous, so each has its own.
  od::SphericalModel model;
  model.width = 4;
  model.ring_elevation_rad = {0.1, -0.1};
  PointCloud cloud;
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 2; ++r) {
      const double az = model.ColumnAzimuth(c), el = model.ring_elevation_rad[r];
      cloud.points.emplace_back(static_cast<float>(5 * std::cos(el) * std::cos(az)),
                                static_cast<float>(5 * std::cos(el) * std::sin(az)),
                                static_cast<float>(5 * std::sin(el)));
    }
  }
  cloud.points[5] = Eigen::Vector3f::Zero();
  Expected<od::RangeImage> image =
      od::RangeImage::FromPoints(cloud.points, model, Eigen::Vector3d::UnitZ());
  ASSERT_TRUE(image.ok()) << image.error().message;

  // Segment 1 (kept) on cells (0, 0) and (1, 0); segment 2 (rejected) on (0, 2) and (1, 2).
  od::Detection detection;
  detection.width = 4;
  detection.height = 2;
  detection.labels = {1, 0, 2, 0,   // row 0
                      1, 0, 2, 0};  // row 1
  detection.segments.resize(2);
  detection.segments[0].id = 1;
  detection.segments[1].id = 2;
  od::Classification classification;
  classification.verdicts = {{1, od::SegmentClass::kKept, ""},
                             {2, od::SegmentClass::kRejected, "too small"}};
  classification.kept = classification.rejected = 1;

  Expected<std::vector<std::uint32_t>> labels =
      od::io::PointLabels(*image, detection, classification);
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  // Point index = col * 2 + ring; point 5 (col 2, ring 1) is no return.
  const std::vector<std::uint32_t> expected = {
      (1u << 16) | 1u, (1u << 16) | 1u,  // col 0: segment 1, kept
      0u, 0u,                            // col 1
      (2u << 16) | 2u, 0u,               // col 2: segment 2, rejected; no return
      0u, 0u};                           // col 3
  EXPECT_EQ(*labels, expected);

  test::TempDir dir;
  ASSERT_TRUE(od::io::WriteLabelFile(dir / "labels.label", *labels).ok());
  EXPECT_EQ(std::filesystem::file_size(dir / "labels.label"), 8u * 4u);
  Expected<std::vector<std::uint32_t>> back = od::io::ReadLabelFile(dir / "labels.label");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, expected);

  const auto cut = dir.Write("cut.label", std::string(6, '\0'));
  Expected<std::vector<std::uint32_t>> bad = od::io::ReadLabelFile(cut);
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, cut.string())) << bad.error().message;
}

// --- End to end on RELLIS-3D frame 000104 -------------------------------------------------

#if defined(CAIRN_EXE) && defined(CAIRN_SOURCE_DIR)

std::string Quote(const std::string& s) {
  std::string q = "'";
  for (const char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}

/// Runs the built command; returns its exit code (-1 on a crash) and fills `output`.
int RunCairn(const std::vector<std::string>& args, std::string* output) {
  std::string command = Quote(CAIRN_EXE);
  for (const std::string& a : args) command += " " + Quote(a);
  command += " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buffer;
  while (std::fgets(buffer.data(), buffer.size(), pipe)) *output += buffer.data();
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

struct Score {
  double precision = 0, recall = 0, f1 = 0;
};

/// Per-point obstacle score of kept points against RELLIS-3D ids: tree, pole, vehicle,
/// object, building, log, person, fence, barrier are obstacles; void and bush are ignored.
Score ObstacleScore(const std::vector<std::uint32_t>& truth,
                    const std::vector<std::uint32_t>& result) {
  const std::set<std::uint32_t> obstacle = {4, 5, 8, 9, 12, 15, 17, 18, 27};
  const std::set<std::uint32_t> ignored = {0, 19};
  double tp = 0, fp = 0, fn = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const std::uint32_t id = truth[i] & 0xFFFFu;
    if (ignored.count(id)) continue;
    const bool detected = (result[i] & 0xFFFFu) == 1u;
    const bool is_obstacle = obstacle.count(id) > 0;
    tp += detected && is_obstacle;
    fp += detected && !is_obstacle;
    fn += !detected && is_obstacle;
  }
  Score s;
  s.precision = tp / (tp + fp);
  s.recall = tp / (tp + fn);
  s.f1 = 2 * tp / (2 * tp + fp + fn);
  return s;
}

TEST(DetectPointsCli, RellisFrameConeBeatsColumnBaseline) {
  const std::filesystem::path data =
      std::filesystem::path(CAIRN_SOURCE_DIR) / ".." / "shared" / "datasets" / "rellis3d-000104";
  if (!std::filesystem::exists(data)) {
    GTEST_SKIP() << "RELLIS-3D frame not found at " << data.string()
                 << " (see ../shared/datasets/README.md)";
  }
  const std::string config =
      (std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "os1-64.yaml").string();
  Expected<std::vector<std::uint32_t>> truth =
      od::io::ReadLabelFile(data / "os1_label" / "000104.label");
  ASSERT_TRUE(truth.ok()) << truth.error().message;
  ASSERT_EQ(truth->size(), 131072u);

  test::TempDir dir;
  Score score[2];
  const char* methods[2] = {"cone", "column"};
  for (int m = 0; m < 2; ++m) {
    const std::filesystem::path out = dir / methods[m];
    std::string output;
    const int code = RunCairn({"detect", "--points", (data / "os1_bin" / "000104.bin").string(),
                               "--sensor", "OS1-64", "--config", config, "--method", methods[m],
                               "--out", out.string()},
                              &output);
    ASSERT_EQ(code, 0) << output;
    EXPECT_TRUE(Contains(output, "organised")) << output;
    for (const char* name : {"labels.label", "birds_eye.png", "segments.png", "classes.png",
                             "overlay.png", "segments_color.png", "segments.json"}) {
      EXPECT_TRUE(std::filesystem::is_regular_file(out / name)) << name;
    }
    Expected<std::vector<std::uint32_t>> labels = od::io::ReadLabelFile(out / "labels.label");
    ASSERT_TRUE(labels.ok()) << labels.error().message;
    ASSERT_EQ(labels->size(), 131072u);
    score[m] = ObstacleScore(*truth, *labels);
    std::printf("%s: obstacle P %.3f R %.3f F1 %.3f\n", methods[m], score[m].precision,
                score[m].recall, score[m].f1);
  }
  EXPECT_GT(score[0].f1, 0.8);
  EXPECT_GT(score[0].f1, score[1].f1);
}

#endif

}  // namespace
}  // namespace cairn
