// Detection on recorded frames and annotated copies: the cone detector on MRPT's sample
// rawlogs finds what a person sees (the figures asserted here were measured and checked on
// the overlays), `cairn detect --rawlog` writes one folder per frame and an annotated copy
// that MRPT reads back with the same labels, and `cairn info` describes files or says why
// it cannot.
#include <gtest/gtest.h>
#include <mrpt/maps/CWeightedPointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationStereoImages.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/obs/T3DPointsProjectionParams.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <random>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sources/annotate.hpp"
#include "cairn/sources/decode.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "../io/cairn_command.hpp"
#include "helpers.hpp"
#include "io/temp_dir.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

const fs::path kDefaultConfig = fs::path(__FILE__).parent_path().parent_path().parent_path() /
                                "config" / "default.yaml";

// Measured on MRPT's sample scans with config/default.yaml (see the tests below for what
// was checked on the overlays).
constexpr std::size_t kVelodyneSegments = 87;
constexpr int kVelodyneKept = 33;
constexpr double kVelodyneGroundZ = -2.506;  // [m] in the LiDAR frame
constexpr int kGroundPercent = 10;           // measured 36 of 536 (6.7%)
constexpr int kTallPercent = 90;             // measured 2765 of 2999 (92.2%)
constexpr std::size_t kRotatingSegments = 87;
constexpr int kRotatingKept = 33;

od::io::DetectSettings DefaultSettings() {
  Expected<od::io::DetectSettings> settings =
      od::io::LoadDetectSettings(kDefaultConfig, {"map", "tilt", "frames"});
  EXPECT_TRUE(settings.ok()) << settings.error().message;
  return settings.ok() ? *settings : od::io::DetectSettings{};
}

struct Detected {
  od::RangeImage image;
  od::Detection detection;
  od::Classification classification;
};

Detected DetectPoints(const Frame& frame) {
  const PointScan& scan = *frame.points();
  Detected out;
  Expected<od::RangeImage> image =
      od::RangeImage::FromPoints(scan.points, scan.model, UpInSensor(frame), scan.rows, scan.cols);
  EXPECT_TRUE(image.ok()) << image.error().message;
  out.image = *image;
  const od::io::DetectSettings settings = DefaultSettings();
  Expected<od::Detection> detection = od::Detect(out.image, settings.detector);
  EXPECT_TRUE(detection.ok());
  out.detection = *detection;
  out.classification = *od::Classify(out.detection, settings.rules);
  return out;
}

// ---------------------------------------------------------------------------------------
// MRPT's sample scans

TEST(DetectMrptDatasets, KinectBookshelfAndWallAreOneObstacle) {
  // tests_rgbd.rawlog looks level at a bookshelf standing against a wall, 1.6 to 2.6 m away,
  // with no floor in view: every surface is vertical, so every return is an obstacle point,
  // and the shelf touches the wall, so they are one segment. At full resolution the exact
  // search examines 8.2e9 pairs (minutes); every 4th pixel (160x120) keeps the scene.
  CAIRN_MRPT_DATASET_OR_SKIP(path, "tests_rgbd");
  const Frame frame = test::FirstFrame(path);
  const DepthImage& depth = *frame.depth();
  constexpr int kStep = 4;
  od::PinholeModel model = depth.model;
  model.width /= kStep;
  model.height /= kStep;
  model.fx /= kStep;
  model.fy /= kStep;
  model.cx /= kStep;
  model.cy /= kStep;
  std::vector<float> decimated(static_cast<std::size_t>(model.width) * model.height);
  for (int r = 0; r < model.height; ++r) {
    for (int c = 0; c < model.width; ++c) {
      decimated[static_cast<std::size_t>(r) * model.width + c] =
          depth.depth_m[static_cast<std::size_t>(kStep * r) * depth.model.width + kStep * c];
    }
  }
  Expected<od::RangeImage> image = od::RangeImage::FromDepth(decimated, model, UpInSensor(frame));
  ASSERT_TRUE(image.ok()) << image.error().message;
  const od::io::DetectSettings settings = DefaultSettings();
  Expected<od::Detection> detection = od::Detect(*image, settings.detector);
  ASSERT_TRUE(detection.ok());
  const od::Classification classification = *od::Classify(*detection, settings.rules);
  const int valid = image->valid_count();
  EXPECT_GT(valid, 17000);
  ASSERT_EQ(detection->segments.size(), 1u);
  EXPECT_EQ(classification.kept, 1);
  EXPECT_GT(detection->stats.obstacle_points, valid * 99 / 100);
  // Its extent is the shelf and wall: from 1.74 m (the nearest of the pixels kept), about
  // 2 m across and 1.9 m tall.
  const od::SegmentFeatures& s = detection->segments.front();
  EXPECT_NEAR(s.range_min_m, 1.743, 0.001);
  EXPECT_GT(s.bbox_max.y() - s.bbox_min.y(), 1.8);
  EXPECT_GT(s.bbox_max.z() - s.bbox_min.z(), 1.5);
}

