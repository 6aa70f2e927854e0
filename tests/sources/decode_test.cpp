// Observations decoded into frames: MRPT's sample rawlogs (a Kinect frame, one VLP-16 scan
// as raw packets and the same scan as a rotating scan) checked against MRPT's own geometry,
// and synthetic observations with known answers (range vs depth conventions, lens
// distortion, externally stored images, ring finding, stereo pairs, IMU and odometry).
#include "cairn/sources/decode.hpp"

#include <gtest/gtest.h>
#include <mrpt/img/CImage.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationStereoImages.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/T3DPointsProjectionParams.h>
#include <mrpt/poses/CPose3DQuat.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "cairn/od/io/point_cloud.hpp"
#include "cairn/sources/frame.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "helpers.hpp"
#include "io/temp_dir.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

double Elevation(const Eigen::Vector3f& p) {
  return std::atan2(double{p.z()}, std::hypot(double{p.x()}, double{p.y()}));
}

// ---------------------------------------------------------------------------------------
// MRPT's sample rawlogs

TEST(DecodeMrptDatasets, KinectFrameIsAnUndistortedPinholeDepthImage) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "tests_rgbd");
  const Frame frame = test::FirstFrame(path);
  ASSERT_NE(frame.depth(), nullptr);
  EXPECT_EQ(frame.label, "OPENNI2");
  EXPECT_EQ(frame.mrpt_class, "CObservation3DRangeScan");
  EXPECT_EQ(frame.entry, 0);
  EXPECT_EQ(frame.index, 0);
  EXPECT_NEAR(frame.stamp_s, 1462879443.617188, 1e-5);
  const DepthImage& depth = *frame.depth();
  EXPECT_EQ(depth.model.width, 640);
  EXPECT_EQ(depth.model.height, 480);
  EXPECT_NEAR(depth.model.fx, 572.88277, 1e-4);
  EXPECT_NEAR(depth.model.fy, 542.73998, 1e-4);
  EXPECT_NEAR(depth.model.cx, 314.64917, 1e-4);
  EXPECT_NEAR(depth.model.cy, 240.16046, 1e-4);
  // sensorPose is the identity: the optical frame is the body's x-forward frame turned.
  EXPECT_TRUE(frame.T_body_sensor.linear().isApprox(RotationFluFromOptical(), 1e-12));
  EXPECT_NEAR(frame.T_body_sensor.translation().norm(), 0.0, 1e-12);
  // The lens has distortion (k1 = -0.0047): the image was resampled and every recorded
  // pixel knows where it went.
  ASSERT_EQ(depth.decoded_of_source.size(), 640u * 480u);
  int valid = 0;
  float nearest = 1e9f, farthest = 0.0f;
  for (float z : depth.depth_m) {
    if (z <= 0.0f) continue;
    ++valid;
    nearest = std::min(nearest, z);
    farthest = std::max(farthest, z);
  }
  // The recording has 273225 returns between 1.624 and 2.560 m; resampling repeats a few
  // pixels where the lens stretches the image and loses a margin.
  EXPECT_GT(valid, 270000);
  EXPECT_LT(valid, 276000);
  EXPECT_NEAR(nearest, 1.624f, 1e-4f);
  EXPECT_NEAR(farthest, 2.560f, 1e-4f);
  // The frame looks at a bookshelf before a wall, level: up is the optical -y.
  EXPECT_TRUE(UpInSensor(frame).isApprox(Eigen::Vector3d(0.0, -1.0, 0.0), 1e-12));
}

