#include "cairn/od/io/depth_png.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

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

}  // namespace
}  // namespace cairn::od::io
