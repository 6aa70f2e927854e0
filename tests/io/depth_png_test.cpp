#include "cairn/od/io/depth_png.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cairn/eval/plane_fit.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/range_image.hpp"
#include "temp_dir.hpp"

namespace cairn::od::io {
namespace {

constexpr double kTumScale = 1.0 / 5000.0;

TEST(DepthPng, ReadsTumUnitsAsMetres) {
  test::TempDir dir;
  cv::Mat raw(2, 3, CV_16UC1);
  raw.at<std::uint16_t>(0, 0) = 0;
  raw.at<std::uint16_t>(0, 1) = 5000;
  raw.at<std::uint16_t>(0, 2) = 65535;
  raw.at<std::uint16_t>(1, 0) = 1;
  raw.at<std::uint16_t>(1, 1) = 12345;
  raw.at<std::uint16_t>(1, 2) = 2500;
  ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), raw));

  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", 3, 2, kTumScale);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  EXPECT_EQ(depth->width, 3);
  EXPECT_EQ(depth->height, 2);
  EXPECT_EQ(depth->at(0, 0), 0.0f);  // no return
  EXPECT_FLOAT_EQ(depth->at(0, 1), 1.0f);
  EXPECT_FLOAT_EQ(depth->at(0, 2), 65535.0f / 5000.0f);
  EXPECT_FLOAT_EQ(depth->at(1, 0), 1.0f / 5000.0f);
  EXPECT_FLOAT_EQ(depth->at(1, 1), 12345.0f / 5000.0f);
  EXPECT_FLOAT_EQ(depth->at(1, 2), 0.5f);
}

TEST(DepthPng, WriteThenReadRoundTripsToHalfAUnit) {
  test::TempDir dir;
  Grid<float> depth{4, 3, {}};
  for (int i = 0; i < 12; ++i) depth.data.push_back(0.37f * static_cast<float>(i));
  depth.data[5] = std::numeric_limits<float>::quiet_NaN();  // no return
  depth.data[6] = -2.0f;                                    // no return
  depth.data[7] = 1e-6f;                                    // tiny, still a return
  const double scale = 0.001;
  ASSERT_TRUE(WriteDepthPng(dir / "d.png", depth, scale).ok());
  Expected<Grid<float>> back = ReadDepthPng(dir / "d.png", 4, 3, scale);
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (int i = 0; i < 12; ++i) {
    if (i == 5 || i == 6) {
      EXPECT_EQ(back->data[i], 0.0f) << i;
    } else if (i == 7) {
      EXPECT_FLOAT_EQ(back->data[i], 0.001f);
    } else {
      EXPECT_NEAR(back->data[i], depth.data[i], scale / 2 + 1e-6) << i;
    }
  }
}

TEST(DepthPng, DepthBeyondTheSixteenBitRangeIsAnError) {
  test::TempDir dir;
  Grid<float> depth{1, 1, {14.0f}};  // 70000 units at 1/5000
  Status s = WriteDepthPng(dir / "d.png", depth, kTumScale);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("16-bit range"), std::string::npos) << s.message();
  EXPECT_TRUE(dir.List().empty());
}

TEST(DepthPng, MissingFile) {
  test::TempDir dir;
  Expected<Grid<float>> depth = ReadDepthPng(dir / "none.png", 3, 2, kTumScale);
  ASSERT_FALSE(depth.ok());
  EXPECT_EQ(depth.error().message, (dir / "none.png").string() + ": no such file");
}

TEST(DepthPng, NotAPng) {
  test::TempDir dir;
  dir.Write("d.png", "this is text");
  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", 3, 2, kTumScale);
  ASSERT_FALSE(depth.ok());
  EXPECT_NE(depth.error().message.find("not a PNG"), std::string::npos);
}

TEST(DepthPng, TruncatedPngIsUnreadable) {
  test::TempDir dir;
  cv::Mat raw(20, 30, CV_16UC1, cv::Scalar(1000));
  std::vector<unsigned char> bytes;
  ASSERT_TRUE(cv::imencode(".png", raw, bytes));
  dir.Write("d.png", std::string(bytes.begin(), bytes.begin() + 40));
  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", 30, 20, kTumScale);
  ASSERT_FALSE(depth.ok());
  EXPECT_EQ(depth.error().message, (dir / "d.png").string() + ": unreadable PNG (truncated)");
}