TEST(DecodeMrptDatasets, KinectPixelsLandOnTheirUndistortedRays) {
  // Each recorded pixel goes (decoded_of_source) to the decoded pixel whose pinhole ray the
  // lens images onto it, to within the nearest-pixel rounding, and the decoded depth is the
  // recorded one. (MRPT 2.5's own unprojection ignores the distortion coefficients, so the
  // reference is the lens model itself.)
  CAIRN_MRPT_DATASET_OR_SKIP(path, "tests_rgbd");
  Expected<std::vector<::mrpt::obs::CObservation::Ptr>> read = ReadRawlogObservations(path);
  ASSERT_TRUE(read.ok()) << read.error().message;
  auto scan = std::dynamic_pointer_cast<::mrpt::obs::CObservation3DRangeScan>(read->front());
  ASSERT_TRUE(scan);
  Expected<Frame> frame = DecodeRangeScan(*scan);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const DepthImage& depth = *frame->depth();
  const od::PinholeModel& m = depth.model;
  int compared = 0, same_depth = 0;
  double worst_px = 0.0;
  for (int r = 0; r < 480; ++r) {
    for (int c = 0; c < 640; ++c) {
      const std::int32_t u = depth.decoded_of_source[static_cast<std::size_t>(r) * 640 + c];
      if (u < 0) continue;
      const Eigen::Vector2d imaged = test::Distort(
          {(u % 640 - m.cx) / m.fx, (u / 640 - m.cy) / m.fy}, scan->cameraParams.dist);
      const double dc = m.fx * imaged.x() + m.cx - c, dr = m.fy * imaged.y() + m.cy - r;
      worst_px = std::max({worst_px, std::abs(dc), std::abs(dr)});
      ++compared;
      same_depth += depth.depth_m[u] == static_cast<float>(scan->rangeImage(r, c) * double{scan->rangeUnits});
    }
  }
  EXPECT_GT(compared, 640 * 480 * 99 / 100);  // a barrel lens: the rim looks past the pinhole
  EXPECT_LT(worst_px, 0.75);
  EXPECT_GT(same_depth, 640 * 480 * 99 / 100);  // the rest share a decoded pixel
}

TEST(DecodeMrptDatasets, VelodyneScanPointsKeepTheirLasers) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "test_velodyne_VLP16");
  const Frame frame = test::FirstFrame(path);
  ASSERT_NE(frame.points(), nullptr);
  EXPECT_EQ(frame.label, "Velodyne1_SCAN");
  EXPECT_EQ(frame.mrpt_class, "CObservationVelodyneScan");
  EXPECT_NEAR(frame.stamp_s, 1519637061.085268, 1e-5);
  EXPECT_NEAR((frame.T_body_sensor.translation() - Eigen::Vector3d(0, 0, 0.09)).norm(), 0, 1e-6);
  EXPECT_TRUE(frame.T_body_sensor.linear().isIdentity(1e-12));
  const PointScan& scan = *frame.points();
  // 75 packets, one firing of 16 lasers every 0.4 deg as MRPT decodes them: 11305 returns
  // beyond 1 m.
  ASSERT_EQ(scan.points.size(), 11305u);
  ASSERT_EQ(scan.laser_id.size(), scan.points.size());
  ASSERT_EQ(scan.rows.size(), scan.points.size());
  ASSERT_EQ(scan.cols.size(), scan.points.size());
  ASSERT_EQ(scan.model.height(), 16);
  EXPECT_NEAR(scan.model.ring_elevation_rad.front(), 15.0 * kDegToRad, 1e-9);
  EXPECT_NEAR(scan.model.ring_elevation_rad.back(), -15.0 * kDegToRad, 1e-9);
  EXPECT_EQ(scan.model.width, 905);  // 900 firings over 357.8 deg: 0.3976 deg a firing
  std::set<int> cells;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const int laser = scan.laser_id[i];
    ASSERT_GE(laser, 0);
    ASSERT_LT(laser, 16);
    // VLP-16 lasers interleave: even ids from -15 deg up, odd ids from +1 deg up.
    const double elevation = (laser % 2 == 0 ? -15.0 + laser : laser) * kDegToRad;
    ASSERT_NEAR(Elevation(scan.points[i]), elevation, 1e-4) << "point " << i;
    ASSERT_NEAR(scan.model.ring_elevation_rad[scan.rows[i]], elevation, 1e-9) << "point " << i;
    // The column's azimuth is the point's, within half a step and the firing's spread.
    const double azimuth = std::atan2(double{scan.points[i].y()}, double{scan.points[i].x()});
    const double off = std::remainder(scan.model.ColumnAzimuth(scan.cols[i]) - azimuth, 2 * kPi);
    ASSERT_LT(std::abs(off), 0.5 * scan.model.azimuth_step_rad() + 0.15 * kDegToRad)
        << "point " << i;
    cells.insert(scan.rows[i] * scan.model.width + scan.cols[i]);
    const double range = scan.points[i].norm();
    ASSERT_GT(range, 1.0);
    ASSERT_LT(range, 120.0);
  }
  // Single-return mode: one return per laser and firing, so every point has its own cell.
  EXPECT_EQ(cells.size(), scan.points.size());
}