// Ground and tall things in a LiDAR scan. The ground height is the 10th percentile of the
// lowest ring's heights: that ring meets the open ground 9 m away, 2.5 m below the sensor,
// and things standing on it nearer.
struct GroundSplit {
  int ground = 0, ground_obstacle = 0;  ///< returns within 0.1 m of the ground, 3..20 m away
  int tall = 0, tall_obstacle = 0;      ///< returns 1.0..2.5 m above the ground, 3..20 m away
  double ground_z = 0.0;
};

GroundSplit SplitByHeight(const PointScan& scan, const std::vector<std::uint32_t>& words) {
  const int lowest = scan.model.height() - 1;
  std::vector<float> z;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    if (scan.rows[i] == lowest) z.push_back(scan.points[i].z());
  }
  std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(z.size() / 10), z.end());
  GroundSplit split;
  split.ground_z = z[z.size() / 10];
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const float d = scan.points[i].head<2>().norm();
    if (d < 3.0f || d > 20.0f) continue;
    const double h = scan.points[i].z() - split.ground_z;
    const bool obstacle = (words[i] & 0xFFFFu) != 0;
    if (std::abs(h) < 0.1) {
      ++split.ground;
      split.ground_obstacle += obstacle;
    } else if (h > 1.0 && h < 2.5) {
      ++split.tall;
      split.tall_obstacle += obstacle;
    }
  }
  return split;
}

TEST(DetectMrptDatasets, VelodyneScanFindsWallsAndTreesNotTheGround) {
  // test_velodyne_VLP16.rawlog: a VLP-16 about 2.5 m above open ground among trees, a long
  // building wall on its right. The overlay shows the tree crowns and their trunks and the
  // wall in blue down to the ground, the ground rings grey.
  CAIRN_MRPT_DATASET_OR_SKIP(path, "test_velodyne_VLP16");
  const Frame frame = test::FirstFrame(path);
  const Detected d = DetectPoints(frame);
  Expected<std::vector<std::uint32_t>> words =
      od::io::PointLabels(d.image, d.detection, d.classification);
  ASSERT_TRUE(words.ok());
  EXPECT_EQ(d.image.valid_count(), 11305);  // one cell per return
  EXPECT_EQ(d.detection.segments.size(), kVelodyneSegments);
  EXPECT_EQ(d.classification.kept, kVelodyneKept);
  const GroundSplit split = SplitByHeight(*frame.points(), *words);
  EXPECT_NEAR(split.ground_z, kVelodyneGroundZ, 0.001);
  // The road is not an obstacle (but where it meets an obstacle's foot, by definition),
  // what stands 1 to 2.5 m above it mostly is.
  EXPECT_LT(split.ground_obstacle, split.ground * kGroundPercent / 100);
  EXPECT_GT(split.tall_obstacle, split.tall * kTallPercent / 100);
}