TEST(DepthPng, EightBitIsRejected) {
  test::TempDir dir;
  ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), cv::Mat(2, 3, CV_8UC1, cv::Scalar(9))));
  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", 3, 2, kTumScale);
  ASSERT_FALSE(depth.ok());
  EXPECT_NE(depth.error().message.find("expected a 16-bit single-channel"), std::string::npos);
  EXPECT_NE(depth.error().message.find("got 8-bit single-channel"), std::string::npos)
      << depth.error().message;
}

TEST(DepthPng, MultiChannelIsRejected) {
  test::TempDir dir;
  ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), cv::Mat(2, 3, CV_16UC3, cv::Scalar(9))));
  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", 3, 2, kTumScale);
  ASSERT_FALSE(depth.ok());
  EXPECT_NE(depth.error().message.find("got 16-bit 3-channel"), std::string::npos)
      << depth.error().message;
}

TEST(DepthPng, SizeDifferentFromTheIntrinsics) {
  test::TempDir dir;
  ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), cv::Mat(2, 3, CV_16UC1, cv::Scalar(9))));
  CameraIntrinsics cam;
  cam.model = PinholeModel{4, 2, 1.0, 1.0, 1.5, 1.0};
  cam.depth_scale_m = kTumScale;
  Expected<Grid<float>> depth = ReadDepthPng(dir / "d.png", cam);
  ASSERT_FALSE(depth.ok());
  EXPECT_NE(depth.error().message.find("3x2"), std::string::npos) << depth.error().message;
  EXPECT_NE(depth.error().message.find("width 4"), std::string::npos) << depth.error().message;
}

// ---------------------------------------------------------------------------------------
// 32-bit float TIFF depth, and the reader that tells the formats apart.

TEST(DepthTiff, FloatRoundTripIsExactAndNoReturnIsZero) {
  test::TempDir dir;
  Grid<float> depth{5, 3, {}};
  for (int i = 0; i < 15; ++i) depth.data.push_back(0.1234567f * static_cast<float>(i * i) + 1e-3f);
  depth.data[3] = std::numeric_limits<float>::quiet_NaN();
  depth.data[4] = -1.0f;
  depth.data[5] = std::numeric_limits<float>::infinity();
  depth.data[6] = 123456.78f;  // far beyond any 16-bit PNG scale
  ASSERT_TRUE(WriteDepthTiff(dir / "d.tiff", depth).ok());
  Expected<Grid<float>> back = ReadDepthImage(dir / "d.tiff", 5, 3, 1.0);
  ASSERT_TRUE(back.ok()) << back.error().message;
  for (int i = 0; i < 15; ++i) {
    if (i >= 3 && i <= 5) {
      EXPECT_EQ(back->data[i], 0.0f) << i;
    } else {
      EXPECT_EQ(back->data[i], depth.data[i]) << i;  // bit for bit
    }
  }
  // depth_scale does not apply to float metres.
  Expected<Grid<float>> scaled = ReadDepthImage(dir / "d.tiff", 5, 3, 0.001);
  ASSERT_TRUE(scaled.ok());
  EXPECT_EQ(scaled->data[7], depth.data[7]);
}

TEST(DepthTiff, NonFiniteValuesWrittenByOthersReadAsNoReturn) {
  test::TempDir dir;
  cv::Mat raw(1, 4, CV_32FC1);
  raw.at<float>(0, 0) = 2.5f;
  raw.at<float>(0, 1) = std::numeric_limits<float>::quiet_NaN();
  raw.at<float>(0, 2) = -std::numeric_limits<float>::infinity();
  raw.at<float>(0, 3) = 0.0f;
  ASSERT_TRUE(cv::imwrite((dir / "d.tif").string(), raw));
  Expected<Grid<float>> depth = ReadDepthTiff(dir / "d.tif", 4, 1, 1.0);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  EXPECT_EQ(depth->data, (std::vector<float>{2.5f, 0.0f, 0.0f, 0.0f}));
}

TEST(DepthTiff, SixteenBitTiffIsScaledLikeAPng) {
  test::TempDir dir;
  cv::Mat raw(1, 2, CV_16UC1);
  raw.at<std::uint16_t>(0, 0) = 5000;
  raw.at<std::uint16_t>(0, 1) = 0;
  ASSERT_TRUE(cv::imwrite((dir / "d.tiff").string(), raw));
  Expected<Grid<float>> depth = ReadDepthImage(dir / "d.tiff", 2, 1, kTumScale);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  EXPECT_FLOAT_EQ(depth->data[0], 1.0f);
  EXPECT_EQ(depth->data[1], 0.0f);
}

