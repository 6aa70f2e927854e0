// Synthetic sequences on disk: a rawlog written is read back with the same poses, stamps and
// ranges; MRPT's own unprojection agrees with ours; the ground-truth files round-trip; real
// rawlogs from mrpt-common read too.
#include <gtest/gtest.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/mrpt/frame_files.hpp"
#include "cairn/sim/mrpt/rawlog.hpp"
#include "cairn/sim/mrpt/sequence.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/sources/decode.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "cairn/sources/trajectory.hpp"
#include "io/temp_dir.hpp"

namespace cairn::sim {
namespace {

namespace fs = std::filesystem;
using ::mrpt::obs::CObservation3DRangeScan;
using ::mrpt::obs::CObservationIMU;
using ::mrpt::obs::CObservationOdometry;
using ::mrpt::obs::CObservationPointCloud;
// The generic rawlog plumbing lives in cairn::sources; libsim/mrpt makes the observations.
using sources::DecodeRangeScan;
using sources::FromCPose3D;
using sources::FromMrptTime;
using sources::RawlogReader;
using sources::RawlogWriter;
using sources::ReadRawlogObservations;
using sources::ReadTumPoses;
using sources::StampedPose;
using sources::ToCPose3D;
using sources::ToMrptTime;
using sources::WriteTumPoses;

constexpr double kStart = 1704067200.0;

Scene MakeScene() {
  Scene scene(Terrain::Hills(0.0, {{0.3, 14.0, 0.4, 0.0}, {0.1, 5.0, 2.0, 1.0}}));
  scene.AddPole(9.0, 1.0, 0.15, 1.5, true, "pole");
  scene.AddRock(7.0, -1.5, {0.4, 0.3, 0.3}, 0.45, 0.2, true, "rock");
  scene.AddRock(5.0, 0.5, {0.2, 0.2, 0.1}, 0.12, 0.0, false, "pebble");
  return scene;
}

DriveSpec MakeSpec() {
  DriveSpec spec;
  spec.waypoints = {{0.0, 0.0}, {4.0, 0.5}, {6.0, 3.0}};
  spec.speed_mps = 3.0;
  spec.frame_rate_hz = 5.0;
  return spec;
}

// A rawlog of a short drive (ODOMETRY, IMU, CAMERA per frame) and what went into it.
struct Written {
  Drive drive;
  std::vector<DepthFrame> frames;
  std::vector<CObservation3DRangeScan::Ptr> scans;
};

Written WriteCameraRawlog(const fs::path& path, int gzip_level) {
  Written w;
  const Scene scene = MakeScene();
  Expected<Drive> drive =
      SimulateDrive(scene.terrain(), MakeSpec(), SensorFrame::kCameraOptical, 9, 6);
  EXPECT_TRUE(drive.ok());
  w.drive = *drive;
  Expected<RawlogWriter> writer = RawlogWriter::Create(path, gzip_level);
  EXPECT_TRUE(writer.ok()) << writer.error().message;
  for (const DriveSample& s : w.drive.samples) {
    Camera camera;
    camera.model = PinholeFromFov(80, 60, 1.3);
    camera.T_world_camera = s.T_world_sensor;
    RenderOptions options;
    options.max_range_m = 40.0;
    Expected<DepthFrame> frame = RenderDepth(scene, camera, options);
    EXPECT_TRUE(frame.ok());
    const auto stamp = ToMrptTime(kStart + s.stamp_s);
    EXPECT_TRUE(writer->Write(*MakeOdometry(s.odometry, {1.0, 0.0, 0.1}, stamp)).ok());
    EXPECT_TRUE(writer->Write(*MakeImu(s.imu, stamp)).ok());
    Expected<CObservation3DRangeScan::Ptr> scan =
        MakeRangeScan(*frame, w.drive.T_body_sensor, 0.001, 40.0, stamp);
    EXPECT_TRUE(scan.ok());
    EXPECT_TRUE(writer->Write(**scan).ok());
    w.frames.push_back(*frame);
    w.scans.push_back(*scan);
  }
  EXPECT_EQ(writer->objects_written(), 3 * static_cast<int>(w.drive.samples.size()));
  const Status committed = writer->Commit();
  EXPECT_TRUE(committed.ok()) << committed.message();
  return w;
}

TEST(SimRawlog, TimesRoundTripToTheTick) {
  for (double t : {0.0, 1.0, kStart, kStart + 0.2, kStart + 123.4567891}) {
    EXPECT_NEAR(FromMrptTime(ToMrptTime(t)), t, 1e-7) << t;
  }
  EXPECT_NEAR(::mrpt::Clock::toDouble(ToMrptTime(kStart + 0.5)), kStart + 0.5, 1e-6);
}

TEST(SimRawlog, PosesConvertBothWays) {
  const Eigen::Isometry3d T = [] {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.linear() = RotationFromAttitude({0.1, -0.2, 2.5});
    t.translation() << 1.0, -2.0, 0.5;
    return t;
  }();
  const ::mrpt::poses::CPose3D pose = ToCPose3D(T);
  EXPECT_NEAR(pose.yaw(), 2.5, 1e-12);
  EXPECT_NEAR(pose.pitch(), -0.2, 1e-12);
  EXPECT_NEAR(pose.roll(), 0.1, 1e-12);
  EXPECT_TRUE(FromCPose3D(pose).isApprox(T, 1e-12));
}

TEST(SimRawlog, WrittenRawlogReadsBackTheSame) {
  for (int gzip_level : {0, 1}) {
    test::TempDir dir;
    const fs::path path = dir / "drive.rawlog";
    const Written w = WriteCameraRawlog(path, gzip_level);
    EXPECT_EQ(dir.List(), std::vector<std::string>{"drive.rawlog"});  // no temporary left

    Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read = ReadRawlogObservations(path);
    ASSERT_TRUE(read.ok()) << read.error().message;
    ASSERT_EQ(read->size(), 3 * w.drive.samples.size());
    for (std::size_t k = 0; k < w.drive.samples.size(); ++k) {
      const DriveSample& s = w.drive.samples[k];
      const auto stamp = ToMrptTime(kStart + s.stamp_s);
      const auto odom = std::dynamic_pointer_cast<CObservationOdometry>((*read)[3 * k]);
      const auto imu = std::dynamic_pointer_cast<CObservationIMU>((*read)[3 * k + 1]);
      const auto scan = std::dynamic_pointer_cast<CObservation3DRangeScan>((*read)[3 * k + 2]);
      ASSERT_TRUE(odom && imu && scan) << "frame " << k;
      EXPECT_EQ(odom->sensorLabel, "ODOMETRY");
      EXPECT_EQ(imu->sensorLabel, "IMU");
      EXPECT_EQ(scan->sensorLabel, "CAMERA");
      EXPECT_EQ(odom->timestamp, stamp);
      EXPECT_EQ(imu->timestamp, stamp);
      EXPECT_EQ(scan->timestamp, stamp);
      EXPECT_NEAR(FromMrptTime(scan->timestamp), kStart + s.stamp_s, 1e-7);

      EXPECT_EQ(odom->odometry.x(), s.odometry.x_m);
      EXPECT_EQ(odom->odometry.y(), s.odometry.y_m);
      EXPECT_NEAR(odom->odometry.phi(), s.odometry.yaw_rad, 1e-15);
      EXPECT_TRUE(odom->hasVelocities);
      ASSERT_TRUE(imu->has(::mrpt::obs::IMU_YAW) && imu->has(::mrpt::obs::IMU_PITCH) &&
                  imu->has(::mrpt::obs::IMU_ROLL));
      EXPECT_EQ(imu->get(::mrpt::obs::IMU_YAW), s.imu.yaw_rad);
      EXPECT_EQ(imu->get(::mrpt::obs::IMU_PITCH), s.imu.pitch_rad);
      EXPECT_EQ(imu->get(::mrpt::obs::IMU_ROLL), s.imu.roll_rad);

      // The range image bit for bit, and in metres within half a unit of the render.
      ASSERT_TRUE(scan->hasRangeImage);
      EXPECT_TRUE(scan->range_is_depth);
      EXPECT_EQ(scan->rangeImage.asEigen(), w.scans[k]->rangeImage.asEigen()) << "frame " << k;
      Expected<sources::Frame> decoded = DecodeRangeScan(*scan);
      ASSERT_TRUE(decoded.ok()) << decoded.error().message;
      const DepthFrame& frame = w.frames[k];
      EXPECT_EQ(decoded->depth()->model.width, frame.model.width);
      EXPECT_EQ(decoded->depth()->model.fx, frame.model.fx);
      EXPECT_EQ(decoded->depth()->model.cy, frame.model.cy);
      int valid = 0;
      for (std::size_t i = 0; i < frame.depth_m.size(); ++i) {
        if (frame.depth_m[i] > 0.0f) ++valid;
        ASSERT_NEAR(decoded->depth()->depth_m[i], frame.depth_m[i], 0.0005 + 1e-6) << "pixel " << i;
      }
      EXPECT_GT(valid, static_cast<int>(frame.depth_m.size() / 3));  // the rest is sky
      EXPECT_TRUE(decoded->T_body_sensor.isApprox(w.drive.T_body_sensor, 1e-12));
      EXPECT_NEAR(decoded->stamp_s, kStart + s.stamp_s, 1e-7);
    }
  }
}

TEST(SimRawlog, MrptUnprojectsTheScanWhereTheCameraSawIt) {
  // MRPT's own unprojection, with sensorPose, puts each return where the renderer's ray hit
  // it (in the body frame): the range-camera convention and the sensor pose are right.
  test::TempDir dir;
  const Written w = WriteCameraRawlog(dir / "drive.rawlog", 0);
  const CObservation3DRangeScan& scan = *w.scans[2];
  const DepthFrame& frame = w.frames[2];
  ::mrpt::maps::CSimplePointsMap points;
  ::mrpt::obs::T3DPointsProjectionParams params;
  params.takeIntoAccountSensorPoseOnRobot = true;
  params.MAKE_ORGANIZED = false;
  const_cast<CObservation3DRangeScan&>(scan).unprojectInto(points, params);
  // Unorganised unprojection keeps the valid pixels in row-major order.
  std::size_t n = 0;
  for (int r = 0; r < frame.height(); ++r) {
    for (int c = 0; c < frame.width(); ++c) {
      const float d = frame.depth_m[static_cast<std::size_t>(r) * frame.width() + c];
      if (!(d > 0.0f)) continue;
      ASSERT_LT(n, points.size());
      const double units = std::lround(d / 0.001) * 0.001;
      const Eigen::Vector3d expected = w.drive.T_body_sensor * frame.model.Unproject(c, r, units);
      float x, y, z;
      points.getPoint(n++, x, y, z);
      ASSERT_NEAR((Eigen::Vector3d(x, y, z) - expected).norm(), 0.0, 1e-4)
          << "row " << r << ", col " << c;
    }
  }
  EXPECT_EQ(n, points.size());
}

TEST(SimRawlog, PointCloudsReadBackExactly) {
  test::TempDir dir;
  LidarScan scan;
  for (int i = 0; i < 500; ++i) {
    scan.points.emplace_back(0.5f + 0.01f * i, -3.0f + 0.013f * i, -1.5f + 0.001f * i);
    scan.ring.push_back(i % 16);
    scan.column.push_back(i / 16);
    scan.object_id.push_back(i % 7 == 0 ? 3 : 0);
  }
  Eigen::Isometry3d T_body_lidar = Eigen::Isometry3d::Identity();
  T_body_lidar.translation() << 0.3, 0.0, 1.9;
  T_body_lidar.linear() = RotationFromAttitude({0.0, 0.05, 0.0});
  const auto stamp = ToMrptTime(kStart + 0.1);
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "lidar.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(*MakePointCloud(scan, T_body_lidar, stamp)).ok());
    ASSERT_TRUE(writer->Commit().ok());
  }
  Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read =
      ReadRawlogObservations(dir / "lidar.rawlog");
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), 1u);
  const auto cloud = std::dynamic_pointer_cast<CObservationPointCloud>(read->front());
  ASSERT_TRUE(cloud && cloud->pointcloud);
  EXPECT_EQ(cloud->sensorLabel, "LIDAR");
  EXPECT_EQ(cloud->timestamp, stamp);
  EXPECT_TRUE(FromCPose3D(cloud->sensorPose).isApprox(T_body_lidar, 1e-12));
  ASSERT_EQ(cloud->pointcloud->size(), scan.points.size());
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    float x, y, z;
    cloud->pointcloud->getPoint(i, x, y, z);
    EXPECT_EQ(Eigen::Vector3f(x, y, z), scan.points[i]) << "point " << i;
  }

  // Its ground truth beside it.
  ASSERT_TRUE(WriteLidarLabels(dir / "0.label", scan).ok());
  std::ifstream labels(dir / "0.label", std::ios::binary);
  std::vector<std::uint32_t> ids(scan.points.size() + 1);
  labels.read(reinterpret_cast<char*>(ids.data()), ids.size() * sizeof(std::uint32_t));
  EXPECT_EQ(labels.gcount(), static_cast<std::streamsize>(scan.points.size() * 4));
  EXPECT_EQ(ids[7], 3u);
  EXPECT_EQ(ids[8], 0u);
}