TEST(DetectMrptDatasets, RotatingScanGivesTheSameObstacles) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "rot_scan_velodyne");
  const Frame frame = test::FirstFrame(path);
  const Detected d = DetectPoints(frame);
  Expected<std::vector<std::uint32_t>> words =
      od::io::PointLabels(d.image, d.detection, d.classification);
  ASSERT_TRUE(words.ok());
  EXPECT_EQ(d.image.valid_count(), 11305);
  EXPECT_EQ(d.detection.segments.size(), kRotatingSegments);
  EXPECT_EQ(d.classification.kept, kRotatingKept);
  const GroundSplit split = SplitByHeight(*frame.points(), *words);
  EXPECT_LT(split.ground_obstacle, split.ground * kGroundPercent / 100);
  EXPECT_GT(split.tall_obstacle, split.tall * kTallPercent / 100);
}

// ---------------------------------------------------------------------------------------
// Pixel labels

TEST(PixelLabels, MoreSegmentsThanBitsKeepTheLargestKeptFirst) {
  od::Detection detection;
  od::Classification classification;
  for (int id = 1; id <= 70; ++id) {
    od::SegmentFeatures s;
    s.id = id;
    s.point_count = 1000 - id;  // larger ids are smaller
    detection.segments.push_back(s);
    od::SegmentVerdict v;
    v.id = id;
    v.cls = id % 3 == 0 ? od::SegmentClass::kRejected : od::SegmentClass::kKept;
    classification.verdicts.push_back(v);
  }
  const PixelLabelPlan plan = PlanPixelLabels(detection, classification);
  EXPECT_EQ(plan.bytes, 8);
  ASSERT_EQ(plan.bits.size(), 62u);
  EXPECT_EQ(plan.segments_without_bit, 8);
  // 47 kept segments, all with a bit, largest first; then the 15 largest rejected ones.
  EXPECT_EQ(plan.bits[0], std::make_pair(1, std::string("obstacle 1")));
  EXPECT_EQ(plan.bits[46], std::make_pair(70, std::string("obstacle 70")));
  EXPECT_EQ(plan.bits[47], std::make_pair(3, std::string("rejected 3")));
  EXPECT_EQ(plan.bits[61], std::make_pair(45, std::string("rejected 45")));
  detection.segments.resize(5);
  EXPECT_EQ(PlanPixelLabels(detection, classification).bytes, 1);
}

#ifdef CAIRN_EXE
// ---------------------------------------------------------------------------------------
// The command

struct CommandRun {
  int status = -1;
  std::string out;  ///< stdout and stderr
};

CommandRun Cairn(const std::string& args) {
  const test::CommandResult run = test::RunShell(std::string(CAIRN_EXE) + " " + args);
  return {run.exit_code, run.output};
}

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

std::string Quote(const fs::path& path) { return "'" + path.string() + "'"; }

