// LiDAR point clouds: readers (KITTI .bin, PLY, text and bzip2 text) and their errors, the
// layout of points (organised, ring after ring, elevation clusters, uniform bins; the rings
// found on the real scans of ../shared/datasets and their agreement with the recorded ring
// numbers), the exact projection round trip on every data set, SemanticKITTI .label layout,
// and `cairn detect --points` end to end on the RELLIS-3D frame. Cases on the shared data
// sets are skipped when ../shared/datasets is not there.
#include "cairn/od/io/point_cloud.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/od/units.hpp"
#include "cairn_command.hpp"
#include "temp_dir.hpp"

namespace cairn {
namespace {

using od::OrganisedMode;
using od::PointCloud;
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

// Every preset name is one Preset() knows, in any case, with its own ring count; an unknown
// name is refused with the list.
TEST(SensorPresets, EveryNameIsAModelInAnyCaseAndAnUnknownOneListsThem) {
  const std::vector<std::string>& names = od::SphericalModel::PresetNames();
  ASSERT_EQ(names.size(), 4u);
  const std::map<std::string, int> rings = {
      {"HDL-64E", 64}, {"VLP-16", 16}, {"VLP-32C", 32}, {"OS1-64", 64}};
  for (const std::string& name : names) {
    std::string lower = name;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (const std::string& given : {name, lower}) {
      Expected<od::SphericalModel> model = od::SphericalModel::Preset(given);
      ASSERT_TRUE(model) << given << ": " << model.error().message;
      EXPECT_EQ(model->height(), rings.at(name)) << given;
    }
  }
  Expected<od::SphericalModel> unknown = od::SphericalModel::Preset("HDL-32");
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message,
            "unknown sensor preset 'HDL-32' (expected HDL-64E, VLP-16, VLP-32C or OS1-64)");
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
  Expected<od::PointLayout> layout =
      od::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
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
  Expected<od::PointLayout> layout =
      od::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_FALSE(layout->organised);
  EXPECT_EQ(layout->model.width, 2048);
  EXPECT_TRUE(layout->rows.empty());
  // Forced: the caller knows better.
  layout = od::ResolveLayout(cloud, Os1(2048), OrganisedMode::kYes, "scan");
  ASSERT_TRUE(layout.ok());
  EXPECT_TRUE(layout->organised);
}

TEST(PointLayout, ForcedOrganisedNeedsAMultipleOfTheRings) {
  PointCloud cloud = OrganisedScan(Os1(16), 4);
  cloud.points.pop_back();
  Expected<od::PointLayout> layout =
      od::ResolveLayout(cloud, Os1(2048), OrganisedMode::kYes, "scan.bin");
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
  Expected<od::PointLayout> layout =
      od::ResolveLayout(cloud, Os1(2048), OrganisedMode::kAuto, "scan");
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
    Expected<od::PointLayout> layout = od::ResolveLayout(cloud, *model, OrganisedMode::kNo, "scan");
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
  const std::vector<std::uint32_t> expected = {(1u << 16) | 1u,
                                               (1u << 16) | 1u,  // col 0: segment 1, kept
                                               0u,
                                               0u,  // col 1
                                               (2u << 16) | 2u,
                                               0u,  // col 2: segment 2, rejected; no return
                                               0u,
                                               0u};  // col 3
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

// --- Readers -------------------------------------------------------------------------------

TEST(KittiBin, EmptyFileErrorNamesTheFile) {
  test::TempDir dir;
  const auto path = dir.Write("empty.bin", "");
  Expected<PointCloud> cloud = od::io::ReadKittiBin(path);
  ASSERT_FALSE(cloud.ok());
  EXPECT_TRUE(Contains(cloud.error().message, path.string())) << cloud.error().message;
  EXPECT_TRUE(Contains(cloud.error().message, "empty")) << cloud.error().message;
}

TEST(KittiBin, TruncatedFileErrorGivesTheOffsetOfTheCutPoint) {
  test::TempDir dir;
  const auto path = dir.Write("cut.bin", std::string(16 * 3 + 5, '\0'));
  Expected<PointCloud> cloud = od::io::ReadKittiBin(path);
  ASSERT_FALSE(cloud.ok());
  EXPECT_TRUE(Contains(cloud.error().message, "53 bytes")) << cloud.error().message;
  EXPECT_TRUE(Contains(cloud.error().message, "offset 48")) << cloud.error().message;
}

TEST(KittiBin, AllNanPointIsNoReturnPartialNanIsAnError) {
  test::TempDir dir;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointCloud cloud;
  cloud.points = {{1.f, 2.f, 3.f}, {nan, nan, nan}, {4.f, 5.f, 6.f}};
  cloud.intensity = {0.5f, nan, 0.25f};
  ASSERT_TRUE(od::io::WriteKittiBin(dir / "nan.bin", cloud).ok());
  Expected<PointCloud> back = od::io::ReadKittiBin(dir / "nan.bin");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->points[1], Eigen::Vector3f::Zero());
  EXPECT_EQ(back->points[2], cloud.points[2]);

  cloud.points[2].z() = std::numeric_limits<float>::infinity();
  ASSERT_TRUE(od::io::WriteKittiBin(dir / "inf.bin", cloud).ok());
  back = od::io::ReadKittiBin(dir / "inf.bin");
  ASSERT_FALSE(back.ok());
  EXPECT_TRUE(Contains(back.error().message, "point 2 (byte offset 32): z is inf"))
      << back.error().message;
}

/// A PLY with the RELLIS-3D extras' layout (x y z intensity t reflectivity ring noise range)
/// plus a face element after the vertices, binary or ascii.
std::string PlyFile(const PointCloud& cloud, bool binary) {
  std::string out = std::string("ply\nformat ") + (binary ? "binary_little_endian" : "ascii") +
                    " 1.0\ncomment made by point_cloud_test\nelement vertex " +
                    std::to_string(cloud.points.size()) +
                    "\nproperty float x\nproperty float y\nproperty float z\n"
                    "property float intensity\nproperty uint t\nproperty ushort reflectivity\n"
                    "property uchar ring\nproperty ushort noise\nproperty uint range\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    const std::uint32_t t = static_cast<std::uint32_t>(i * 781);
    const std::uint16_t reflectivity = 7, noise = 3;
    const std::uint8_t ring = static_cast<std::uint8_t>(cloud.ring[i]);
    const std::uint32_t range = static_cast<std::uint32_t>(p.norm() * 1000);
    if (binary) {
      auto put = [&](const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
      put(p.x()), put(p.y()), put(p.z()), put(cloud.intensity[i]), put(t), put(reflectivity);
      put(ring), put(noise), put(range);
    } else {
      char line[256];
      std::snprintf(line, sizeof(line), "%.9g %.9g %.9g %.9g %u %u %u %u %u\n", p.x(), p.y(), p.z(),
                    cloud.intensity[i], t, reflectivity, ring, noise, range);
      out += line;
    }
  }
  out += binary ? std::string("\x03\x00\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00", 13)
                : std::string("3 0 1 2\n");
  return out;
}

PointCloud SmallCloud() {
  PointCloud cloud;
  cloud.points = {{1.5f, -2.25f, 0.125f}, {0.f, 0.f, 0.f}, {-80.0f, 1e-7f, -3.5f}, {3.f, 4.f, 5.f}};
  cloud.intensity = {0.01f, 0.f, 0.75f, 12.f};
  cloud.ring = {0, 1, 63, 7};
  return cloud;
}

TEST(Ply, BinaryAndAsciiGiveTheSamePointsIntensitiesAndRings) {
  test::TempDir dir;
  const PointCloud cloud = SmallCloud();
  for (bool binary : {true, false}) {
    const auto path = dir.Write(binary ? "b.ply" : "a.ply", PlyFile(cloud, binary));
    Expected<PointCloud> back = od::io::ReadPly(path);
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_EQ(back->points.size(), cloud.points.size());
    for (std::size_t i = 0; i < cloud.points.size(); ++i) {
      EXPECT_EQ(back->points[i], cloud.points[i]) << i;  // %.9g round-trips a float exactly
      EXPECT_EQ(back->intensity[i], cloud.intensity[i]) << i;
    }
    EXPECT_EQ(back->ring, cloud.ring);
    Expected<PointCloud> any = od::io::ReadPointFile(path);  // chosen by content
    ASSERT_TRUE(any.ok());
    EXPECT_EQ(any->ring, cloud.ring);
  }
}

TEST(Ply, ErrorsNameTheFileAndWhere) {
  test::TempDir dir;
  const std::string good = PlyFile(SmallCloud(), true);
  struct Case {
    std::string name, text, expected;
  };
  std::string no_z = good;
  no_z.replace(no_z.find("property float z\n"), 17, "property float w\n");
  std::string big_endian = good;
  big_endian.replace(big_endian.find("binary_little_endian"), 20, "binary_big_endian");
  std::string bad_type = good;
  bad_type.replace(bad_type.find("property uint t"), 15, "property quad t");
  const std::size_t body = good.find("end_header\n") + 11;
  const std::vector<Case> cases = {
      {"noz.ply", no_z, "lacks property z"},
      {"be.ply", big_endian, "binary_big_endian' is not supported"},
      {"type.ply", bad_type, "header line 9: unknown type 'quad'"},
      {"cut.ply", good.substr(0, body + 29 + 10),
       "vertex 1 is incomplete at byte offset " + std::to_string(body + 29)},
      {"nothing.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n",
       "no vertices"},
      {"notply.ply", "plx\n", "not a PLY file"},
      {"ascii.ply",
       "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
       "property float z\nend_header\n1 2 3\n4 five 6\n",
       "line 9: 'five' is not a number (y)"},
      {"empty.ply", "", "empty"},
  };
  for (const Case& c : cases) {
    const auto path = dir.Write(c.name, c.text);
    Expected<PointCloud> cloud = od::io::ReadPly(path);
    ASSERT_FALSE(cloud.ok()) << c.name;
    EXPECT_TRUE(Contains(cloud.error().message, path.string())) << cloud.error().message;
    EXPECT_TRUE(Contains(cloud.error().message, c.expected)) << cloud.error().message;
  }
}

TEST(XyzText, ReadsThreeOrFourNumbersPerLineAndNamesBadLines) {
  test::TempDir dir;
  const auto path = dir.Write("scan.xyz",
                              "# x y z [intensity]\n1.5 -2.25 0.125\n\n-80,1e-7,-3.5,0.75\n"
                              "nan nan nan\n+3 4 5 12\n");
  Expected<PointCloud> cloud = od::io::ReadPointFile(path);
  ASSERT_TRUE(cloud.ok()) << cloud.error().message;
  ASSERT_EQ(cloud->points.size(), 4u);
  EXPECT_EQ(cloud->points[0], Eigen::Vector3f(1.5f, -2.25f, 0.125f));
  EXPECT_EQ(cloud->points[1], Eigen::Vector3f(-80.0f, 1e-7f, -3.5f));
  EXPECT_EQ(cloud->intensity[1], 0.75f);
  EXPECT_EQ(cloud->points[2], Eigen::Vector3f::Zero());  // NaN in all three: no return
  EXPECT_EQ(cloud->points[3], Eigen::Vector3f(3.f, 4.f, 5.f));
  EXPECT_TRUE(cloud->ring.empty());

  const std::vector<std::pair<std::string, std::string>> bad = {
      {"1 2 3\n1 2\n", "line 2: 2 values, expected 3 or 4"},
      {"1 2 3\n1 2 x\n", "line 2: 'x' is not a number"},
      {"1 2 3 4 5\n", "line 1: 5 values"},
      {"1 nan 3\n", "line 1: y is nan"},
      {"# only a comment\n", "no points"},
      {"", "empty"},
  };
  for (std::size_t k = 0; k < bad.size(); ++k) {
    const auto file = dir.Write("bad" + std::to_string(k) + ".txt", bad[k].first);
    Expected<PointCloud> c = od::io::ReadXyzText(file);
    ASSERT_FALSE(c.ok()) << k;
    EXPECT_TRUE(Contains(c.error().message, file.string())) << c.error().message;
    EXPECT_TRUE(Contains(c.error().message, bad[k].second)) << c.error().message;
  }
  Expected<PointCloud> unknown = od::io::ReadPointFile(dir.Write("scan.las", "x"));
  ASSERT_FALSE(unknown.ok());
  EXPECT_TRUE(Contains(unknown.error().message, "unknown point file type"))
      << unknown.error().message;
}

const std::filesystem::path kDatasets = CAIRN_SHARED_DATASETS;

#define SKIP_WITHOUT_DATASET(folder)                                 \
  if (!std::filesystem::exists(kDatasets / folder)) {                \
    GTEST_SKIP() << (kDatasets / folder).string()                    \
                 << " not found (see ../shared/datasets/README.md)"; \
  }

TEST(XyzText, ReadsOctomapsBzip2ScanAndRejectsBrokenStreams) {
  SKIP_WITHOUT_DATASET("octomap-fr079");
  const std::filesystem::path scan = kDatasets / "octomap-fr079" / "scan.dat.bz2";
  Expected<PointCloud> cloud = od::io::ReadPointFile(scan);
  ASSERT_TRUE(cloud.ok()) << cloud.error().message;
  ASSERT_EQ(cloud->points.size(), 88206u);  // `bzcat scan.dat.bz2 | wc -l`
  EXPECT_EQ(cloud->points.front(), Eigen::Vector3f(-0.0434742f, -4.82982f, 0.499645f));
  EXPECT_EQ(cloud->points.back(), Eigen::Vector3f(0.130896f, 3.58f, 0.432014f));

  std::ifstream in(scan, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  test::TempDir dir;
  const auto cut = dir.Write("cut.dat.bz2", bytes.substr(0, bytes.size() / 2));
  Expected<PointCloud> c = od::io::ReadPointFile(cut);
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(Contains(c.error().message, cut.string() + ": bzip2 stream is truncated"))
      << c.error().message;
  std::string flipped = bytes;
  for (std::size_t k = 1000; k < 1100; ++k) flipped[k] = static_cast<char>(~flipped[k]);
  const auto corrupt = dir.Write("corrupt.dat.bz2", flipped);
  c = od::io::ReadPointFile(corrupt);
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(Contains(c.error().message, "corrupt bzip2 data")) << c.error().message;
  const auto plain = dir.Write("plain.xyz.bz2", "1 2 3\n");
  c = od::io::ReadPointFile(plain);
  ASSERT_FALSE(c.ok());
  EXPECT_TRUE(Contains(c.error().message, "not a bzip2 stream at byte offset 0"))
      << c.error().message;
}

// --- Rings found in the data ---------------------------------------------------------------

/// A KITTI-like scan stored ring after ring: `rings` beams from +2 deg down every 0.4 deg,
/// each with a vertical offset of up to +-0.2 m from the origin, so that the elevation seen
/// from the origin scatters over more than the ring spacing up close (as the HDL-64E's
/// does); every ring starts at the seam azimuth and sweeps counter-clockwise in steps of
/// 2 pi / columns with jitter, a tenth of the returns missing (dropped, as KITTI does) and
/// one return in a hundred a step backwards. `truth` gets each point's ring.
PointCloud RingAfterRingScan(int rings, int columns, double seam, std::uint32_t seed,
                             std::vector<std::int32_t>* truth) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double step = 2.0 * kPi / columns, deg = kPi / 180.0;
  PointCloud cloud;
  truth->clear();
  for (int r = 0; r < rings; ++r) {
    const double elevation = (2.0 - 0.4 * r) * deg;
    const double offset = 0.4 * (u01(rng) - 0.5);  // [m], along z
    for (int c = 0; c < columns; ++c) {
      if (u01(rng) < 0.1) continue;
      double az = seam + (c + 0.5 + 0.2 * (u01(rng) - 0.5)) * step;
      if (u01(rng) < 0.01) az -= 1.5 * step;
      const double d = 3.0 + 40.0 * u01(rng);
      cloud.points.emplace_back(static_cast<float>(d * std::cos(elevation) * std::cos(az)),
                                static_cast<float>(d * std::cos(elevation) * std::sin(az)),
                                static_cast<float>(d * std::sin(elevation) + offset));
      cloud.intensity.push_back(0.f);
      truth->push_back(r);
    }
  }
  return cloud;
}

/// Share of the returns whose row equals `truth`.
double Agreement(const std::vector<std::int32_t>& rows, const std::vector<std::int32_t>& truth,
                 const PointCloud& cloud) {
  std::size_t same = 0, returns = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (cloud.points[i].isZero()) continue;
    ++returns;
    same += rows[i] == truth[i];
  }
  return static_cast<double>(same) / static_cast<double>(returns);
}