TEST(SimRawlog, AbandonedWriterLeavesNothing) {
  test::TempDir dir;
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "x.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(*MakeImu({0.1, 0.2, 0.3}, ToMrptTime(kStart))).ok());
  }
  EXPECT_TRUE(dir.List().empty());
  const Expected<RawlogWriter> nowhere = RawlogWriter::Create(dir / "no" / "such" / "x.rawlog");
  ASSERT_FALSE(nowhere.ok());
  EXPECT_NE(nowhere.error().message.find("x.rawlog"), std::string::npos);
}

TEST(SimRawlog, TruncatedOrForeignFilesGiveErrors) {
  test::TempDir dir;
  const fs::path path = dir / "drive.rawlog";
  WriteCameraRawlog(path, 0);
  const auto size = fs::file_size(path);
  fs::resize_file(path, size - size / 3);
  Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read = ReadRawlogObservations(path);
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("drive.rawlog"), std::string::npos);
  EXPECT_NE(read.error().message.find("truncated or corrupt"), std::string::npos);

  const fs::path text = dir.Write("notes.rawlog", "these are not MRPT objects\n");
  read = ReadRawlogObservations(text);
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("notes.rawlog"), std::string::npos);

  read = ReadRawlogObservations(dir / "missing.rawlog");
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("no such file"), std::string::npos);

  // An empty file is an empty rawlog.
  read = ReadRawlogObservations(dir.Write("empty.rawlog", ""));
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_TRUE(read->empty());
}