TEST(DepthTiff, WrongTypeSizeOrContentAreErrors) {
  test::TempDir dir;
  ASSERT_TRUE(cv::imwrite((dir / "rgb.tiff").string(), cv::Mat(2, 3, CV_8UC3, cv::Scalar(1))));
  Expected<Grid<float>> rgb = ReadDepthImage(dir / "rgb.tiff", 3, 2, 1.0);
  ASSERT_FALSE(rgb.ok());
  EXPECT_NE(rgb.error().message.find("expected a 32-bit float (or 16-bit) single-channel TIFF, "
                                     "got 8-bit 3-channel"),
            std::string::npos)
      << rgb.error().message;

  ASSERT_TRUE(cv::imwrite((dir / "f.tiff").string(), cv::Mat(2, 3, CV_32FC1, cv::Scalar(1))));
  Expected<Grid<float>> size = ReadDepthImage(dir / "f.tiff", 4, 2, 1.0);
  ASSERT_FALSE(size.ok());
  EXPECT_NE(size.error().message.find("image is 3x2 px, the intrinsics say width 4"),
            std::string::npos)
      << size.error().message;

  std::vector<unsigned char> bytes;
  ASSERT_TRUE(cv::imencode(".tiff", cv::Mat(20, 30, CV_32FC1, cv::Scalar(2)), bytes));
  dir.Write("cut.tiff", std::string(bytes.begin(), bytes.begin() + 100));
  Expected<Grid<float>> cut = ReadDepthImage(dir / "cut.tiff", 30, 20, 1.0);
  ASSERT_FALSE(cut.ok());
  EXPECT_NE(cut.error().message.find("unreadable TIFF"), std::string::npos) << cut.error().message;

  dir.Write("d.txt", "1 2 3");
  Expected<Grid<float>> text = ReadDepthImage(dir / "d.txt", 3, 1, 1.0);
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.error().message, (dir / "d.txt").string() +
                                      ": not a depth image (expected a 16-bit PNG or a 32-bit "
                                      "float TIFF)");
}

TEST(DepthImage, PngsAreReadByTheSignatureWhateverTheirName) {
  test::TempDir dir;
  cv::Mat raw(1, 2, CV_16UC1);
  raw.at<std::uint16_t>(0, 0) = 2500;
  raw.at<std::uint16_t>(0, 1) = 7;
  std::vector<unsigned char> bytes;
  ASSERT_TRUE(cv::imencode(".png", raw, bytes));
  dir.Write("depth.bin", std::string(bytes.begin(), bytes.end()));
  Expected<Grid<float>> depth = ReadDepthImage(dir / "depth.bin", 2, 1, 0.001);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  EXPECT_FLOAT_EQ(depth->data[0], 2.5f);
  EXPECT_FLOAT_EQ(depth->data[1], 0.007f);
}

TEST(DepthImage, TheTumFrameReadsAtScale5000) {
  const std::filesystem::path file =
      std::filesystem::path(CAIRN_SHARED_DATASETS) / "rgbd-tum-frame" / "TUM_depth.png";
  if (!std::filesystem::exists(file)) {
    GTEST_SKIP() << file.string() << " not found: this test needs ../shared/datasets";
  }
  CameraIntrinsics tum;  // TUM's default intrinsics; only size and scale matter here
  tum.model = PinholeModel{640, 480, 525.0, 525.0, 319.5, 239.5};
  tum.depth_scale_m = kTumScale;
  Expected<Grid<float>> depth = ReadDepthImage(file, tum);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  const cv::Mat raw = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  std::vector<float> valid;
  for (int r = 0; r < 480; ++r) {
    for (int c = 0; c < 640; ++c) {
      const std::uint16_t units = raw.at<std::uint16_t>(r, c);
      ASSERT_FLOAT_EQ(depth->at(r, c), static_cast<float>(units / 5000.0));
      if (units != 0) valid.push_back(depth->at(r, c));
    }
  }
  // A Kinect in an office (measured: 248,250 returns, 1.46 m nearest, median 2.42 m,
  // farthest 9.33 m). Read at the wrong scale (1/1000) the median would be 12 m.
  std::sort(valid.begin(), valid.end());
  EXPECT_EQ(valid.size(), 248250u);
  EXPECT_NEAR(valid.front(), 1.464f, 1e-4f);
  EXPECT_NEAR(valid[valid.size() / 2], 2.415f, 1e-3f);
  EXPECT_NEAR(valid.back(), 9.331f, 1e-4f);
}