TEST(DecodeMrptDatasets, RotatingScanIsTheSameScanAsThePackets) {
  // rot_scan_velodyne.rawlog is test_velodyne_VLP16.rawlog converted by MRPT into a
  // CObservationRotatingScan (same time, same returns): decoded independently (MRPT's
  // generatePointCloud on the packets; our geometry on the range image), they must agree.
  CAIRN_MRPT_DATASET_OR_SKIP(packets_path, "test_velodyne_VLP16");
  CAIRN_MRPT_DATASET_OR_SKIP(rotating_path, "rot_scan_velodyne");
  const Frame packets = test::FirstFrame(packets_path);
  const Frame rotating = test::FirstFrame(rotating_path);
  ASSERT_NE(packets.points(), nullptr);
  ASSERT_NE(rotating.points(), nullptr);
  EXPECT_EQ(rotating.mrpt_class, "CObservationRotatingScan");
  EXPECT_EQ(rotating.label, packets.label);
  EXPECT_EQ(rotating.stamp_s, packets.stamp_s);
  EXPECT_TRUE(rotating.T_body_sensor.isApprox(packets.T_body_sensor, 1e-12));
  const PointScan& a = *packets.points();
  const PointScan& b = *rotating.points();
  ASSERT_EQ(a.points.size(), b.points.size());
  EXPECT_EQ(b.model.ring_elevation_rad, a.model.ring_elevation_rad);
  double worst_m = 0.0, worst_deg = 0.0;
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    ASSERT_EQ(a.laser_id[i], b.laser_id[i]) << "point " << i;  // both in firing order
    ASSERT_EQ(a.rows[i], b.rows[i]) << "point " << i;
    ASSERT_NEAR(a.points[i].norm(), b.points[i].norm(), 1e-3) << "point " << i;
    worst_m = std::max(worst_m, double((a.points[i] - b.points[i]).norm()));
    const double da = std::remainder(
        std::atan2(double{a.points[i].y()}, double{a.points[i].x()}) -
            std::atan2(double{b.points[i].y()}, double{b.points[i].x()}),
        2 * kPi);
    worst_deg = std::max(worst_deg, std::abs(da) / kDegToRad);
  }
  // The range image keeps one azimuth per firing (MRPT's interpolation between lasers is
  // lost) and spaces firings evenly over the sweep, while the packets' firings are 0.39 or
  // 0.40 deg apart: 0.31 deg at most (0.49 m at 90 m).
  EXPECT_LT(worst_deg, 0.32);
  EXPECT_LT(worst_m, 0.5);
}

// ---------------------------------------------------------------------------------------
// Synthetic range cameras

// A slanted plane: z-depth grows with the row and the column.
double Slanted(int c, int r) { return 2.0 + 0.05 * r + 0.013 * c; }

TEST(DecodeRangeScans, RangeAndDepthConventionsGiveTheSameZDepth) {
  const auto as_depth = test::MakeScan(40, 30, 35.0, Slanted, true);
  const auto as_range = test::MakeScan(40, 30, 35.0, Slanted, false);
  Expected<Frame> a = DecodeRangeScan(*as_depth);
  Expected<Frame> b = DecodeRangeScan(*as_range);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_TRUE(a->depth()->decoded_of_source.empty());  // no distortion: the same grid
  for (int r = 0; r < 30; ++r) {
    for (int c = 0; c < 40; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * 40 + c;
      ASSERT_NEAR(a->depth()->depth_m[i], Slanted(c, r), 0.5e-4 + 1e-6);
      ASSERT_NEAR(b->depth()->depth_m[i], Slanted(c, r), 1e-4) << "row " << r << ", col " << c;
    }
  }
}