TEST(DetectRawlogCommand, VelodyneScanFolderSummaryAndAnnotatedCopy) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "test_velodyne_VLP16");
  test::TempDir dir;
  const CommandRun run = Cairn("detect --rawlog " + Quote(path) + " --config " + Quote(kDefaultConfig) +
                        " --out " + Quote(dir / "out") + " --annotated " +
                        Quote(dir / "annotated.rawlog"));
  ASSERT_EQ(run.status, 0) << run.out;
  const fs::path folder = dir / "out" / "000000_Velodyne1_SCAN";
  EXPECT_EQ(dir.List(folder),
            (std::vector<std::string>{"birds_eye.png", "classes.png", "labels.label", "overlay.png",
                                      "segments.json", "segments.png", "segments_color.png"}));
  const nlohmann::json summary = ReadJson(dir / "out" / "summary.json");
  EXPECT_EQ(summary["frames_detected"], 1);
  EXPECT_EQ(summary["segments_found"], kVelodyneSegments);
  EXPECT_EQ(summary["segments_kept"], kVelodyneKept);
  const nlohmann::json& frame = summary["frames"][0];
  EXPECT_EQ(frame["label"], "Velodyne1_SCAN");
  EXPECT_EQ(frame["class"], "CObservationVelodyneScan");
  EXPECT_EQ(frame["points"], 11305);
  EXPECT_EQ(frame["height"], 16);
  EXPECT_EQ(frame["up_from"], "sensor pose, body level");
  Expected<std::vector<std::uint32_t>> words = od::io::ReadLabelFile(folder / "labels.label");
  ASSERT_TRUE(words.ok());
  ASSERT_EQ(words->size(), 11305u);

  // MRPT reads the annotated copy: the scan as it was, then its points with their words.
  Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read =
      ReadRawlogObservations(dir / "annotated.rawlog");
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), 2u);
  auto velodyne = std::dynamic_pointer_cast<::mrpt::obs::CObservationVelodyneScan>((*read)[0]);
  auto cloud = std::dynamic_pointer_cast<::mrpt::obs::CObservationPointCloud>((*read)[1]);
  ASSERT_TRUE(velodyne && cloud);
  EXPECT_EQ(velodyne->scan_packets.size(), 75u);
  EXPECT_EQ(cloud->sensorLabel, "Velodyne1_SCAN_SEGMENTS");
  EXPECT_EQ(cloud->timestamp, velodyne->timestamp);
  auto map = std::dynamic_pointer_cast<::mrpt::maps::CWeightedPointsMap>(cloud->pointcloud);
  ASSERT_TRUE(map);
  const Frame decoded = test::FirstFrame(path);
  ASSERT_EQ(map->size(), decoded.points()->points.size());
  for (std::size_t i = 0; i < map->size(); ++i) {
    float x, y, z;
    map->getPoint(i, x, y, z);
    ASSERT_EQ(Eigen::Vector3f(x, y, z), decoded.points()->points[i]) << "point " << i;
    ASSERT_EQ(map->getPointWeight(i), (*words)[i]) << "point " << i;
  }
}

// A range camera 1.5 m above flat ground, pitched down 15 deg, 60x45 px with a barrel lens,
// before a box 5 m ahead (1 m wide, 0.8 m tall): its recorded (distorted) range image.
::mrpt::obs::CObservation3DRangeScan::Ptr BoxScan(std::vector<bool>& on_box) {
  constexpr int kWidth = 60, kHeight = 45;
  auto scan = test::MakeScan(kWidth, kHeight, 40.0, [](int, int) { return 1.0; }, true);
  scan->cameraParams.dist[0] = -0.08;
  scan->sensorPose = ::mrpt::poses::CPose3D(0.0, 0.0, 1.5, 0.0, 15.0 * kDegToRad, 0.0);
  scan->sensorLabel = "DEPTH_CAM";
  const Eigen::Isometry3d T_body_camera = FromCPose3D(scan->sensorPose);
  on_box.assign(static_cast<std::size_t>(kWidth) * kHeight, false);
  for (int r = 0, i = 0; r < kHeight; ++r) {
    for (int c = 0; c < kWidth; ++c, ++i) {
      // The pixel's ray through the lens, in MRPT's range-camera frame (x along the axis).
      const Eigen::Vector2d n = test::Undistort({(c - 29.5) / 40.0, (r - 22.0) / 40.0},
                                                scan->cameraParams.dist);
      const double x = 1.0, y = -n.x(), z = -n.y();
      const Eigen::Vector3d origin = T_body_camera.translation();
      const Eigen::Vector3d ray = T_body_camera.linear() * Eigen::Vector3d(x, y, z);
      double t = std::numeric_limits<double>::infinity();  // depth: the ray has x_cam = 1
      if (ray.z() < 0.0) t = -origin.z() / ray.z();
      if (ray.x() > 0.0) {
        const double tb = (5.0 - origin.x()) / ray.x();
        const Eigen::Vector3d hit = origin + tb * ray;
        if (std::abs(hit.y()) < 0.5 && hit.z() > 0.0 && hit.z() < 0.8 && tb < t) {
          t = tb;
          on_box[static_cast<std::size_t>(i)] = true;
        }
      }
      scan->rangeImage(r, c) =
          std::isfinite(t) && t < 6.0 ? static_cast<std::uint16_t>(std::lround(t / 0.0001)) : 0;
    }
  }
  return scan;
}