TEST(SimRawlog, ReadsMrptsRgbdDataset) {
  const fs::path path = "/usr/share/mrpt/datasets/tests_rgbd.rawlog";
  if (!fs::exists(path)) {
    GTEST_SKIP() << path << " is absent: install Debian's mrpt-common (tools/setup-deps.sh)";
  }
  Expected<RawlogReader> reader = RawlogReader::Open(path);
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  int observations = 0, scans = 0;
  while (true) {
    Expected<::mrpt::obs::CObservation::Ptr> next = reader->Next();
    ASSERT_TRUE(next.ok()) << next.error().message;
    if (!*next) break;
    ++observations;
    const auto scan = std::dynamic_pointer_cast<CObservation3DRangeScan>(*next);
    if (!scan || !scan->hasRangeImage) continue;
    ++scans;
    Expected<sources::Frame> frame = DecodeRangeScan(*scan);
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    EXPECT_GT(frame->depth()->model.width, 0);
    int valid = 0;
    for (float d : frame->depth()->depth_m) valid += d > 0.0f && d < 20.0f;
    EXPECT_GT(valid, static_cast<int>(frame->depth()->depth_m.size() / 4)) << "scan " << scans;
  }
  EXPECT_GT(scans, 0);
  EXPECT_GE(observations, scans);
  EXPECT_GE(reader->entries_read(), 1);
}

