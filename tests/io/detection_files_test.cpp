#include "cairn/od/io/detection_files.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "temp_dir.hpp"

namespace cairn::od::io {
namespace {

Detection SmallDetection(std::int32_t first_id = 1, std::int32_t second_id = 2) {
  Detection d;
  d.width = 5;
  d.height = 4;
  d.labels = {0, first_id, first_id, 0, 0,          //
              0, first_id, 0,        0, second_id,  //
              0, 0,        0,        0, second_id,  //
              0, 0,        0,        0, 0};
  SegmentFeatures a;
  a.id = 1;
  a.point_count = 3;
  a.raised_count = 2;
  a.bbox_min = {1, -1, 0};
  a.bbox_max = {2, 1, 0.5};
  a.bbox_perimeter_m = 6;
  a.bbox_volume_m3 = 1;
  a.slope_mean_rad = kPi / 3;
  a.slope_max_rad = kPi / 2;
  a.height_max_m = 0.5;
  SegmentFeatures b = a;
  b.id = 2;
  b.point_count = 2;
  d.segments = {a, b};
  d.stats.obstacle_points = 5;
  return d;
}

Classification SmallClassification() {
  Classification c;
  c.verdicts = {SegmentVerdict{1, SegmentClass::kKept, ""},
                SegmentVerdict{2, SegmentClass::kRejected, "points 2 < 3"}};
  c.kept = 1;
  c.rejected = 1;
  return c;
}

Grid<float> SmallDepth() {
  Grid<float> depth{5, 4, {}};
  for (int i = 0; i < 20; ++i) depth.data.push_back(i == 0 ? 0.0f : 1.0f + 0.1f * i);
  return depth;
}

TEST(SegmentsJson, TextIsWhatTheFileHolds) {
  const test::TempDir dir;
  RunDescription run;
  run.method = "column";
  const Expected<std::string> text =
      SegmentsJsonText("here", SmallDetection(), SmallClassification(), run);
  ASSERT_TRUE(text.ok()) << text.error().message;
  ASSERT_TRUE(
      WriteSegmentsJson(dir / "segments.json", SmallDetection(), SmallClassification(), run).ok());
  std::ifstream in(dir / "segments.json");
  const std::string file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(*text, file);
  Classification short_of_one = SmallClassification();
  short_of_one.verdicts.pop_back();
  const Expected<std::string> bad = SegmentsJsonText("here", SmallDetection(), short_of_one, run);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().message.rfind("here: ", 0), 0u) << bad.error().message;
}

TEST(SegmentsPng, RoundTripsTheLabels) {
  test::TempDir dir;
  // Ids beyond 8 bits and up to the 16-bit limit survive.
  const Detection d = SmallDetection(300, 65535);
  ASSERT_TRUE(WriteSegmentsPng(dir / "segments.png", d).ok());
  Expected<Grid<std::int32_t>> back = ReadSegmentsPng(dir / "segments.png");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->width, 5);
  EXPECT_EQ(back->height, 4);
  EXPECT_EQ(back->data, d.labels);
  // And it is a plain 16-bit PNG that other tools read the same way.
  const cv::Mat raw = cv::imread((dir / "segments.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  EXPECT_EQ(raw.at<std::uint16_t>(1, 4), 65535);
}

TEST(SegmentsPng, IdsBeyondSixteenBitsAreAnError) {
  test::TempDir dir;
  Status s = WriteSegmentsPng(dir / "segments.png", SmallDetection(1, 70000));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("70000"), std::string::npos) << s.message();
  EXPECT_TRUE(dir.List().empty());
}

TEST(ClassesPng, HoldsTheClassOfEachPixel) {
  test::TempDir dir;
  ASSERT_TRUE(WriteClassesPng(dir / "classes.png", SmallDetection(), SmallClassification()).ok());
  Expected<Grid<std::uint8_t>> back = ReadClassesPng(dir / "classes.png");
  ASSERT_TRUE(back.ok()) << back.error().message;
  const std::vector<std::uint8_t> expected = {0, 1, 1, 0, 0,  //
                                              0, 1, 0, 0, 2,  //
                                              0, 0, 0, 0, 2,  //
                                              0, 0, 0, 0, 0};
  EXPECT_EQ(back->data, expected);
}

TEST(AtomicFile, LeavesNoTemporaryFile) {
  test::TempDir dir;
  ASSERT_TRUE(util::WriteFileAtomic(dir / "a.txt", "first").ok());
  ASSERT_TRUE(util::WriteFileAtomic(dir / "a.txt", "second").ok());  // replaces
  EXPECT_EQ(dir.List(), std::vector<std::string>{"a.txt"});
  std::ifstream in(dir / "a.txt");
  std::string text;
  std::getline(in, text);
  EXPECT_EQ(text, "second");
}

TEST(AtomicFile, AFailedWriteLeavesNothingAndNamesTheFile) {
  test::TempDir dir;
  // The rename fails: the destination is a directory that is not empty.
  std::filesystem::create_directories(dir / "target" / "inside");
  Status s = util::WriteFileAtomic(dir / "target", "data");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find((dir / "target").string()), std::string::npos);
  EXPECT_EQ(dir.List(), std::vector<std::string>{"target"});
  // The directory does not exist: nothing can be created.
  Status missing = util::WriteFileAtomic(dir / "no" / "a.txt", "data");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.message().find((dir / "no" / "a.txt").string()), std::string::npos);
}