TEST(DetectRawlogCommand, RangeScanLabelsReadBackThroughMrpt) {
  test::TempDir dir;
  std::vector<bool> on_box;
  const auto scan = BoxScan(on_box);
  auto odometry = std::make_shared<::mrpt::obs::CObservationOdometry>();
  odometry->sensorLabel = "ODOM";
  odometry->timestamp = scan->timestamp;
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "box.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(*odometry).ok());
    ASSERT_TRUE(writer->Write(*scan).ok());
    ASSERT_TRUE(writer->Commit().ok());
  }
  const CommandRun run = Cairn("detect --rawlog " + Quote(dir / "box.rawlog") + " --config " +
                        Quote(kDefaultConfig) + " --out " + Quote(dir / "out") +
                        " --annotated " + Quote(dir / "box.annotated.rawlog"));
  ASSERT_EQ(run.status, 0) << run.out;
  const fs::path folder = dir / "out" / "000000_DEPTH_CAM";
  const nlohmann::json summary = ReadJson(dir / "out" / "summary.json");
  EXPECT_EQ(summary["frames_detected"], 1);
  EXPECT_EQ(summary["frames"][0]["undistorted"], true);
  EXPECT_EQ(summary["frames"][0]["odometry"]["source"], "ODOM");
  EXPECT_EQ(summary["segments_kept"], 1);  // the box (with the ground at its foot)
  Expected<od::Grid<std::uint8_t>> classes = od::io::ReadClassesPng(folder / "classes.png");
  Expected<od::Grid<std::int32_t>> segments = od::io::ReadSegmentsPng(folder / "segments.png");
  ASSERT_TRUE(classes.ok() && segments.ok());

  Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read =
      ReadRawlogObservations(dir / "box.annotated.rawlog");
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), 2u);
  auto labelled = std::dynamic_pointer_cast<::mrpt::obs::CObservation3DRangeScan>((*read)[1]);
  ASSERT_TRUE(labelled && labelled->hasPixelLabels());
  EXPECT_EQ(labelled->pixelLabels->getLabelName(0), "obstacle");
  EXPECT_EQ(labelled->pixelLabels->getLabelName(1), "rejected");
  EXPECT_EQ(labelled->pixelLabels->getLabelName(2), "obstacle 1");
  EXPECT_EQ(labelled->rangeImage.asEigen(), scan->rangeImage.asEigen());  // data untouched
  Expected<PixelLabelsRead> labels = ReadPixelLabels(*labelled);
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  Expected<Frame> decoded = DecodeRangeScan(*scan);
  ASSERT_TRUE(decoded.ok());
  const std::vector<std::int32_t>& to = decoded->depth()->decoded_of_source;
  ASSERT_EQ(to.size(), labels->cls.size());
  int box = 0, boxed = 0;
  for (std::size_t s = 0; s < to.size(); ++s) {
    const std::uint8_t cls = to[s] < 0 ? 0 : classes->data[to[s]];
    const std::int32_t id = to[s] < 0 ? 0 : segments->data[to[s]];
    ASSERT_EQ(labels->cls[s], cls) << "recorded pixel " << s;
    ASSERT_EQ(labels->segment[s], id) << "recorded pixel " << s;
    // Pixels seeing the box's face are kept obstacle points.
    if (on_box[s]) {
      ++box;
      boxed += labels->cls[s] == 1;
    }
  }
  EXPECT_GT(box, 20);
  EXPECT_EQ(boxed, box);
  // The ground at the camera's feet (bottom row, 1.6 m ahead) is not an obstacle.
  for (std::size_t s = 44 * 60; s < 45 * 60; ++s) EXPECT_EQ(labels->cls[s], 0) << s;
}