TEST(DecodeRangeScans, SensorPoseIsMrptsRangeCameraFrame) {
  // A camera on the body, 1.2 m up and pitched down 20 deg: MRPT's unprojection with the
  // sensor pose and ours through T_body_sensor give the same body-frame points.
  auto scan = test::MakeScan(24, 18, 20.0, Slanted, false);
  scan->sensorPose = ::mrpt::poses::CPose3D(0.4, -0.1, 1.2, 0.3, 20.0 * kDegToRad, 0.05);
  Expected<Frame> frame = DecodeRangeScan(*scan);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  ::mrpt::maps::CSimplePointsMap points;
  ::mrpt::obs::T3DPointsProjectionParams params;
  params.takeIntoAccountSensorPoseOnRobot = true;
  params.MAKE_ORGANIZED = false;
  scan->unprojectInto(points, params);
  ASSERT_EQ(points.size(), 24u * 18u);
  for (int r = 0, n = 0; r < 18; ++r) {
    for (int c = 0; c < 24; ++c, ++n) {
      float x, y, z;
      points.getPoint(static_cast<std::size_t>(n), x, y, z);
      const Eigen::Vector3d ours = frame->T_body_sensor * frame->depth()->model.Unproject(
                                                              c, r, frame->depth()->depth_m[n]);
      ASSERT_NEAR((ours - Eigen::Vector3d(x, y, z)).norm(), 0.0, 1e-4);
    }
  }
  // Level body: up in the sensor is the body's z seen from the pitched camera.
  const Eigen::Vector3d up = UpInSensor(*frame);
  EXPECT_NEAR(up.dot(frame->T_body_sensor.linear().transpose() * Eigen::Vector3d::UnitZ()), 1.0,
              1e-12);
  EXPECT_NEAR(std::asin(-up.z()), 20.0 * kDegToRad, 1e-9);  // optical axis 20 deg below horizon
}

TEST(DecodeRangeScans, LensDistortionIsRemovedWithoutInventingDepths) {
  // Two walls, 2 m on the left half of the recorded image and 4 m on the right, seen
  // through a barrel lens: the decoded image holds only those two depths (nearest-pixel
  // resampling), and each recorded pixel goes to a decoded pixel on its own ray, or nowhere
  // when its ray leaves the undistorted image (the lens sees wider than the pinhole).
  auto scan = test::MakeScan(64, 48, 40.0, [](int c, int) { return c < 32 ? 2.0 : 4.0; }, true);
  scan->cameraParams.dist[0] = -0.25;  // k1
  scan->cameraParams.dist[1] = 0.05;   // k2
  Expected<Frame> frame = DecodeRangeScan(*scan);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const DepthImage& depth = *frame->depth();
  int twos = 0, fours = 0, holes = 0;
  for (float z : depth.depth_m) {
    if (z == 0.0f) {
      ++holes;
    } else if (std::abs(z - 2.0f) < 1e-4f) {
      ++twos;
    } else {
      ASSERT_NEAR(z, 4.0f, 1e-4f);
      ++fours;
    }
  }
  EXPECT_GT(twos, 1000);
  EXPECT_GT(fours, 1000);
  EXPECT_EQ(holes, 0);  // barrel distortion: every undistorted pixel was seen
  // Each recorded pixel against the lens model: the decoded pixel it went to is imaged onto
  // it within the rounding; pixels that went nowhere see rays outside the pinhole image.
  int outside = 0;
  for (int r = 0; r < 48; ++r) {
    for (int c = 0; c < 64; ++c) {
      const std::int32_t u = depth.decoded_of_source[static_cast<std::size_t>(r) * 64 + c];
      if (u < 0) {
        ++outside;
        const Eigen::Vector2d ray =
            test::Undistort({(c - 31.5) / 40.0, (r - 23.5) / 40.0}, scan->cameraParams.dist);
        const double col = 40.0 * ray.x() + 31.5, row = 40.0 * ray.y() + 23.5;
        EXPECT_TRUE(col < -0.5 || row < -0.5 || col > 63.5 || row > 47.5)
            << "recorded pixel " << c << ", " << r << " col " << col << " row " << row;
        continue;
      }
      const Eigen::Vector2d imaged = test::Distort(
          {(u % 64 - 31.5) / 40.0, (u / 64 - 23.5) / 40.0}, scan->cameraParams.dist);
      EXPECT_LE(std::abs(40.0 * imaged.x() + 31.5 - c), 0.75) << "recorded pixel " << c << ", " << r;
      EXPECT_LE(std::abs(40.0 * imaged.y() + 23.5 - r), 0.75) << "recorded pixel " << c << ", " << r;
    }
  }
  EXPECT_GT(outside, 0);  // the corners of the recording
}