/// Share of the returns grouped as `truth` groups them, whatever the numbering: each true
/// ring is mapped to the row most of its returns have (rows may be renumbered by their
/// elevation), two rings to one row counting once.
double PartitionAgreement(const std::vector<std::int32_t>& rows,
                          const std::vector<std::int32_t>& truth, const PointCloud& cloud) {
  std::map<std::int32_t, std::map<std::int32_t, std::size_t>> votes;
  std::size_t returns = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (cloud.points[i].isZero()) continue;
    ++returns;
    ++votes[truth[i]][rows[i]];
  }
  std::set<std::int32_t> used;
  std::size_t same = 0;
  for (const auto& [ring, row_counts] : votes) {
    const auto best =
        std::max_element(row_counts.begin(), row_counts.end(),
                         [](const auto& a, const auto& b) { return a.second < b.second; });
    if (used.insert(best->first).second) same += best->second;
  }
  return static_cast<double>(same) / static_cast<double>(returns);
}

TEST(RingFinding, RingAfterRingScanIsCutAtItsSeam) {
  for (const double seam : {0.0, 2.5, -1.0}) {
    std::vector<std::int32_t> truth;
    const PointCloud cloud = RingAfterRingScan(64, 1000, seam, 11, &truth);
    Expected<od::RingBreaks> breaks = od::FindRingBreaks(cloud.points);
    ASSERT_TRUE(breaks.ok()) << breaks.error().message;
    EXPECT_EQ(breaks->rings, 64);
    EXPECT_NEAR(std::remainder(breaks->seam_rad - seam, 2.0 * kPi), 0.0, 0.01);
    EXPECT_EQ(breaks->ring, truth);
    Expected<od::FoundLayout> layout = od::FindLayout(cloud, {}, "scan");
    ASSERT_TRUE(layout.ok()) << layout.error().message;
    EXPECT_EQ(layout->source, od::RingSource::kRingBreaks);
    ASSERT_EQ(layout->model.height(), 64);
    // The rings, renumbered by their median elevation (the offsets reorder a few).
    EXPECT_EQ(PartitionAgreement(layout->rows, truth, cloud), 1.0);
    EXPECT_NEAR(layout->model.width, 1000, 20);  // measured azimuth step
  }
}