TEST(DetectRawlogCommand, SensoryFramesGetTheirSegmentCloudsInside) {
  // A point cloud in a sensory-frame file: the annotated copy keeps the file's layout, the
  // segment cloud joins the cloud's sensory frame.
  CAIRN_MRPT_DATASET_OR_SKIP(path, "test_velodyne_VLP16");
  test::TempDir dir;
  const Frame frame = test::FirstFrame(path);
  auto map = ::mrpt::maps::CSimplePointsMap::Create();
  for (const Eigen::Vector3f& p : frame.points()->points) map->insertPointFast(p.x(), p.y(), p.z());
  auto cloud = std::make_shared<::mrpt::obs::CObservationPointCloud>();
  cloud->sensorLabel = "LIDAR";
  cloud->pointcloud = map;
  cloud->timestamp = ToMrptTime(frame.stamp_s);
  ::mrpt::obs::CSensoryFrame sf;
  sf.insert(cloud);
  ::mrpt::obs::CActionCollection actions;
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "sf.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(sf).ok());
    ASSERT_TRUE(writer->Write(actions).ok());
    ASSERT_TRUE(writer->Commit().ok());
  }
  const CommandRun run = Cairn("detect --rawlog " + Quote(dir / "sf.rawlog") + " --label LIDAR --out " +
                        Quote(dir / "out") + " --annotated " + Quote(dir / "sf.annotated.rawlog"));
  ASSERT_EQ(run.status, 0) << run.out;
  Expected<RawlogReader> reader = RawlogReader::Open(dir / "sf.annotated.rawlog");
  ASSERT_TRUE(reader.ok());
  Expected<std::optional<RawlogEntry>> first = reader->NextEntry();
  ASSERT_TRUE(first.ok() && *first);
  auto annotated = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>((*first)->object);
  ASSERT_TRUE(annotated);
  ASSERT_EQ(annotated->size(), 2u);
  EXPECT_EQ(annotated->getObservationByIndex(1)->sensorLabel, "LIDAR_SEGMENTS");
  Expected<std::optional<RawlogEntry>> second = reader->NextEntry();
  ASSERT_TRUE(second.ok() && *second);
  EXPECT_TRUE(std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>((*second)->object));
}

TEST(DetectRawlogCommand, StereoPairsAreMatchedThenDetected) {
  // A textured wall seen by a rectified pair 4 px apart: fx B / d = 50 * 0.12 / 4 = 1.5 m.
  test::TempDir dir;
  constexpr int kWidth = 128, kHeight = 96, kShift = 4;
  std::mt19937 rng(5);
  std::vector<std::uint8_t> texture(static_cast<std::size_t>(kWidth + kShift) * kHeight);
  for (auto& v : texture) v = static_cast<std::uint8_t>(rng() & 0xFF);
  ::mrpt::obs::CObservationStereoImages stereo;
  stereo.sensorLabel = "BUMBLEBEE";
  stereo.imageLeft.resize(kWidth, kHeight, ::mrpt::img::CH_GRAY);
  stereo.imageRight.resize(kWidth, kHeight, ::mrpt::img::CH_GRAY);
  for (int r = 0; r < kHeight; ++r) {
    for (int c = 0; c < kWidth; ++c) {
      const std::size_t row = static_cast<std::size_t>(r) * (kWidth + kShift);
      // A point at left column c is at right column c - kShift: disparity +kShift.
      stereo.imageLeft.at<std::uint8_t>(c, r) = texture[row + c];
      stereo.imageRight.at<std::uint8_t>(c, r) = texture[row + c + kShift];
    }
  }
  stereo.hasImageRight = true;
  for (auto* camera : {&stereo.leftCamera, &stereo.rightCamera}) {
    camera->ncols = kWidth;
    camera->nrows = kHeight;
    camera->setIntrinsicParamsFromValues(50.0, 50.0, 63.5, 47.5);
  }
  stereo.rightCameraPose = ::mrpt::poses::CPose3DQuat(::mrpt::poses::CPose3D(0.12, 0, 0, 0, 0, 0));
  stereo.cameraPose = ::mrpt::poses::CPose3DQuat(
      ::mrpt::poses::CPose3D(0.0, 0.0, 1.0, -90 * kDegToRad, 0.0, -90 * kDegToRad));
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "stereo.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(stereo).ok());
    ASSERT_TRUE(writer->Commit().ok());
  }
  const CommandRun run = Cairn("detect --rawlog " + Quote(dir / "stereo.rawlog") + " --out " +
                               Quote(dir / "out"));
  ASSERT_EQ(run.status, 0) << run.out;
  const nlohmann::json summary = ReadJson(dir / "out" / "summary.json");
  const nlohmann::json& frame = summary["frames"][0];
  EXPECT_EQ(frame["kind"], "stereo");
  EXPECT_EQ(frame["baseline_m"], 0.12);
  EXPECT_EQ(frame["rectified_here"], false);
  EXPECT_EQ(frame["stereo_range_too_short"], false);  // 4 px, well inside the range
  Expected<od::Grid<float>> depth =
      od::io::ReadDepthTiff(dir / "out" / "000000_BUMBLEBEE" / "depth.tiff", kWidth, kHeight, 1.0);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  int near_1_5 = 0, valid = 0;
  for (float z : depth->data) {
    if (z <= 0.0f) continue;
    ++valid;
    near_1_5 += std::abs(z - 1.5f) < 0.02f;
  }
  EXPECT_GT(valid, kWidth * kHeight / 2);
  EXPECT_GT(near_1_5, valid * 95 / 100);
  // A vertical wall 1.5 m ahead, 1.3 m tall in view: one obstacle.
  EXPECT_EQ(frame["segments_kept"], 1);
}