TEST(DecodeRangeScans, ExternallyStoredRangeImagesAreLoaded) {
  test::TempDir dir;
  const fs::path rawlog = dir / "ext.rawlog";
  const fs::path images = dir / "ext_Images";
  fs::create_directories(images);
  auto scan = test::MakeScan(16, 12, 10.0, Slanted, true);
  const auto expected = scan->rangeImage;
  scan->rangeImage_convertToExternalStorage("scan0.bin", images.string() + "/");
  ASSERT_TRUE(scan->rangeImage_isExternallyStored());
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(rawlog, 0);
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(*scan).ok());
    ASSERT_TRUE(writer->Commit().ok());
  }
  const Frame frame = test::FirstFrame(rawlog);
  ASSERT_NE(frame.depth(), nullptr);
  for (int r = 0; r < 12; ++r) {
    for (int c = 0; c < 16; ++c) {
      ASSERT_NEAR(frame.depth()->depth_m[static_cast<std::size_t>(r) * 16 + c],
                  expected(r, c) * 0.0001, 1e-6);
    }
  }
  // Without its images folder the error names what is missing.
  fs::remove_all(images);
  Expected<RawlogSource> source = RawlogSource::Open(rawlog);
  ASSERT_TRUE(source.ok());
  Expected<std::optional<Frame>> missing = source->NextFrame();
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("ext.rawlog: entry 0"), std::string::npos)
      << missing.error().message;
  EXPECT_NE(missing.error().message.find("externally stored"), std::string::npos)
      << missing.error().message;
}

TEST(DecodeRangeScans, BadScansNameTheField) {
  auto scan = test::MakeScan(16, 12, 10.0, Slanted, true);
  scan->cameraParams.ncols = 20;
  Expected<Frame> frame = DecodeRangeScan(*scan);
  ASSERT_FALSE(frame.ok());
  EXPECT_NE(frame.error().message.find("CObservation3DRangeScan 'RGBD': cameraParams are 20x12"),
            std::string::npos)
      << frame.error().message;
  scan = test::MakeScan(16, 12, 10.0, Slanted, true);
  scan->cameraParams.setIntrinsicParamsFromValues(0.0, 10.0, 7.5, 5.5);
  frame = DecodeRangeScan(*scan);
  ASSERT_FALSE(frame.ok());
  EXPECT_NE(frame.error().message.find("fx"), std::string::npos) << frame.error().message;
  scan->hasRangeImage = false;
  EXPECT_EQ(WhyNoRangeData(*scan), std::optional<std::string>("no range image"));
}

// ---------------------------------------------------------------------------------------
// Point clouds