// A log whose committed length a checkpoint keeps: each write cuts what lies beyond the
// length it is given (an interrupted write's tail) and leaves the bytes before it alone.
TEST(AtomicFile, WriteAtCutsTheTailAndKeepsTheCommittedBytes) {
  test::TempDir dir;
  const std::filesystem::path log = dir / "log.txt";
  const auto read = [&log]() {
    std::ifstream in(log, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  ASSERT_TRUE(util::WriteFileAt(log, 0, "one\n").ok());  // created
  ASSERT_TRUE(util::WriteFileAt(log, 4, "two\nhalf").ok());
  EXPECT_EQ(read(), "one\ntwo\nhalf");
  ASSERT_TRUE(util::WriteFileAt(log, 8, "three\n").ok());  // "half" was never committed
  EXPECT_EQ(read(), "one\ntwo\nthree\n");
  ASSERT_TRUE(util::WriteFileAt(log, 0, "").ok());  // a fresh start empties it
  EXPECT_EQ(read(), "");
  // Asked to keep more than the file holds: refused, naming the file, and left as it was.
  ASSERT_TRUE(util::WriteFileAt(log, 0, "abc").ok());
  const Status s = util::WriteFileAt(log, 10, "x");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find(log.string()), std::string::npos) << s.message();
  EXPECT_EQ(read(), "abc");
  EXPECT_FALSE(util::WriteFileAt(dir / "no" / "log.txt", 0, "x").ok());
}

TEST(DetectionFiles, WritesTheFiveFilesIntoANewDirectory) {
  test::TempDir dir;
  RunDescription run;
  run.method = "column";
  run.depth_file = "frame.png";
  run.settings.detector.min_slope_rad = kPi / 4;
  run.settings.rules.min_points = 3;
  const std::filesystem::path out = dir / "a" / "b";
  Expected<DetectionFiles> files =
      WriteDetectionFiles(out, SmallDepth(), SmallDetection(), SmallClassification(), run);
  ASSERT_TRUE(files.ok()) << files.error().message;
  EXPECT_EQ(dir.List(out), (std::vector<std::string>{"classes.png", "overlay.png", "segments.json",
                                                     "segments.png", "segments_color.png"}));
  EXPECT_EQ(files->segments_json, out / "segments.json");

  std::ifstream in(files->segments_json);
  const nlohmann::json doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["image"]["width"], 5);
  EXPECT_EQ(doc["image"]["height"], 4);
  EXPECT_EQ(doc["method"], "column");
  EXPECT_EQ(doc["rules_applied"], true);
  EXPECT_EQ(doc["inputs"]["depth"], "frame.png");
  EXPECT_TRUE(doc["inputs"]["config"].is_null());
  EXPECT_NEAR(doc["config"]["detector"]["min_slope_deg"].get<double>(), 45.0, 1e-9);
  EXPECT_EQ(doc["config"]["rules"]["min_points"], 3);
  EXPECT_EQ(doc["summary"]["kept"], 1);
  EXPECT_EQ(doc["summary"]["rejected"], 1);
  ASSERT_EQ(doc["segments"].size(), 2u);
  const nlohmann::json& s1 = doc["segments"][0];
  EXPECT_EQ(s1["id"], 1);
  EXPECT_EQ(s1["class"], "kept");
  EXPECT_EQ(s1["rejection_reason"], "");
  EXPECT_NEAR(s1["slope_mean_deg"].get<double>(), 60.0, 1e-9);
  EXPECT_NEAR(s1["slope_max_deg"].get<double>(), 90.0, 1e-9);
  EXPECT_EQ(s1["bbox_max_m"], nlohmann::json::array({2.0, 1.0, 0.5}));
  for (const char* key : {"point_count", "raised_count", "bbox_min_m", "bbox_perimeter_m",
                          "bbox_volume_m3", "ground_height_m", "height_mean_m", "height_max_m",
                          "centroid_m", "range_mean_m", "range_min_m", "rows_px", "cols_px"}) {
    EXPECT_TRUE(s1.contains(key)) << key;
  }
  EXPECT_EQ(doc["segments"][1]["class"], "rejected");
  EXPECT_EQ(doc["segments"][1]["rejection_reason"], "points 2 < 3");
}

