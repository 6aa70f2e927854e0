// sources::ReadAhead: the frames of the source it wraps, in order, with the same skips,
// errors and end, while each next frame is read on a thread of its own.
#include "cairn/sources/frame_source.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace cairn::sources {
namespace {

// A source of `count` frames, frame k at stamp k; frame `missing` is skipped as missing and
// frame `broken` is an error (-1: none). Each read takes a millisecond, so that a read ahead
// is still under way when the caller asks for more. It records the order of its calls.
class ScriptedSource final : public FrameSource {
 public:
  ScriptedSource(int count, int missing, int broken, std::vector<std::string>* calls)
      : count_(count),
        missing_(missing),
        broken_(broken),
        calls_(calls),
        trajectory_(Trajectory::FromOdometry({{0.0, Eigen::Isometry3d::Identity(), "scripted"}}, {}).value()) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    calls_->push_back("next " + std::to_string(next_));
    if (next_ == count_) return std::optional<SequenceFrame>();
    const int k = next_++;
    if (k == broken_) return Error{"frame " + std::to_string(k) + ": corrupt"};
    SequenceFrame frame;
    frame.index = k;
    frame.stamp_s = k;
    frame.name = "frame " + std::to_string(k);
    if (k == missing_) {
      frame.skip = SourceSkip::kMissing;
      frame.skip_detail = "not there";
    }
    return std::optional<SequenceFrame>(std::move(frame));
  }
  Status Skip(int n) override {
    calls_->push_back("skip " + std::to_string(n));
    next_ = std::min(count_, next_ + n);
    return Status::Ok();
  }
  int total() const override { return count_; }
  SourceInfo Describe() const override { return {{"kind", std::string("scripted")}}; }
  const Trajectory& trajectory() const override { return trajectory_; }

 private:
  int count_, missing_, broken_, next_ = 0;
  std::vector<std::string>* calls_;
  Trajectory trajectory_;
};

// What a caller sees, frame by frame: "k", "k missing", "error: ...", "end".
std::vector<std::string> Drain(FrameSource& source, int skip_first = 0) {
  std::vector<std::string> seen;
  if (skip_first > 0) {
    if (Status s = source.Skip(skip_first); !s) seen.push_back("skip error: " + s.message());
  }
  for (;;) {
    Expected<std::optional<SequenceFrame>> next = source.Next();
    if (!next) {
      seen.push_back("error: " + next.error().message);
      return seen;
    }
    if (!*next) {
      seen.push_back("end");
      return seen;
    }
    const SequenceFrame& f = **next;
    seen.push_back(std::to_string(f.index) + (f.used() ? "" : " missing") + " at " +
                   std::to_string(f.stamp_s) + " " + f.name);
  }
}

TEST(ReadAhead, GivesTheSameFramesSkipsErrorsAndEndAsTheSourceItWraps) {
  struct Case {
    int count, missing, broken, skip_first;
  };
  for (const Case c : {Case{6, 2, -1, 0}, Case{6, -1, 3, 0}, Case{0, -1, -1, 0}, Case{5, 4, -1, 2},
                       Case{4, -1, -1, 9}, Case{1, 0, 0, 0}}) {
    std::vector<std::string> plain_calls, ahead_calls;
    ScriptedSource plain(c.count, c.missing, c.broken, &plain_calls);
    std::unique_ptr<FrameSource> ahead =
        ReadAhead(std::make_unique<ScriptedSource>(c.count, c.missing, c.broken, &ahead_calls));
    const std::vector<std::string> expected = Drain(plain, c.skip_first);
    EXPECT_EQ(Drain(*ahead, c.skip_first), expected)
        << c.count << " frames, missing " << c.missing << ", broken " << c.broken << ", skip "
        << c.skip_first;
    // Nothing is read past an error or the end.
    EXPECT_EQ(ahead_calls, plain_calls);
  }
}