// 8 rings from +7 to -7 deg, 360 azimuth steps, ranges varying, shuffled; ring of each point.
struct RingCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<int> ring;
};
RingCloud MakeRingCloud(std::uint32_t seed) {
  RingCloud cloud;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> range(2.0, 30.0), jitter(-0.02, 0.02);
  for (int ring = 0; ring < 8; ++ring) {
    const double e = (7.0 - 2.0 * ring) * kDegToRad;
    for (int step = 0; step < 360; ++step) {
      if ((step * 7 + ring) % 13 == 0) continue;  // some rays without return
      const double a = (step + jitter(rng)) * kDegToRad, d = range(rng);
      cloud.points.emplace_back(d * std::cos(e) * std::cos(a), d * std::cos(e) * std::sin(a),
                                d * std::sin(e));
      cloud.ring.push_back(ring);
    }
  }
  std::vector<std::size_t> order(cloud.points.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  RingCloud shuffled;
  for (std::size_t i : order) {
    shuffled.points.push_back(cloud.points[i]);
    shuffled.ring.push_back(cloud.ring[i]);
  }
  shuffled.points.emplace_back(0.0f, 0.0f, 0.0f);  // no return
  shuffled.ring.push_back(-1);
  return shuffled;
}

TEST(DecodePointClouds, RingsAndColumnsComeFromTheData) {
  const RingCloud truth = MakeRingCloud(7);
  auto map = ::mrpt::maps::CPointsMapXYZI::Create();
  for (std::size_t i = 0; i < truth.points.size(); ++i) {
    map->insertPointFast(truth.points[i].x(), truth.points[i].y(), truth.points[i].z());
    map->setPointIntensity(i, static_cast<float>(i % 100) / 100.0f);
  }
  ::mrpt::obs::CObservationPointCloud obs;
  obs.sensorLabel = "LIDAR";
  obs.pointcloud = map;
  obs.sensorPose = ::mrpt::poses::CPose3D(0.2, 0.0, 1.8, 0.0, 0.0, 0.0);
  Expected<Frame> frame = DecodePointCloud(obs);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const PointScan& scan = *frame->points();
  ASSERT_EQ(scan.points.size(), truth.points.size());
  EXPECT_EQ(scan.intensity.size(), truth.points.size());
  EXPECT_FLOAT_EQ(scan.intensity[37], 0.37f);
  ASSERT_EQ(scan.model.height(), 8);
  EXPECT_EQ(scan.model.width, 360);
  for (int ring = 0; ring < 8; ++ring) {
    EXPECT_NEAR(scan.model.ring_elevation_rad[ring], (7.0 - 2.0 * ring) * kDegToRad, 1e-5);
  }
  for (std::size_t i = 0; i < truth.points.size(); ++i) {
    ASSERT_EQ(scan.rows[i], truth.ring[i]) << "point " << i;
    if (truth.ring[i] < 0) continue;
    ASSERT_EQ(scan.cols[i], scan.model.Column(truth.points[i].cast<double>()));
  }
  EXPECT_NE(scan.layout.find("8 rows (elevation clusters)"), std::string::npos) << scan.layout;
  EXPECT_TRUE(frame->T_body_sensor.translation().isApprox(Eigen::Vector3d(0.2, 0, 1.8)));
}

TEST(DecodePointClouds, CloudsWithoutRingsGetEvenElevationBins) {
  // Points scattered over a band of elevations (a non-spinning sensor): no gaps, no rings.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> elevation(-10 * kDegToRad, 10 * kDegToRad),
      azimuth(-kPi, kPi);
  auto map = ::mrpt::maps::CSimplePointsMap::Create();
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 20000; ++i) {
    const double e = elevation(rng), a = azimuth(rng);
    points.emplace_back(5 * std::cos(e) * std::cos(a), 5 * std::cos(e) * std::sin(a),
                        5 * std::sin(e));
    map->insertPointFast(points.back().x(), points.back().y(), points.back().z());
  }
  ::mrpt::obs::CObservationPointCloud obs;
  obs.sensorLabel = "TOF";
  obs.pointcloud = map;
  Expected<Frame> frame = DecodePointCloud(obs);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const PointScan& scan = *frame->points();
  EXPECT_NE(scan.layout.find("uniform elevation bins"), std::string::npos) << scan.layout;
  ASSERT_GT(scan.model.height(), 1);
  // Each point lies in its row's elevation bin (rows top first, even bins).
  const auto& e = scan.model.ring_elevation_rad;
  const double bin = e[0] - e[1];
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_GE(scan.rows[i], 0);
    ASSERT_NEAR(Elevation(points[i]), e[scan.rows[i]], 0.5 * bin + 1e-6) << "point " << i;
  }
}

// ---------------------------------------------------------------------------------------
// Stereo

::mrpt::img::CImage Pattern(int width, int height, int shift) {
  ::mrpt::img::CImage image(width, height, ::mrpt::img::CH_RGB);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const auto v = static_cast<std::uint8_t>(((c + shift) * 37 + r * 11) % 251);
      image.setPixel(c, r, ::mrpt::img::TColor(v, v, v));
    }
  }
  return image;
}

