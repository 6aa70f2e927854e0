// The rule classifier on hand-made detections: each rule rejects with a reason that names
// its measure, a zero threshold disables it, and the class image follows the labels.
#include "cairn/od/rules.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"

namespace cairn::od {
namespace {

// A segment that passes every rule used below by a wide margin.
SegmentFeatures Big(int id) {
  SegmentFeatures f;
  f.id = id;
  f.point_count = 500;
  f.raised_count = 4000;
  f.bbox_min = {5.0, -0.5, -1.6};
  f.bbox_max = {6.0, 0.5, -0.6};
  f.bbox_perimeter_m = 4.0;
  f.bbox_volume_m3 = 1.0;
  f.slope_mean_rad = 1.2;
  f.slope_max_rad = 1.5;
  f.ground_height_m = -1.6;
  f.height_mean_m = 0.5;
  f.height_max_m = 1.0;
  return f;
}

// A 4x3 detection: segment 1 on the left column, segment 2 on the right one, the middle
// no obstacle.
Detection TwoSegments(const SegmentFeatures& first, const SegmentFeatures& second) {
  Detection d;
  d.width = 4;
  d.height = 3;
  // clang-format off
  d.labels = {1, 0, 0, 2,
              1, 0, 0, 2,
              1, 0, 0, 0};
  // clang-format on
  d.segments = {first, second};
  d.segments[0].id = 1;
  d.segments[1].id = 2;
  d.stats.obstacle_points = 5;
  return d;
}

Classification MustClassify(const Detection& d, const RuleConfig& rules) {
  Expected<Classification> c = Classify(d, rules);
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().message);
  return c.ok() ? std::move(c).value() : Classification{};
}

bool Contains(const std::string& text, const std::string& word) {
  return text.find(word) != std::string::npos;
}

struct RuleCase {
  std::string name;
  std::function<void(RuleConfig&)> set_threshold;   // makes the rule active
  std::function<void(SegmentFeatures&)> make_fail;  // makes the segment fail only it
  std::vector<std::string> words;                   // the reason names the measure
};

std::vector<RuleCase> Cases() {
  return {
      {"points",
       [](RuleConfig& r) { r.min_points = 20; },
       [](SegmentFeatures& f) { f.point_count = 12; },
       {"point"}},
      {"volume",
       [](RuleConfig& r) { r.min_volume_m3 = 0.01; },
       [](SegmentFeatures& f) { f.bbox_volume_m3 = 0.004; },
       {"volume"}},
      {"perimeter",
       [](RuleConfig& r) { r.min_perimeter_m = 1.5; },
       [](SegmentFeatures& f) { f.bbox_perimeter_m = 0.8; },
       {"perimeter"}},
      {"slope mean",
       [](RuleConfig& r) { r.min_slope_mean_rad = 1.0; },
       [](SegmentFeatures& f) { f.slope_mean_rad = 0.9; },
       {"slope", "mean"}},
      {"slope max",
       [](RuleConfig& r) { r.min_slope_max_rad = 1.4; },
       [](SegmentFeatures& f) { f.slope_max_rad = 1.3; },
       {"slope", "max"}},
      {"height mean",
       [](RuleConfig& r) { r.min_height_mean_m = 0.3; },
       [](SegmentFeatures& f) { f.height_mean_m = 0.2; },
       {"height", "mean"}},
      {"height max",
       [](RuleConfig& r) { r.min_height_max_m = 0.6; },
       [](SegmentFeatures& f) { f.height_max_m = 0.45; },
       {"height", "max"}},
      {"raised points",
       [](RuleConfig& r) { r.min_raised = 50; },
       [](SegmentFeatures& f) { f.raised_count = 10; },
       {"raised"}},
  };
}

TEST(Rules, EachRuleRejectsWithAReasonNamingItsMeasure) {
  for (const RuleCase& rc : Cases()) {
    RuleConfig rules = RuleConfig::None();
    rc.set_threshold(rules);
    ASSERT_TRUE(rules.Validate().ok()) << rc.name;
    SegmentFeatures failing = Big(0);
    rc.make_fail(failing);
    const Classification c = MustClassify(TwoSegments(Big(0), failing), rules);
    ASSERT_EQ(c.verdicts.size(), 2u) << rc.name;
    EXPECT_EQ(c.verdicts[0].id, 1);
    EXPECT_EQ(c.verdicts[0].cls, SegmentClass::kKept) << rc.name;
    EXPECT_EQ(c.verdicts[0].reason, "") << rc.name;
    EXPECT_EQ(c.verdicts[1].id, 2);
    EXPECT_EQ(c.verdicts[1].cls, SegmentClass::kRejected) << rc.name;
    for (const std::string& word : rc.words) {
      EXPECT_TRUE(Contains(c.verdicts[1].reason, word))
          << rc.name << ": reason '" << c.verdicts[1].reason << "' lacks '" << word << "'";
    }
    EXPECT_EQ(c.kept, 1) << rc.name;
    EXPECT_EQ(c.rejected, 1) << rc.name;
  }
}

TEST(Rules, ReasonGivesTheValueAndTheThreshold) {
  RuleConfig rules = RuleConfig::None();
  rules.min_volume_m3 = 0.01;
  SegmentFeatures small = Big(0);
  small.bbox_volume_m3 = 0.004;
  const Classification c = MustClassify(TwoSegments(Big(0), small), rules);
  const std::string& reason = c.verdicts[1].reason;
  EXPECT_TRUE(Contains(reason, "0.004")) << reason;
  EXPECT_TRUE(Contains(reason, "0.01")) << reason;
}

TEST(Rules, ReasonNamesEveryRuleFailed) {
  RuleConfig rules = RuleConfig::None();
  rules.min_volume_m3 = 0.01;
  rules.min_perimeter_m = 1.5;
  rules.min_points = 20;
  SegmentFeatures f = Big(0);
  f.bbox_volume_m3 = 0.004;
  f.bbox_perimeter_m = 0.8;  // points still pass
  const Classification c = MustClassify(TwoSegments(Big(0), f), rules);
  EXPECT_EQ(c.verdicts[1].cls, SegmentClass::kRejected);
  EXPECT_TRUE(Contains(c.verdicts[1].reason, "volume")) << c.verdicts[1].reason;
  EXPECT_TRUE(Contains(c.verdicts[1].reason, "perimeter")) << c.verdicts[1].reason;
  EXPECT_FALSE(Contains(c.verdicts[1].reason, "point")) << c.verdicts[1].reason;
}

TEST(Rules, ValueEqualToTheThresholdPasses) {
  // Thresholds are least values: a measure equal to one passes.
  for (const RuleCase& rc : Cases()) {
    RuleConfig rules = RuleConfig::None();
    rc.set_threshold(rules);
    SegmentFeatures f = Big(0);
    f.point_count = rules.min_points > 0 ? rules.min_points : f.point_count;
    f.bbox_volume_m3 = rules.min_volume_m3 > 0 ? rules.min_volume_m3 : f.bbox_volume_m3;
    f.bbox_perimeter_m = rules.min_perimeter_m > 0 ? rules.min_perimeter_m : f.bbox_perimeter_m;
    f.slope_mean_rad = rules.min_slope_mean_rad > 0 ? rules.min_slope_mean_rad : f.slope_mean_rad;
    f.slope_max_rad = rules.min_slope_max_rad > 0 ? rules.min_slope_max_rad : f.slope_max_rad;
    f.height_mean_m = rules.min_height_mean_m > 0 ? rules.min_height_mean_m : f.height_mean_m;
    f.height_max_m = rules.min_height_max_m > 0 ? rules.min_height_max_m : f.height_max_m;
    f.raised_count = rules.min_raised > 0 ? rules.min_raised : f.raised_count;
    const Classification c = MustClassify(TwoSegments(Big(0), f), rules);
    EXPECT_EQ(c.verdicts[1].cls, SegmentClass::kKept) << rc.name << ": " << c.verdicts[1].reason;
  }
}

TEST(Rules, ZeroThresholdsKeepEverySegment) {
  // The smallest segment there can be: one point, no volume, nothing.
  SegmentFeatures tiny;
  tiny.point_count = 1;
  const Detection d = TwoSegments(tiny, Big(0));
  const Classification c = MustClassify(d, RuleConfig::None());
  ASSERT_EQ(c.verdicts.size(), 2u);
  for (const SegmentVerdict& v : c.verdicts) {
    EXPECT_EQ(v.cls, SegmentClass::kKept);
    EXPECT_EQ(v.reason, "");
  }
  EXPECT_EQ(c.kept, 2);
  EXPECT_EQ(c.rejected, 0);

  const Classification all = KeepAll(d);
  ASSERT_EQ(all.verdicts.size(), 2u);
  EXPECT_EQ(all.verdicts[0].id, 1);
  EXPECT_EQ(all.verdicts[1].id, 2);
  EXPECT_EQ(all.verdicts[1].cls, SegmentClass::kKept);
  EXPECT_EQ(all.kept, 2);
  EXPECT_EQ(all.rejected, 0);
}

TEST(Rules, EmptyDetectionHasNoVerdicts) {
  Detection d;
  d.width = 2;
  d.height = 2;
  d.labels.assign(4, 0);
  RuleConfig rules = RuleConfig::None();
  rules.min_points = 10;
  const Classification c = MustClassify(d, rules);
  EXPECT_TRUE(c.verdicts.empty());
  EXPECT_EQ(c.kept + c.rejected, 0);
  EXPECT_EQ(ClassImage(d, c), std::vector<std::uint8_t>(4, 0));
}

TEST(Rules, ClassImageFollowsTheLabels) {
  RuleConfig rules = RuleConfig::None();
  rules.min_points = 100;
  SegmentFeatures small = Big(0);
  small.point_count = 2;
  const Detection d = TwoSegments(Big(0), small);
  const Classification c = MustClassify(d, rules);
  const std::vector<std::uint8_t> image = ClassImage(d, c);
  const auto kept = static_cast<std::uint8_t>(SegmentClass::kKept);
  const auto rejected = static_cast<std::uint8_t>(SegmentClass::kRejected);
  // clang-format off
  const std::vector<std::uint8_t> expected = {kept, 0, 0, rejected,
                                              kept, 0, 0, rejected,
                                              kept, 0, 0, 0};
  // clang-format on
  EXPECT_EQ(image, expected);
  EXPECT_EQ(static_cast<int>(SegmentClass::kNone), 0);
  EXPECT_EQ(static_cast<int>(SegmentClass::kKept), 1);
  EXPECT_EQ(static_cast<int>(SegmentClass::kRejected), 2);
}

TEST(RuleConfig, ValidationNamesTheBadThreshold) {
  EXPECT_TRUE(RuleConfig().Validate().ok());
  EXPECT_TRUE(RuleConfig::None().Validate().ok());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::pair<std::string, std::function<void(RuleConfig&)>>> bad = {
      {"min_points", [](RuleConfig& r) { r.min_points = -1; }},
      {"min_volume", [](RuleConfig& r) { r.min_volume_m3 = -0.1; }},
      {"min_perimeter", [nan](RuleConfig& r) { r.min_perimeter_m = nan; }},
      {"min_slope_mean", [](RuleConfig& r) { r.min_slope_mean_rad = -1.0; }},
      {"min_slope_max", [](RuleConfig& r) { r.min_slope_max_rad = INFINITY; }},
      {"min_height_mean", [](RuleConfig& r) { r.min_height_mean_m = -0.2; }},
      {"min_height_max", [nan](RuleConfig& r) { r.min_height_max_m = nan; }},
      {"min_raised", [](RuleConfig& r) { r.min_raised = -5; }},
  };
  for (const auto& [field, spoil] : bad) {
    RuleConfig rules = RuleConfig::None();
    spoil(rules);
    const Status s = rules.Validate();
    ASSERT_FALSE(s.ok()) << field;
    EXPECT_TRUE(Contains(s.message(), field)) << field << ": '" << s.message() << "'";
    // Classify refuses it too.
    EXPECT_FALSE(Classify(TwoSegments(Big(0), Big(0)), rules).ok()) << field;
  }
}

}  // namespace
}  // namespace cairn::od