TEST(SimTruthFiles, ObjectIdImagesRoundTrip) {
  test::TempDir dir;
  od::Grid<std::int32_t> ids;
  ids.width = 5;
  ids.height = 3;
  ids.data = {0, 1, 2, -1, 254, 0, 0, 7, 7, -1, 3, 3, 3, 0, 0};
  ASSERT_TRUE(WriteObjectIdPng(dir / "small.png", ids).ok());
  Expected<od::Grid<std::int32_t>> back = ReadObjectIdPng(dir / "small.png");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->data, ids.data);
  EXPECT_EQ(TruthNoHitLabel(ids.data), 255);

  ids.data[4] = 300;  // no longer fits 8 bits: 16-bit, 65535 = no return
  EXPECT_EQ(TruthNoHitLabel(ids.data), 65535);
  ASSERT_TRUE(WriteObjectIdPng(dir / "wide.png", ids).ok());
  back = ReadObjectIdPng(dir / "wide.png");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->data, ids.data);

  ids.data[0] = 70000;
  EXPECT_FALSE(WriteObjectIdPng(dir / "bad.png", ids).ok());
}

TEST(SimTruthFiles, TumPosesRoundTrip) {
  test::TempDir dir;
  std::vector<StampedPose> poses;
  for (int k = 0; k < 20; ++k) {
    StampedPose p;
    p.stamp_s = kStart + 0.1 * k;
    p.T_world_x.linear() = RotationFromAttitude({0.01 * k, -0.02 * k, 0.3 * k - 3.0});
    p.T_world_x.translation() << 0.5 * k, -0.25 * k, 0.01 * k * k;
    poses.push_back(p);
  }
  ASSERT_TRUE(WriteTumPoses(dir / "poses.tum", poses, "T_world_body\nof a test").ok());
  Expected<std::vector<StampedPose>> back = ReadTumPoses(dir / "poses.tum");
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_NEAR((*back)[k].stamp_s, poses[k].stamp_s, 1e-6);
    EXPECT_NEAR(((*back)[k].T_world_x.translation() - poses[k].T_world_x.translation()).norm(), 0.0,
                1e-6);
    EXPECT_TRUE((*back)[k].T_world_x.linear().isApprox(poses[k].T_world_x.linear(), 1e-8));
  }
  dir.Write("bad.tum", "# ok\n1 2 3\n");
  const Expected<std::vector<StampedPose>> bad = ReadTumPoses(dir / "bad.tum");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("bad.tum:2"), std::string::npos);
}