TEST(DecodeStereo, RectifiedPairGivesGreyImagesPinholeAndBaseline) {
  ::mrpt::obs::CObservationStereoImages stereo;
  stereo.sensorLabel = "STEREO";
  stereo.imageLeft = Pattern(64, 48, 0);
  stereo.imageRight = Pattern(64, 48, 4);
  stereo.hasImageRight = true;
  for (auto* camera : {&stereo.leftCamera, &stereo.rightCamera}) {
    camera->ncols = 64;
    camera->nrows = 48;
    camera->setIntrinsicParamsFromValues(50.0, 50.0, 31.5, 23.5);
  }
  stereo.rightCameraPose = ::mrpt::poses::CPose3DQuat(::mrpt::poses::CPose3D(0.12, 0, 0, 0, 0, 0));
  const ::mrpt::poses::CPose3D camera_pose(0.3, 0.0, 1.1, -90 * kDegToRad, 0.0, -100 * kDegToRad);
  stereo.cameraPose = ::mrpt::poses::CPose3DQuat(camera_pose);
  Expected<Frame> frame = DecodeStereoImages(stereo);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const StereoPair& pair = *frame->stereo();
  EXPECT_FALSE(pair.rectified_here);
  EXPECT_EQ(pair.left.width, 64);
  EXPECT_EQ(pair.right.height, 48);
  EXPECT_EQ(pair.left.at(5, 7), (7 * 37 + 5 * 11) % 251);
  EXPECT_EQ(pair.right.at(5, 7), (11 * 37 + 5 * 11) % 251);
  EXPECT_DOUBLE_EQ(pair.left_model.fx, 50.0);
  EXPECT_DOUBLE_EQ(pair.left_model.cy, 23.5);
  EXPECT_NEAR(pair.baseline_m, 0.12, 1e-12);
  EXPECT_TRUE(frame->T_body_sensor.isApprox(FromCPose3D(camera_pose), 1e-9));
  // Optical frame on a level body, camera 10 deg down: up is mostly -y, tilted towards -z.
  const Eigen::Vector3d up = UpInSensor(*frame);
  EXPECT_NEAR(up.y(), -std::cos(10 * kDegToRad), 1e-9);
  EXPECT_NEAR(up.z(), -std::sin(10 * kDegToRad), 1e-9);

  stereo.hasImageRight = false;
  EXPECT_EQ(WhyNoRangeData(stereo), std::optional<std::string>("no right image"));
}

TEST(DecodeStereo, RawPairsAreRectifiedWithMrpt) {
  ::mrpt::obs::CObservationStereoImages stereo;
  stereo.imageLeft = Pattern(80, 60, 0);
  stereo.imageRight = Pattern(80, 60, 3);
  stereo.hasImageRight = true;
  for (auto* camera : {&stereo.leftCamera, &stereo.rightCamera}) {
    camera->ncols = 80;
    camera->nrows = 60;
    camera->setIntrinsicParamsFromValues(60.0, 60.0, 40.0, 29.0);
    camera->dist[0] = -0.1;
  }
  stereo.rightCameraPose =
      ::mrpt::poses::CPose3DQuat(::mrpt::poses::CPose3D(0.1, 0.002, 0, 0.01, 0, 0));
  Expected<Frame> frame = DecodeStereoImages(stereo);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  const StereoPair& pair = *frame->stereo();
  EXPECT_TRUE(pair.rectified_here);
  EXPECT_EQ(pair.left.width, 80);
  EXPECT_EQ(pair.left.height, 60);
  EXPECT_NEAR(pair.baseline_m, std::hypot(0.1, 0.002), 1e-6);
  EXPECT_GT(pair.left_model.fx, 0.0);
}

// ---------------------------------------------------------------------------------------
// IMU and odometry

TEST(DecodeImuAndOdometry, RawSamplesFromTheAccelerometerAndGyroFields) {
  using namespace ::mrpt::obs;
  CObservationIMU imu;
  imu.sensorLabel = "IMU";
  imu.timestamp = ToMrptTime(7.25);
  imu.set(IMU_ROLL, 0.05);
  imu.set(IMU_PITCH, -0.1);
  EXPECT_FALSE(DecodeImuSample(imu).has_value());  // attitude only
  imu.set(IMU_X_ACC, 0.3);
  imu.set(IMU_Y_ACC, -0.2);
  EXPECT_FALSE(DecodeImuSample(imu).has_value());  // two axes are not a reading
  imu.set(IMU_Z_ACC, 9.7);
  std::optional<ImuSample> sample = DecodeImuSample(imu);
  ASSERT_TRUE(sample);
  EXPECT_NEAR(sample->stamp_s, 7.25, 1e-9);
  ASSERT_TRUE(sample->specific_force_mps2);
  EXPECT_EQ(*sample->specific_force_mps2, Eigen::Vector3d(0.3, -0.2, 9.7));
  EXPECT_FALSE(sample->angular_rate_radps);
  imu.set(IMU_WX, 0.01);
  imu.set(IMU_WY, 0.02);
  imu.set(IMU_WZ, -0.03);
  imu.sensorPose = ::mrpt::poses::CPose3D(0, 0, 0, 0.0, 0.1, 0.0);
  sample = DecodeImuSample(imu);
  ASSERT_TRUE(sample && sample->angular_rate_radps);
  EXPECT_EQ(*sample->angular_rate_radps, Eigen::Vector3d(0.01, 0.02, -0.03));
  EXPECT_TRUE(sample->T_body_imu.isApprox(FromCPose3D(imu.sensorPose), 1e-12));
  EXPECT_EQ(sample->label, "IMU");
}