TEST(DetectRawlogCommand, BadInputsFailWithAMessage) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "test_velodyne_VLP16");
  test::TempDir dir;
  CommandRun run = Cairn("detect --rawlog " + Quote(path) + " --label NOPE --out " + Quote(dir / "out"));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("no range observation labelled 'NOPE'"), std::string::npos) << run.out;
  dir.Write("empty.rawlog", "");
  run = Cairn("detect --rawlog " + Quote(dir / "empty.rawlog") + " --out " + Quote(dir / "out"));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("empty.rawlog: no range observation"), std::string::npos) << run.out;
  fs::copy_file(path, dir / "cut.rawlog");
  fs::resize_file(dir / "cut.rawlog", fs::file_size(path) / 2);
  run = Cairn("detect --rawlog " + Quote(dir / "cut.rawlog") + " --out " + Quote(dir / "out") +
              " --annotated " + Quote(dir / "cut.annotated.rawlog"));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("cut.rawlog: entry 0: truncated or corrupt"), std::string::npos)
      << run.out;
  EXPECT_FALSE(fs::exists(dir / "cut.annotated.rawlog"));  // nothing half-written
  run = Cairn("detect --rawlog " + Quote(path) + " --out " + Quote(dir / "out") +
              " --annotated " + Quote(path));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("is the input rawlog"), std::string::npos) << run.out;
}

TEST(InfoCommand, DescribesRawlogsAndRefusesOtherFiles) {
  CAIRN_MRPT_DATASET_OR_SKIP(rgbd, "tests_rgbd");
  CAIRN_MRPT_DATASET_OR_SKIP(kf, "kf-slam_6D_demo");
  CommandRun run = Cairn("info " + Quote(rgbd));
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("format:    observations, 1 top-level objects"), std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("OPENNI2"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("640x480 px"), std::string::npos) << run.out;
  run = Cairn("info " + Quote(kf));
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find("sensory frames (actions and observations), 1200 top-level objects"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("odometry:  601 poses"), std::string::npos) << run.out;

  test::TempDir dir;
  const fs::path bin = dir.Write("scan.bin", std::string(64, '\x01'));
  run = Cairn("info " + Quote(bin));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("scan.bin: entry 0: truncated or corrupt rawlog (or not a rawlog)"),
            std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("cairn detect --points"), std::string::npos) << run.out;
  run = Cairn("info " + Quote(dir.Write("empty.rawlog", "")));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("empty file"), std::string::npos) << run.out;
  run = Cairn("info " + Quote(dir / "none.rawlog"));
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.out.find("none.rawlog: no such file"), std::string::npos) << run.out;
}
#endif  // CAIRN_EXE

}  // namespace
}  // namespace cairn::sources