// Mirrored (y -> -y), the same rings sweep the other way: the sweep's direction is the sign
// of the median azimuth step, taken either way; no step at all is no sweep.
TEST(RingFinding, AScanSweptTheOtherWayIsCutToo) {
  for (const double seam : {0.0, 2.5}) {
    std::vector<std::int32_t> truth;
    PointCloud cloud = RingAfterRingScan(64, 1000, seam, 11, &truth);
    for (Eigen::Vector3f& p : cloud.points) p.y() = -p.y();
    Expected<od::RingBreaks> breaks = od::FindRingBreaks(cloud.points);
    ASSERT_TRUE(breaks.ok()) << breaks.error().message;
    EXPECT_EQ(breaks->rings, 64);
    EXPECT_NEAR(std::remainder(breaks->seam_rad + seam, 2.0 * kPi), 0.0, 0.01);
    EXPECT_EQ(breaks->ring, truth);
  }
  PointCloud line;
  for (int i = 0; i < 100; ++i) line.points.emplace_back(1.0f + 0.01f * i, 0.0f, 0.1f * (i % 7));
  Expected<od::RingBreaks> none = od::FindRingBreaks(line.points);
  ASSERT_FALSE(none.ok());
  EXPECT_TRUE(Contains(none.error().message, "does not sweep")) << none.error().message;
}