TEST(SimTruthFiles, CameraFrameIsWhatDetectReads) {
  test::TempDir dir;
  const Scene scene = MakeScene();
  const Camera camera = Camera::AboveGround(PinholeFromFov(64, 48, 1.2), scene.terrain(), 0.0, 0.0,
                                            1.5, 0.0, 0.15, 0.03);
  Expected<DepthFrame> frame = RenderDepth(scene, camera, {});
  ASSERT_TRUE(frame.ok());
  Expected<CameraFrameFiles> files = WriteCameraFrame(dir / "view", *frame, scene);
  ASSERT_TRUE(files.ok()) << files.error().message;
  EXPECT_EQ(dir.List(dir / "view"),
            (std::vector<std::string>{"depth.png", "intrinsics.yaml", "truth.png", "truth.yaml"}));
  Expected<od::io::CameraIntrinsics> intrinsics = od::io::LoadIntrinsics(files->intrinsics_yaml);
  ASSERT_TRUE(intrinsics.ok()) << intrinsics.error().message;
  EXPECT_NEAR(intrinsics->model.fx, frame->model.fx, 1e-6);
  EXPECT_NEAR(intrinsics->model.cx, frame->model.cx, 1e-9);
  EXPECT_NEAR((intrinsics->up - frame->up_optical).norm(), 0.0, 1e-9);
  Expected<od::Grid<float>> depth = od::io::ReadDepthPng(files->depth_png, *intrinsics);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  for (std::size_t i = 0; i < depth->data.size(); ++i) {
    ASSERT_NEAR(depth->data[i], frame->depth_m[i], 0.5 * files->depth_scale_m + 1e-6);
  }
  Expected<od::Grid<std::int32_t>> ids = ReadObjectIdPng(files->truth_png);
  ASSERT_TRUE(ids.ok());
  EXPECT_EQ(ids->data, frame->object_id);
  std::ifstream yaml(files->truth_yaml);
  const std::string text((std::istreambuf_iterator<char>(yaml)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("{id: 1, name: \"pole\", is_obstacle: true, height_m: 1.5}"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("name: \"pebble\", is_obstacle: false"), std::string::npos) << text;
}

TEST(SimTruthFiles, DepthScaleReachesTheFarthestReturn) {
  EXPECT_EQ(DepthScaleFor(0.0), 0.001);
  EXPECT_EQ(DepthScaleFor(65.0), 0.001);
  EXPECT_GE(DepthScaleFor(100.0) * 65535.0, 100.0);
  EXPECT_LE(DepthScaleFor(100.0), 0.0016);
}

World MakeWorld() {
  World world;
  world.name = "test";
  world.scene = MakeScene();
  world.camera.model = PinholeFromFov(80, 60, 1.3);
  world.camera.max_range_m = 40.0;
  world.views = {Viewpoint{}};
  world.drive = MakeSpec();
  world.seed = 3;
  return world;
}

std::vector<std::string> Names(const Expected<std::vector<::mrpt::obs::CObservation::Ptr>>& obs) {
  std::vector<std::string> names;
  for (const auto& o : *obs) names.push_back(o->sensorLabel);
  return names;
}

TEST(SimSequence, DriveSequenceReadsBackLikeRealData) {
  test::TempDir dir;
  const World world = MakeWorld();
  SequenceOptions options;
  options.max_frames = 8;
  options.noise = false;
  options.frames_in_flight = 3;
  std::vector<int> progress;
  Expected<SequenceSummary> summary =
      WriteDriveSequence(world, dir.path(), options, [&progress](int done, int total) {
        EXPECT_EQ(total, 8);
        progress.push_back(done);
      });
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->frames, 8);
  EXPECT_EQ(progress, (std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(dir.List(),
            (std::vector<std::string>{"poses_body.tum", "poses_sensor.tum", "sequence.rawlog",
                                      "sequence.yaml", "truth", "truth.yaml"}));
  const Expected<Drive> drive = SimulateDrive(world.scene.terrain(), *world.drive,
                                              SensorFrame::kCameraOptical, world.seed, 8);
  ASSERT_TRUE(drive.ok());
  const Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read =
      ReadRawlogObservations(summary->rawlog);
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->size(), 24u);
  const Expected<std::vector<StampedPose>> body = ReadTumPoses(summary->poses_body);
  const Expected<std::vector<StampedPose>> sensor = ReadTumPoses(summary->poses_sensor);
  ASSERT_TRUE(body.ok() && sensor.ok());
  ASSERT_EQ(body->size(), 8u);
  for (int k = 0; k < 8; ++k) {
    const DriveSample& s = drive->samples[k];
    const double stamp = options.start_unix_s + 0.2 * k;
    EXPECT_EQ((*read)[3 * k]->sensorLabel, "ODOMETRY");
    EXPECT_EQ((*read)[3 * k + 1]->sensorLabel, "IMU");
    const auto odom = std::dynamic_pointer_cast<CObservationOdometry>((*read)[3 * k]);
    const auto scan = std::dynamic_pointer_cast<CObservation3DRangeScan>((*read)[3 * k + 2]);
    ASSERT_TRUE(odom && scan);
    EXPECT_EQ(odom->odometry.x(), s.odometry.x_m);
    EXPECT_EQ(odom->odometry.y(), s.odometry.y_m);
    EXPECT_NEAR(FromMrptTime(scan->timestamp), stamp, 1e-7);
    EXPECT_NEAR((*body)[k].stamp_s, stamp, 1e-6);
    EXPECT_TRUE((*body)[k].T_world_x.translation().isApprox(s.T_world_body.translation(), 1e-5));
    EXPECT_TRUE((*sensor)[k].T_world_x.linear().isApprox(s.T_world_sensor.linear(), 1e-8));

    // The range image is the camera's view from the true pose, its truth beside it.
    Expected<sources::Frame> decoded = DecodeRangeScan(*scan);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_TRUE(decoded->T_body_sensor.isApprox(drive->T_body_sensor, 1e-12));
    EXPECT_TRUE((s.T_world_body * decoded->T_body_sensor).isApprox(s.T_world_sensor, 1e-12));
    const Expected<DepthFrame> frame = RenderDriveCamera(world, s.T_world_sensor, k, false);
    ASSERT_TRUE(frame.ok());
    for (std::size_t i = 0; i < frame->depth_m.size(); ++i) {
      ASSERT_NEAR(decoded->depth()->depth_m[i], frame->depth_m[i], 0.0005 + 1e-6) << "frame " << k;
    }
    char name[32];
    std::snprintf(name, sizeof(name), "truth/%06d.png", k);
    const Expected<od::Grid<std::int32_t>> ids = ReadObjectIdPng(dir / name);
    ASSERT_TRUE(ids.ok()) << ids.error().message;
    EXPECT_EQ(ids->data, frame->object_id) << name;
  }
}

TEST(SimSequence, CameraNoiseIsSeededPerFrame) {
  World world = MakeWorld();
  world.camera.noise.depth_sigma_per_m2 = 0.01;
  world.camera.noise.dropout_probability = 0.05;
  const Camera camera =
      Camera::AboveGround(world.camera.model, world.scene.terrain(), 0.0, 0.0, 1.5, 0.0, 0.15, 0.0);
  const auto a = RenderDriveCamera(world, camera.T_world_camera, 4, true);
  const auto b = RenderDriveCamera(world, camera.T_world_camera, 4, true);
  const auto c = RenderDriveCamera(world, camera.T_world_camera, 5, true);
  const auto exact = RenderDriveCamera(world, camera.T_world_camera, 4, false);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok() && exact.ok());
  EXPECT_EQ(a->depth_m, b->depth_m);
  EXPECT_NE(a->depth_m, c->depth_m);
  EXPECT_NE(a->depth_m, exact->depth_m);
}

TEST(SimSequence, LidarSequenceHasCloudsAndPointTruth) {
  test::TempDir dir;
  World world = MakeWorld();
  Expected<LidarSpec> lidar = LidarSpec::Preset("VLP-16");
  ASSERT_TRUE(lidar.ok());
  lidar->azimuth_steps = 256;
  world.lidar = *lidar;
  SequenceOptions options;
  options.sensor = SensorFrame::kLidar;
  options.max_frames = 4;
  Expected<SequenceSummary> summary = WriteDriveSequence(world, dir.path(), options);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read =
      ReadRawlogObservations(summary->rawlog);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(Names(read),
            (std::vector<std::string>{"ODOMETRY", "IMU", "LIDAR", "ODOMETRY", "IMU", "LIDAR",
                                      "ODOMETRY", "IMU", "LIDAR", "ODOMETRY", "IMU", "LIDAR"}));
  for (int k = 0; k < 4; ++k) {
    const auto cloud = std::dynamic_pointer_cast<CObservationPointCloud>((*read)[3 * k + 2]);
    ASSERT_TRUE(cloud && cloud->pointcloud);
    EXPECT_GT(cloud->pointcloud->size(), 500u);
    EXPECT_TRUE(FromCPose3D(cloud->sensorPose)
                    .isApprox(BodyToSensor(*world.drive, SensorFrame::kLidar), 1e-12));
    char name[32];
    std::snprintf(name, sizeof(name), "truth/%06d.label", k);
    EXPECT_EQ(fs::file_size(dir / name), 4 * cloud->pointcloud->size());
    std::snprintf(name, sizeof(name), "truth/%06d.rowcol", k);
    EXPECT_EQ(fs::file_size(dir / name), 4 * cloud->pointcloud->size());
  }
}

TEST(SimSequence, MissingSectionsAreNamedAndLeaveNoRawlog) {
  test::TempDir dir;
  World world = MakeWorld();
  SequenceOptions options;
  options.sensor = SensorFrame::kLidar;
  Expected<SequenceSummary> summary = WriteDriveSequence(world, dir.path(), options);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.error().message.find("lidar: missing"), std::string::npos);
  world.drive.reset();
  summary = WriteDriveSequence(world, dir.path(), {});
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.error().message.find("drive: missing"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "sequence.rawlog"));
}