TEST(DecodeImuAndOdometry, AttitudeFromAnglesOrQuaternion) {
  ::mrpt::obs::CObservationIMU imu;
  imu.sensorLabel = "IMU";
  imu.set(::mrpt::obs::IMU_WZ, 0.1);
  EXPECT_FALSE(DecodeImu(imu).has_value());  // rates only
  imu.set(::mrpt::obs::IMU_ROLL, 0.05);
  imu.set(::mrpt::obs::IMU_PITCH, -0.1);
  std::optional<ImuAttitude> attitude = DecodeImu(imu);
  ASSERT_TRUE(attitude);
  EXPECT_EQ(attitude->roll_rad, 0.05);
  EXPECT_EQ(attitude->pitch_rad, -0.1);
  EXPECT_FALSE(attitude->yaw_rad);

  ::mrpt::obs::CObservationIMU quaternion;
  const ::mrpt::poses::CPose3D pose(0, 0, 0, 1.0, 0.2, -0.3);  // yaw, pitch, roll
  const auto q = ::mrpt::poses::CPose3DQuat(pose).quat();
  quaternion.set(::mrpt::obs::IMU_ORI_QUAT_W, q.r());
  quaternion.set(::mrpt::obs::IMU_ORI_QUAT_X, q.x());
  quaternion.set(::mrpt::obs::IMU_ORI_QUAT_Y, q.y());
  quaternion.set(::mrpt::obs::IMU_ORI_QUAT_Z, q.z());
  attitude = DecodeImu(quaternion);
  ASSERT_TRUE(attitude);
  EXPECT_NEAR(*attitude->yaw_rad, 1.0, 1e-12);
  EXPECT_NEAR(attitude->pitch_rad, 0.2, 1e-12);
  EXPECT_NEAR(attitude->roll_rad, -0.3, 1e-12);
  EXPECT_TRUE(RotationFromImu(*attitude).isApprox(pose.getRotationMatrix().asEigen(), 1e-12));

  ::mrpt::obs::CObservationOdometry odometry;
  odometry.sensorLabel = "ODOM";
  odometry.timestamp = ToMrptTime(100.5);
  odometry.odometry = ::mrpt::poses::CPose2D(1.0, -2.0, 0.5);
  const OdometrySample sample = DecodeOdometry(odometry);
  EXPECT_EQ(sample.source, "ODOM");
  EXPECT_NEAR(sample.stamp_s, 100.5, 1e-9);
  EXPECT_TRUE(sample.T_odom_body.isApprox(
      FromCPose3D(::mrpt::poses::CPose3D(1.0, -2.0, 0.0, 0.5, 0.0, 0.0)), 1e-12));
}

TEST(DecodeImuAndOdometry, ImuTiltsTheUpVector) {
  // The body pitched nose down by 0.1 rad and rolled 0.05 rad: up in the body is
  // R_world_body^T z, then the sensor's mount.
  Frame frame;
  frame.T_body_sensor.linear() = RotationFluFromOptical();
  ImuAttitude imu;
  imu.pitch_rad = 0.1;
  imu.roll_rad = 0.05;
  imu.yaw_rad = 2.0;  // plays no part
  frame.imu = imu;
  const Eigen::Matrix3d R_world_body =
      (Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Eigen::Vector3d expected =
      RotationFluFromOptical().transpose() * R_world_body.transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_TRUE(UpInSensor(frame).isApprox(expected, 1e-12));
  // Pitch > 0 is nose down: the camera then looks down, so up leans towards the optical -z.
  EXPECT_LT(UpInSensor(frame).z(), -0.09);
}

}  // namespace
}  // namespace cairn::sources