TEST(RingFinding, ShuffledScatteredRingsFallBackToUniformBins) {
  std::vector<std::int32_t> truth;
  PointCloud cloud = RingAfterRingScan(64, 500, 0.3, 12, &truth);
  std::mt19937 rng(13);
  std::shuffle(cloud.points.begin(), cloud.points.end(), rng);
  EXPECT_FALSE(od::FindRingBreaks(cloud.points).ok());
  Expected<od::FoundLayout> layout = od::FindLayout(cloud, {}, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(layout->source, od::RingSource::kUniformBins);
  EXPECT_TRUE(Contains(layout->note, "do not split into separate rings")) << layout->note;
}

TEST(RingFinding, OrganisedScanInFiringOrderFindsItsRingCountAndSortsTheRings) {
  // VLP-32C lasers fire interleaved, not top first: index = col * 32 + laser.
  const od::SphericalModel vlp = *od::SphericalModel::Preset("VLP-32C", 360);
  std::vector<int> laser_ring(32);
  for (int l = 0; l < 32; ++l) laser_ring[l] = (l * 7) % 32;  // a permutation (7 is odd)
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> range(2.0, 50.0);
  PointCloud cloud;
  std::vector<std::int32_t> truth;
  for (int c = 0; c < vlp.width; ++c) {
    for (int l = 0; l < 32; ++l) {
      const int r = laser_ring[l];
      const double el = vlp.ring_elevation_rad[r], az = vlp.ColumnAzimuth(c), d = range(rng);
      cloud.points.emplace_back(static_cast<float>(d * std::cos(el) * std::cos(az)),
                                static_cast<float>(d * std::cos(el) * std::sin(az)),
                                static_cast<float>(d * std::sin(el)));
      truth.push_back(r);
    }
  }
  Expected<od::FoundLayout> layout = od::FindLayout(cloud, {}, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(layout->source, od::RingSource::kOrganised);
  ASSERT_EQ(layout->model.height(), 32);
  EXPECT_EQ(layout->model.width, 360);
  EXPECT_EQ(Agreement(layout->rows, truth, cloud), 1.0);
  for (int r = 0; r < 32; ++r) {
    EXPECT_NEAR(layout->model.ring_elevation_rad[r], vlp.ring_elevation_rad[r], 1e-6) << r;
  }
}

TEST(RingFinding, PresetThatDisagreesWithTheDataFallsBackToItsNominalRings) {
  std::vector<std::int32_t> truth;
  const PointCloud cloud = RingAfterRingScan(64, 400, 0.0, 15, &truth);
  od::LayoutOptions options;
  options.preset = *od::SphericalModel::Preset("VLP-16");
  Expected<od::FoundLayout> layout = od::FindLayout(cloud, options, "scan");
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  EXPECT_EQ(layout->source, od::RingSource::kNominal);
  EXPECT_EQ(layout->model.height(), 16);
  EXPECT_EQ(layout->model.width, 1800);  // the VLP-16's own
  EXPECT_TRUE(Contains(layout->note, "ring breaks give 64 rings, the preset has 16"))
      << layout->note;
}

/// Projects `cloud` with `layout` and checks the round trip: every return has the cell of
/// its row and column; each cell stores, bit for bit, the nearest point mapped to it (the
/// first of equals); no return has no cell. Returns the share of the returns stored.
double ExpectExactProjection(const PointCloud& cloud, const od::FoundLayout& layout) {
  Expected<od::RangeImage> image = od::RangeImage::FromPoints(
      cloud.points, layout.model, Eigen::Vector3d::UnitZ(), layout.rows, layout.cols);
  EXPECT_TRUE(image.ok()) << image.error().message;
  if (!image) return 0.0;
  const int width = image->width();
  const std::vector<std::int32_t>& cell = image->cell_of_point();
  EXPECT_EQ(cell.size(), cloud.points.size());
  std::vector<int> nearest(static_cast<std::size_t>(image->size()), -1);
  std::vector<float> best(static_cast<std::size_t>(image->size()),
                          std::numeric_limits<float>::infinity());
  std::size_t returns = 0;
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    if (p.isZero()) {
      EXPECT_EQ(cell[i], -1) << i;
      continue;
    }
    ++returns;
    EXPECT_EQ(cell[i], layout.rows[i] * width + layout.cols[i]) << i;
    if (cell[i] < 0) return 0.0;
    if (p.norm() < best[cell[i]]) {
      best[cell[i]] = p.norm();
      nearest[cell[i]] = static_cast<int>(i);
    }
  }
  std::size_t stored = 0, wrong = 0;
  for (int c = 0; c < image->size(); ++c) {
    if (nearest[c] < 0) {
      EXPECT_FALSE(image->valid(c)) << c;
      continue;
    }
    ++stored;
    const float in[3] = {cloud.points[nearest[c]].x(), cloud.points[nearest[c]].y(),
                         cloud.points[nearest[c]].z()};
    const float out[3] = {image->x()[c], image->y()[c], image->z()[c]};
    wrong += !image->valid(c) || std::memcmp(in, out, sizeof(in)) != 0;
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_EQ(static_cast<std::size_t>(image->valid_count()), stored);
  return static_cast<double>(stored) / static_cast<double>(returns);
}

TEST(Projection, SyntheticScansComeBackExactly) {
  std::vector<std::int32_t> truth;
  const PointCloud ring_after_ring = RingAfterRingScan(64, 1000, 1.0, 16, &truth);
  Expected<od::FoundLayout> layout = od::FindLayout(ring_after_ring, {}, "scan");
  ASSERT_TRUE(layout.ok());
  EXPECT_GT(ExpectExactProjection(ring_after_ring, *layout), 0.9);
  const PointCloud organised = OrganisedScan(Os1(512), 17);
  layout = od::FindLayout(organised, {}, "scan");
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(layout->source, od::RingSource::kOrganised);
  EXPECT_EQ(ExpectExactProjection(organised, *layout), 1.0);  // one point per cell
}

struct RealScan {
  const char* name;
  std::filesystem::path path;
  od::RingSource source;
  int rings;
};

std::vector<RealScan> RealScans() {
  return {
      {"KITTI HDL-64E 000000", kDatasets / "kitti-seq00-0-10/velodyne/000000.bin",
       od::RingSource::kRingBreaks, 64},
      {"RELLIS OS1-64 .bin", kDatasets / "rellis3d-000104/os1_bin/000104.bin",
       od::RingSource::kOrganised, 64},
      {"RELLIS OS1-64 .ply", kDatasets / "rellis3d-000104/extras/frame000104-1581624663_170.ply",
       od::RingSource::kRingField, 64},
      {"RELLIS VLP-32C", kDatasets / "rellis3d-000104/extras/vel000104.bin",
       od::RingSource::kElevationClusters, 32},
      {"OctoMap fr079 tilting laser", kDatasets / "octomap-fr079/scan.dat.bz2",
       od::RingSource::kUniformBins, 0}};
}

TEST(RingFinding, RealScansHaveTheirSensorsRings) {
  for (const RealScan& scan : RealScans()) {
    if (!std::filesystem::exists(scan.path)) GTEST_SKIP() << scan.path << " not found";
    Expected<PointCloud> cloud = od::io::ReadPointFile(scan.path);
    ASSERT_TRUE(cloud.ok()) << cloud.error().message;
    Expected<od::FoundLayout> layout = od::FindLayout(*cloud, {}, scan.path.string());
    ASSERT_TRUE(layout.ok()) << layout.error().message;
    EXPECT_EQ(layout->source, scan.source) << scan.name;
    if (scan.rings > 0) {
      EXPECT_EQ(layout->model.height(), scan.rings) << scan.name;
    }
    const double stored = ExpectExactProjection(*cloud, *layout);
    std::printf("%s: %d rings (%s) x %d columns, %.1f%% of the returns stored\n", scan.name,
                layout->model.height(), od::RingSourceName(layout->source), layout->model.width,
                100.0 * stored);
    EXPECT_GT(stored, scan.rings > 0 ? 0.9 : 0.2) << scan.name;
  }
}

TEST(RingFinding, KittiSequenceHas64RingsInEveryScan) {
  SKIP_WITHOUT_DATASET("kitti-seq00-0-10");
  for (int frame = 0; frame <= 10; ++frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.bin", frame);
    Expected<PointCloud> cloud =
        od::io::ReadKittiBin(kDatasets / "kitti-seq00-0-10/velodyne" / name);
    ASSERT_TRUE(cloud.ok()) << cloud.error().message;
    Expected<od::RingBreaks> breaks = od::FindRingBreaks(cloud->points);
    ASSERT_TRUE(breaks.ok()) << breaks.error().message;
    EXPECT_EQ(breaks->rings, 64) << name;
    // KITTI starts every ring straight ahead (+x).
    EXPECT_NEAR(breaks->seam_rad, 0.0, 0.01) << name;
    // Stored top first: the rows are the rings in storage order.
    Expected<od::FoundLayout> layout = od::FindLayout(*cloud, {}, name);
    ASSERT_TRUE(layout.ok());
    EXPECT_EQ(Agreement(layout->rows, breaks->ring, *cloud), 1.0) << name;
    // Measured from the origin, the beams' vertical offsets shift the elevations by up to a
    // degree from the data sheet's +2 and -24.8 deg.
    EXPECT_NEAR(layout->model.ring_elevation_rad.front() * 180 / kPi, 2.0, 1.0) << name;
    EXPECT_NEAR(layout->model.ring_elevation_rad.back() * 180 / kPi, -24.8, 1.5) << name;
  }
}

TEST(RingFinding, RellisOs1RingsAgreeWithTheRecordedRingField) {
  SKIP_WITHOUT_DATASET("rellis3d-000104");
  Expected<PointCloud> ply =
      od::io::ReadPly(kDatasets / "rellis3d-000104/extras/frame000104-1581624663_170.ply");
  Expected<PointCloud> bin = od::io::ReadKittiBin(kDatasets / "rellis3d-000104/os1_bin/000104.bin");
  ASSERT_TRUE(ply.ok() && bin.ok());
  ASSERT_EQ(ply->points.size(), bin->points.size());
  for (std::size_t i = 0; i < bin->points.size(); ++i) {
    ASSERT_EQ(ply->points[i], bin->points[i]) << i;  // the same scan
  }
  // Organised order, without a preset.
  Expected<od::FoundLayout> organised = od::FindLayout(*bin, {}, "os1");
  ASSERT_TRUE(organised.ok());
  ASSERT_EQ(organised->source, od::RingSource::kOrganised);
  const double organised_agreement = Agreement(organised->rows, ply->ring, *bin);
  // Elevations alone: the order ignored.
  od::LayoutOptions no_order;
  no_order.organised = od::OrganisedMode::kNo;
  Expected<od::FoundLayout> clusters = od::FindLayout(*bin, no_order, "os1");
  ASSERT_TRUE(clusters.ok());
  ASSERT_EQ(clusters->source, od::RingSource::kElevationClusters);
  ASSERT_EQ(clusters->model.height(), 64);
  const double cluster_agreement = Agreement(clusters->rows, ply->ring, *bin);
  std::printf(
      "OS1-64 rows against the PLY ring field: organised %.4f%%, elevation clusters "
      "%.4f%%\n",
      100 * organised_agreement, 100 * cluster_agreement);
  EXPECT_EQ(organised_agreement, 1.0);
  EXPECT_EQ(cluster_agreement, 1.0);
  // The measured elevations: +17.02 deg at the top, -16.44 at the bottom (not the nominal
  // +-16.6), 0.44 to 0.62 deg apart.
  EXPECT_NEAR(organised->model.ring_elevation_rad.front() * 180 / kPi, 17.024, 0.001);
  EXPECT_NEAR(organised->model.ring_elevation_rad.back() * 180 / kPi, -16.439, 0.001);
  for (int r = 0; r < 64; ++r) {
    EXPECT_NEAR(organised->model.ring_elevation_rad[r], clusters->model.ring_elevation_rad[r],
                1e-6);
  }
}

TEST(RingFinding, RellisVlp32cRingsAreItsDataSheetElevations) {
  SKIP_WITHOUT_DATASET("rellis3d-000104");
  Expected<PointCloud> cloud =
      od::io::ReadKittiBin(kDatasets / "rellis3d-000104/extras/vel000104.bin");
  ASSERT_TRUE(cloud.ok());
  Expected<od::FoundLayout> layout = od::FindLayout(*cloud, {}, "vlp");
  ASSERT_TRUE(layout.ok());
  ASSERT_EQ(layout->source, od::RingSource::kElevationClusters);
  ASSERT_EQ(layout->model.height(), 32);
  EXPECT_EQ(layout->model.width, 1800);  // 0.2 deg between firings, measured
  const od::SphericalModel sheet = *od::SphericalModel::Preset("VLP-32C");
  double worst = 0.0;
  for (int r = 0; r < 32; ++r) {
    worst = std::max(worst,
                     std::abs(layout->model.ring_elevation_rad[r] - sheet.ring_elevation_rad[r]));
  }
  std::vector<std::int32_t> nominal(cloud->points.size());
  for (std::size_t i = 0; i < nominal.size(); ++i) {
    nominal[i] = sheet.NearestRing(cloud->points[i].cast<double>());
  }
  const double agreement = Agreement(layout->rows, nominal, *cloud);
  std::printf(
      "VLP-32C: measured ring elevations within %.4f deg of the data sheet; rows agree "
      "with the nearest data-sheet ring for %.4f%% of the points\n",
      worst * 180 / kPi, 100 * agreement);
  EXPECT_LT(worst * 180 / kPi, 0.01);
  EXPECT_EQ(agreement, 1.0);
}

// --- End to end on RELLIS-3D frame 000104 -------------------------------------------------

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

// --- The VLP-32C scan of RELLIS-3D frame 000104, scored ------------------------------------

/// The Ouster's labels carried over to the Velodyne's points: each VLP-32C point, moved into
/// the Ouster's frame by extras/vel2os1.yaml (quaternion w, x, y, z and translation), takes
/// the label of the nearest Ouster return within 0.25 m; 0xFFFF where there is none.
std::vector<std::uint32_t> TransferredLabels(const PointCloud& vlp) {
  const std::filesystem::path rellis = kDatasets / "rellis3d-000104";
  std::ifstream yaml(rellis / "extras" / "vel2os1.yaml");
  std::vector<double> v;  // w x y z (q), then x y z (t), in the file's order
  for (std::string line; std::getline(yaml, line);) {
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos || colon + 1 >= line.size()) continue;
    const std::string value = line.substr(colon + 1);
    if (value.find_first_not_of(' ') == std::string::npos) continue;
    v.push_back(std::stod(value));
  }
  EXPECT_EQ(v.size(), 7u);
  if (v.size() != 7) return {};
  const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
  const Eigen::Matrix3f R = q.normalized().toRotationMatrix().cast<float>();
  const Eigen::Vector3f t(static_cast<float>(v[4]), static_cast<float>(v[5]),
                          static_cast<float>(v[6]));

  Expected<PointCloud> os1 = od::io::ReadKittiBin(rellis / "os1_bin" / "000104.bin");
  Expected<std::vector<std::uint32_t>> truth =
      od::io::ReadLabelFile(rellis / "os1_label" / "000104.label");
  EXPECT_TRUE(os1.ok() && truth.ok());
  if (!os1 || !truth) return {};
  constexpr float kCell = 0.3f, kReach = 0.25f;
  auto key = [&](const Eigen::Vector3f& p) {
    return std::array<int, 3>{static_cast<int>(std::floor(p.x() / kCell)),
                              static_cast<int>(std::floor(p.y() / kCell)),
                              static_cast<int>(std::floor(p.z() / kCell))};
  };
  std::map<std::array<int, 3>, std::vector<std::size_t>> grid;
  for (std::size_t i = 0; i < os1->points.size(); ++i) {
    if (!os1->points[i].isZero()) grid[key(os1->points[i])].push_back(i);
  }
  std::vector<std::uint32_t> labels(vlp.points.size(), 0xFFFFu);
  for (std::size_t i = 0; i < vlp.points.size(); ++i) {
    const Eigen::Vector3f p = R * vlp.points[i] + t;
    const std::array<int, 3> k = key(p);
    float best = kReach;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const auto cell = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (cell == grid.end()) continue;
          for (std::size_t j : cell->second) {
            const float d = (os1->points[j] - p).norm();
            if (d < best) {
              best = d;
              labels[i] = (*truth)[j] & 0xFFFFu;
            }
          }
        }
      }
    }
  }
  return labels;
}