TEST(SimRawlog, RawImuSamplesReadBackWithTheFrameThatFollowsThem) {
  test::TempDir dir;
  const fs::path path = dir / "imu.rawlog";
  const Scene scene = MakeScene();
  ImuSpec imu;
  imu.misalignment_rad << 0.02, -0.01, 0.3;
  imu.accel_bias_mps2 << 0.05, 0.0, -0.02;
  const Expected<Drive> drive =
      SimulateDrive(scene.terrain(), MakeSpec(), SensorFrame::kCameraOptical, 9, 4, imu);
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  ASSERT_EQ(drive->imu.size(), 60u);  // 0.6 s at 100 Hz
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(path);
    ASSERT_TRUE(writer.ok());
    std::size_t j = 0;
    for (const DriveSample& s : drive->samples) {
      for (; j < drive->imu.size() && drive->imu[j].stamp_s <= s.stamp_s; ++j) {
        const ImuReading& r = drive->imu[j];
        ASSERT_TRUE(
            writer->Write(*MakeRawImu(r, drive->R_body_imu, ToMrptTime(kStart + r.stamp_s))).ok());
      }
      const auto stamp = ToMrptTime(kStart + s.stamp_s);
      ASSERT_TRUE(writer->Write(*MakeImu(s.imu, stamp)).ok());
      Camera camera;
      camera.model = PinholeFromFov(40, 30, 1.3);
      camera.T_world_camera = s.T_world_sensor;
      RenderOptions options;
      options.max_range_m = 40.0;
      Expected<DepthFrame> frame = RenderDepth(scene, camera, options);
      ASSERT_TRUE(frame.ok());
      Expected<CObservation3DRangeScan::Ptr> scan =
          MakeRangeScan(*frame, drive->T_body_sensor, 0.001, 40.0, stamp);
      ASSERT_TRUE(scan.ok());
      ASSERT_TRUE(writer->Write(**scan).ok());
    }
    ASSERT_TRUE(writer->Commit().ok());
  }
  Expected<sources::RawlogSource> source = sources::RawlogSource::Open(path);
  ASSERT_TRUE(source.ok()) << source.error().message;
  std::size_t j = 0;
  for (std::size_t k = 0; k < drive->samples.size(); ++k) {
    Expected<std::optional<sources::Frame>> frame = source->NextFrame();
    ASSERT_TRUE(frame.ok() && frame->has_value());
    const sources::Frame& f = **frame;
    // Frame k comes with the samples of (t_{k-1}, t_k]: 20 at 100 Hz and 5 frames/s.
    EXPECT_EQ(f.imu_samples.size(), k == 0 ? 0u : 20u) << "frame " << k;
    ASSERT_TRUE(f.imu.has_value());  // the attitude observation is not a raw sample
    for (const sources::ImuSample& got : f.imu_samples) {
      const ImuReading& want = drive->imu[j++];
      EXPECT_NEAR(got.stamp_s, kStart + want.stamp_s, 1e-6);
      ASSERT_TRUE(got.specific_force_mps2 && got.angular_rate_radps);
      EXPECT_NEAR((*got.specific_force_mps2 - want.specific_force_mps2).norm(), 0.0, 1e-12);
      EXPECT_NEAR((*got.angular_rate_radps - want.angular_rate_radps).norm(), 0.0, 1e-12);
      EXPECT_TRUE(got.T_body_imu.linear().isApprox(drive->R_body_imu, 1e-9));
      EXPECT_EQ(got.label, kImuLabel);
    }
  }
  EXPECT_EQ(j, 60u);
}

}  // namespace
}  // namespace cairn::sim