TEST(DepthImage, TheTumOfficeIsFurnitureStandingOnAFloorOfFeet) {
  // datasets/real/REPORT.md: the TUM office frame with datasets/real/tum-kinect.yaml (up
  // measured on the floor) and config/default.yaml. The partition, the desk and the chairs
  // are obstacles; the floor between and around them lies within reach of them, so by the
  // paper's definition it joins their segments, as their foot.
  const std::filesystem::path data = std::filesystem::path(CAIRN_SHARED_DATASETS) / "rgbd-tum-frame";
  if (!std::filesystem::exists(data / "TUM_depth.png")) {
    GTEST_SKIP() << data.string() << " not found: this test needs ../shared/datasets";
  }
  const std::filesystem::path root = CAIRN_SOURCE_DIR;
  Expected<CameraIntrinsics> camera = LoadIntrinsics(root / "datasets" / "real" / "tum-kinect.yaml");
  ASSERT_TRUE(camera.ok()) << camera.error().message;
  Expected<DetectSettings> settings =
      LoadDetectSettings(root / "config" / "default.yaml", {"map", "tilt", "frames"});
  ASSERT_TRUE(settings.ok()) << settings.error().message;
  Expected<Grid<float>> depth = ReadDepthImage(data / "TUM_depth.png", *camera);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  Expected<RangeImage> image = RangeImage::FromDepth(depth->data, camera->model, camera->up);
  ASSERT_TRUE(image.ok()) << image.error().message;
  // The up vector of tum-kinect.yaml is the floor's normal, as its comment says: the plane
  // through every other pixel of two floor patches.
  std::vector<Eigen::Vector3d> floor_points;
  for (const auto& [r0, r1, c0, c1] : {std::array<int, 4>{430, 480, 250, 360},
                                       std::array<int, 4>{300, 480, 600, 640}}) {
    for (int r = r0; r < r1; r += 2) {
      for (int c = c0; c < c1; c += 2) {
        if (image->valid(r * 640 + c)) floor_points.push_back(image->point(r * 640 + c));
      }
    }
  }
  const eval::PlaneFit plane = eval::FitPlane(floor_points);
  EXPECT_EQ(plane.points, 1387);
  EXPECT_LT(plane.rms_m, 0.011);
  EXPECT_NEAR(plane.height_m, 1.79, 0.01);
  EXPECT_LT(std::acos(std::min(1.0, plane.normal.dot(camera->up.normalized()))), 0.2 * M_PI / 180)
      << "floor normal " << plane.normal.transpose();

  Expected<Detection> d = Detect(*image, settings->detector);
  ASSERT_TRUE(d.ok()) << d.error().message;
  // Share of the returns in a box of the image that are obstacle points, and feet.
  struct Share {
    int returns = 0, obstacle = 0, foot = 0;
  };
  const auto share = [&](int r0, int r1, int c0, int c1) {
    Share s;
    for (int r = r0; r < r1; ++r) {
      for (int c = c0; c < c1; ++c) {
        const int i = r * 640 + c;
        if (!image->valid(i)) continue;
        ++s.returns;
        s.obstacle += d->is_obstacle(i) ? 1 : 0;
        s.foot += d->is_foot(i) ? 1 : 0;
      }
    }
    return s;
  };
  const Share floor = share(440, 480, 250, 360);      // between the chairs
  const Share partition = share(30, 90, 330, 560);    // the cork partition behind the desk
  const Share red_chair = share(280, 380, 40, 180);   // the red chair's back and seat
  ASSERT_GT(floor.returns, 2500);
  ASSERT_GT(partition.returns, 10000);
  ASSERT_GT(red_chair.returns, 8000);
  // Measured: floor 2996 of 2996 returns foot, partition 13800 of 13800 and chair 12511 of
  // 13643 (the floor seen under its seat is foot) obstacle points that are no foot.
  EXPECT_GT(floor.foot, floor.returns * 99 / 100);
  EXPECT_GT(partition.obstacle - partition.foot, partition.returns * 98 / 100);
  EXPECT_GT(red_chair.obstacle - red_chair.foot, red_chair.returns * 88 / 100);
  std::printf("floor %d/%d foot, partition %d/%d, chair %d/%d raised obstacle\n", floor.foot,
              floor.returns, partition.obstacle - partition.foot, partition.returns,
              red_chair.obstacle - red_chair.foot, red_chair.returns);
}

}  // namespace
}  // namespace cairn::od::io