TEST(DetectionFiles, OverlayPaintsKeptBlueRejectedRedOverGreyDepth) {
  test::TempDir dir;
  ASSERT_TRUE(
      WriteOverlayPng(dir / "o.png", SmallDepth(), SmallDetection(), SmallClassification()).ok());
  const cv::Mat o = cv::imread((dir / "o.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(o.type(), CV_8UC3);
  const cv::Vec3b kept = o.at<cv::Vec3b>(0, 1), rejected = o.at<cv::Vec3b>(1, 4);
  EXPECT_GT(kept[0], 180);  // BGR: blue
  EXPECT_LT(kept[2], 100);
  EXPECT_GT(rejected[2], 180);  // red
  EXPECT_LT(rejected[0], 100);
  EXPECT_EQ(o.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));  // no return: black
  // Grey elsewhere, nearer brighter.
  const cv::Vec3b near = o.at<cv::Vec3b>(0, 3), far = o.at<cv::Vec3b>(3, 4);
  EXPECT_EQ(near[0], near[1]);
  EXPECT_EQ(near[1], near[2]);
  EXPECT_GT(near[0], far[0]);
}

TEST(DetectionFiles, SegmentColoursAreDeterministicAndDistinct) {
  std::set<std::array<std::uint8_t, 3>> seen;
  for (int id = 1; id <= 32; ++id) {
    EXPECT_EQ(SegmentColor(id), SegmentColor(id));
    seen.insert(SegmentColor(id));
    // Neighbouring ids differ clearly.
    const auto a = SegmentColor(id), b = SegmentColor(id + 1);
    const int diff = std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]);
    EXPECT_GT(diff, 60) << id;
  }
  EXPECT_EQ(seen.size(), 32u);
}

TEST(DetectionFiles, SizeMismatchIsAnError) {
  test::TempDir dir;
  Grid<float> depth{4, 4, std::vector<float>(16, 1.0f)};
  Status s = WriteOverlayPng(dir / "o.png", depth, SmallDetection(), SmallClassification());
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("o.png"), std::string::npos);
}

TEST(DetectionFiles, AnOutputPathThatIsAFileIsAnError) {
  test::TempDir dir;
  dir.Write("out", "a file");
  Expected<DetectionFiles> files = WriteDetectionFiles(dir / "out", SmallDepth(), SmallDetection(),
                                                       SmallClassification(), RunDescription{});
  ASSERT_FALSE(files.ok());
  EXPECT_NE(files.error().message.find((dir / "out").string()), std::string::npos);
}

}  // namespace
}  // namespace cairn::od::io