TEST(DetectVlp32c, ConeDetectorBeatsTheColumnBaselineOnTheOustersLabels) {
  SKIP_WITHOUT_DATASET("rellis3d-000104");
  Expected<PointCloud> vlp =
      od::io::ReadKittiBin(kDatasets / "rellis3d-000104" / "extras" / "vel000104.bin");
  ASSERT_TRUE(vlp.ok());
  const std::vector<std::uint32_t> truth = TransferredLabels(*vlp);
  ASSERT_EQ(truth.size(), vlp->points.size());
  const std::size_t labelled = static_cast<std::size_t>(
      std::count_if(truth.begin(), truth.end(), [](std::uint32_t l) { return l != 0xFFFFu; }));
  EXPECT_EQ(labelled, 21545u);

  Expected<od::FoundLayout> layout = od::FindLayout(*vlp, {}, "vel000104.bin");
  ASSERT_TRUE(layout.ok());
  Expected<od::RangeImage> image = od::RangeImage::FromPoints(
      vlp->points, layout->model, Eigen::Vector3d::UnitZ(), layout->rows, layout->cols);
  Expected<od::io::DetectSettings> settings = od::io::LoadDetectSettings(
      std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "vlp-32c.yaml");
  ASSERT_TRUE(image.ok() && settings.ok());
  od::ColumnConfig column = od::ColumnConfig::From(settings->detector);
  column.min_blob_pixels = settings->min_blob_pixels;
  Expected<od::Detection> detections[2] = {od::Detect(*image, settings->detector),
                                           od::DetectColumns(*image, column)};
  Score score[2];
  for (int m = 0; m < 2; ++m) {
    ASSERT_TRUE(detections[m].ok());
    Expected<od::Classification> classes = od::Classify(*detections[m], settings->rules);
    ASSERT_TRUE(classes.ok());
    Expected<std::vector<std::uint32_t>> labels =
        od::io::PointLabels(*image, *detections[m], *classes);
    ASSERT_TRUE(labels.ok());
    std::vector<std::uint32_t> known_truth, known_labels;  // points with a carried label
    for (std::size_t i = 0; i < truth.size(); ++i) {
      if (truth[i] == 0xFFFFu) continue;
      known_truth.push_back(truth[i]);
      known_labels.push_back((*labels)[i]);
    }
    score[m] = ObstacleScore(known_truth, known_labels);
    std::printf("VLP-32C %s: obstacle P %.3f R %.3f F1 %.3f\n", m == 0 ? "cone" : "column",
                score[m].precision, score[m].recall, score[m].f1);
  }
  // config/sensors/vlp-32c.yaml quotes these.
  EXPECT_NEAR(score[0].f1, 0.855, 0.005);
  EXPECT_NEAR(score[0].recall, 0.961, 0.005);
  EXPECT_NEAR(score[1].f1, 0.766, 0.005);
  EXPECT_GT(score[0].f1, score[1].f1);
}

#if defined(CAIRN_EXE) && defined(CAIRN_SOURCE_DIR)

int RunCairn(const std::vector<std::string>& args, std::string* output) {
  const test::CommandResult run = test::RunProgram(CAIRN_EXE, args);
  *output += run.output;
  return run.exit_code;
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
    const int code =
        // The preset in either case, as config/sensors/os1-64.yaml spells it.
        RunCairn({"detect", "--points", (data / "os1_bin" / "000104.bin").string(), "--sensor",
                  m == 0 ? "OS1-64" : "os1-64", "--config", config, "--method", methods[m],
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