TEST(ReadAhead, ReadsTheNextFrameWhileTheCallerWorks) {
  std::vector<std::string> calls;
  std::unique_ptr<FrameSource> ahead =
      ReadAhead(std::make_unique<ScriptedSource>(3, -1, -1, &calls));
  ASSERT_TRUE(ahead->Next().value().has_value());
  // The caller's work on frame 0: the source is already reading frame 1. The questions
  // about the source wait for that read, then answer.
  EXPECT_EQ(ahead->total(), 3);
  EXPECT_EQ(calls, (std::vector<std::string>{"next 0", "next 1"}));
  EXPECT_EQ(std::get<std::string>(ahead->Describe().at("kind")), "scripted");
  // Skipping passes over the frame read ahead first, then asks the source for the rest.
  EXPECT_TRUE(ahead->Skip(1));
  const Expected<std::optional<SequenceFrame>> last = ahead->Next();
  ASSERT_TRUE(last && *last);
  EXPECT_EQ((*last)->index, 2);
  EXPECT_EQ(ahead->total(), 3);  // waits for the read ahead (of the end) before `calls` is read
  EXPECT_EQ(calls, (std::vector<std::string>{"next 0", "next 1", "next 2", "next 3"}));
  EXPECT_FALSE(ahead->Next().value().has_value());
}

}  // namespace
}  // namespace cairn::sources

namespace cairn::sources {
namespace {

// Same size, returns and points (invalid cells hold NaN, so they are compared by the mask).
bool SameImage(const od::RangeImage& a, const od::RangeImage& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.valid_mask() != b.valid_mask() ||
      a.up() != b.up() || a.valid_count() == 0) {
    return false;
  }
  for (int i = 0; i < a.width() * a.height(); ++i) {
    if (a.valid(i) && a.point(i) != b.point(i)) return false;
  }
  return true;
}

// The one way from a frame to its range image gives what the RangeImage factories give for
// each kind, and names the stereo matching when it is what failed.
TEST(ToRangeImage, EachKindAsItsRangeImageFactoryMakesIt) {
  const Eigen::Vector3d up = Eigen::Vector3d(0.1, -1.0, 0.2).normalized();
  const od::StereoConfig stereo;

  Frame depth_frame;
  DepthImage depth;
  depth.model = od::PinholeModel{8, 6, 5.0, 5.0, 3.5, 2.5};
  for (int i = 0; i < 48; ++i) depth.depth_m.push_back(i % 5 == 0 ? 0.0f : 1.0f + 0.1f * i);
  depth_frame.data = depth;
  Expected<FrameImage> from_depth = ToRangeImage(depth_frame, up, stereo);
  ASSERT_TRUE(from_depth) << from_depth.error().message;
  EXPECT_FALSE(from_depth->stereo);
  EXPECT_TRUE(
      SameImage(from_depth->image, *od::RangeImage::FromDepth(depth.depth_m, depth.model, up)));

  Frame scan_frame;
  PointScan scan;
  scan.model.width = 16;
  scan.model.ring_elevation_rad = {0.1, 0.05, 0.0, -0.05};
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 16; c += 2) {
      const double e = scan.model.ring_elevation_rad[r], a = scan.model.ColumnAzimuth(c);
      scan.points.emplace_back(5 * std::cos(e) * std::cos(a), 5 * std::cos(e) * std::sin(a),
                               5 * std::sin(e));
      scan.rows.push_back(r);
      scan.cols.push_back(c + 1);  // rows and columns of the source are kept as given
    }
  }
  scan_frame.data = scan;
  Expected<FrameImage> from_scan = ToRangeImage(scan_frame, up, stereo);
  ASSERT_TRUE(from_scan) << from_scan.error().message;
  EXPECT_TRUE(SameImage(from_scan->image, *od::RangeImage::FromPoints(scan.points, scan.model, up,
                                                                      scan.rows, scan.cols)));
  EXPECT_FALSE(SameImage(from_scan->image,
                         *od::RangeImage::FromPoints(scan.points, scan.model, up, {}, {})));

  Frame stereo_frame;
  StereoPair pair;
  pair.left = od::Grid<std::uint8_t>{8, 6, std::vector<std::uint8_t>(48, 100)};
  pair.right = od::Grid<std::uint8_t>{4, 6, std::vector<std::uint8_t>(24, 100)};
  pair.left_model = depth.model;
  pair.baseline_m = 0.1;
  stereo_frame.data = pair;
  Expected<FrameImage> from_stereo = ToRangeImage(stereo_frame, up, stereo);
  ASSERT_FALSE(from_stereo);
  EXPECT_EQ(from_stereo.error().message.rfind("stereo: ", 0), 0u) << from_stereo.error().message;
}

}  // namespace
}  // namespace cairn::sources
