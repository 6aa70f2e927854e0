// The evaluation (cairn::eval) on frames whose scores are known:
//  - hand-made truth and label images where precision, recall, IoU, objects found, false
//    obstacles and segment links can be counted by hand;
//  - the foot band on a rendered pole against the definition, tested pixel by pixel;
//  - sweeps that must be monotonic (what the pair definition guarantees);
//  - the bundled demo frame read from files, and errors that name the file and field;
//  - `cairn eval` end to end (when the command is built).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cairn/eval/figures.hpp"
#include "cairn/eval/methods.hpp"
#include "cairn/eval/report.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::eval {
namespace {

using namespace cairn::sim;  // NOLINT: the synthetic scenes the evaluation is tested on

// Hand-made frames: truth ids and segment labels drawn as text, one character per pixel.
//   truth: '.' terrain, '#' no return, '1'..'9' object ids
//   labels: '.' none, '1'..'9' segment ids

FrameTruth Truth(const std::vector<std::string>& rows, const std::vector<TruthObject>& objects) {
  FrameTruth t;
  t.height = static_cast<int>(rows.size());
  t.width = static_cast<int>(rows[0].size());
  for (const std::string& row : rows) {
    for (const char c : row) t.object_id.push_back(c == '.' ? 0 : c == '#' ? -1 : c - '0');
  }
  t.objects = objects;
  return t;
}

od::Detection Labels(const std::vector<std::string>& rows, int segments) {
  od::Detection d;
  d.height = static_cast<int>(rows.size());
  d.width = static_cast<int>(rows[0].size());
  for (const std::string& row : rows) {
    for (const char c : row) d.labels.push_back(c == '.' ? 0 : c - '0');
  }
  d.segments.resize(segments);
  for (int s = 0; s < segments; ++s) d.segments[s].id = s + 1;
  return d;
}

od::Classification Verdicts(const std::vector<od::SegmentClass>& classes) {
  od::Classification c;
  for (std::size_t s = 0; s < classes.size(); ++s) {
    c.verdicts.push_back({static_cast<int>(s + 1), classes[s], ""});
    (classes[s] == od::SegmentClass::kKept ? c.kept : c.rejected)++;
  }
  return c;
}

FrameScore MustScore(const FrameTruth& truth, const std::vector<std::int32_t>& band,
                     const od::Detection& d, const od::Classification& c,
                     const ScoreOptions& options = {}) {
  Expected<FrameScore> s = ScoreDetection(truth, band, d, c, options);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  if (!s.ok()) std::abort();
  return std::move(s).value();
}

constexpr auto kKept = od::SegmentClass::kKept;
constexpr auto kRejected = od::SegmentClass::kRejected;

// 10 obstacle pixels (object 1); segment 1 (kept) covers 8 of them and 2 terrain pixels;
// segment 2 (rejected) covers 3 terrain pixels and does not count.
const std::vector<std::string> kTruth = {
    "..11111...",  //
    "..11111...",  //
    "......#...",  //
    "..........",
};
const std::vector<std::string> kLabels = {
    ".1111111..",  // 5 object pixels + 2 terrain pixels (cols 1 and 7)
    "..111.....",  // 3 object pixels; 2 missed
    "..........",  // (row 2, col 6 has no return: ignored)
    ".......222",
};

TEST(Score, PointFiguresOnAHandMadeFrame) {
  const FrameTruth truth = Truth(kTruth, {{1, "pole", true}});
  const FrameScore s = MustScore(truth, {}, Labels(kLabels, 2), Verdicts({kKept, kRejected}));
  EXPECT_EQ(s.score.strict.tp, 8);
  EXPECT_EQ(s.score.strict.fp, 2);
  EXPECT_EQ(s.score.strict.fn, 2);
  EXPECT_DOUBLE_EQ(s.score.strict.Precision(), 0.8);
  EXPECT_DOUBLE_EQ(s.score.strict.Recall(), 0.8);
  EXPECT_DOUBLE_EQ(s.score.strict.F1(), 0.8);
  EXPECT_DOUBLE_EQ(s.score.strict.IoU(), 8.0 / 12.0);
  // Without a foot band both counts are the same.
  EXPECT_EQ(s.score.band_excluded.fp, 2);
  EXPECT_EQ(s.score.band_pixels, 0);
}

TEST(Score, FootBandPixelsAreLeftOutOfTheSecondCount) {
  const FrameTruth truth = Truth(kTruth, {{1, "pole", true}});
  // The two terrain pixels segment 1 covers lie in the pole's foot band, and one more
  // terrain pixel no segment covers.
  std::vector<std::int32_t> band(truth.object_id.size(), 0);
  band[0 * 10 + 1] = 1;
  band[0 * 10 + 7] = 1;
  band[1 * 10 + 8] = 1;
  const FrameScore s = MustScore(truth, band, Labels(kLabels, 2), Verdicts({kKept, kRejected}));
  EXPECT_DOUBLE_EQ(s.score.strict.Precision(), 0.8);  // strict is unchanged
  EXPECT_DOUBLE_EQ(s.score.band_excluded.Precision(), 1.0);
  EXPECT_DOUBLE_EQ(s.score.band_excluded.Recall(), 0.8);  // recall is the same both ways
  EXPECT_DOUBLE_EQ(s.score.band_excluded.IoU(), 8.0 / 10.0);
  EXPECT_EQ(s.score.band_pixels, 3);
  // The segment lies entirely on the obstacle or its band: not a false obstacle.
  EXPECT_EQ(s.segments[0].on_obstacles, 10);
  EXPECT_FALSE(s.segments[0].false_obstacle);
}

TEST(Score, RejectedSegmentsAreNotDetections) {
  const FrameTruth truth = Truth(kTruth, {{1, "pole", true}});
  ScoreOptions options;
  options.min_object_pixels = 10;  // the default (20) would leave the 10-pixel pole uncounted
  const FrameScore s =
      MustScore(truth, {}, Labels(kLabels, 2), Verdicts({kRejected, kRejected}), options);
  EXPECT_EQ(s.score.strict.tp, 0);
  EXPECT_EQ(s.score.strict.fp, 0);
  EXPECT_EQ(s.score.strict.fn, 10);
  EXPECT_TRUE(std::isnan(s.score.strict.Precision()));
  EXPECT_DOUBLE_EQ(s.score.strict.Recall(), 0.0);
  EXPECT_EQ(s.score.kept_segments, 0);
  EXPECT_EQ(s.score.objects_found, 0);
  EXPECT_EQ(s.score.objects_counted, 1);
}

TEST(Score, ObjectsFoundAndFalseObstaclesAreCounted) {
  // 1: obstacle, 10 px, 8 detected            -> found
  // 2: obstacle, 10 px, 4 detected (< half)   -> counted, not found
  // 3: obstacle, 3 px (< min_object_pixels)   -> not counted ("small")
  // 4: not an obstacle, 6 px, all detected by kept segment 3 -> a false obstacle
  // segment 4 (kept) lies on terrain only     -> a false obstacle
  // segment 5 (rejected) on terrain           -> neither
  const std::vector<std::string> truth_rows = {
      "11111.22222.333",  //
      "11111.22222.....",
      "444444..........",
      "................",
  };
  const std::vector<std::string> label_rows = {
      "11111.22......",  //
      "111...22......5.",
      "333333.....44...",
      "...........44...",
  };
  std::vector<std::string> t = truth_rows, l = label_rows;
  for (auto& r : t) r.resize(16, '.');
  for (auto& r : l) r.resize(16, '.');
  const FrameTruth truth =
      Truth(t, {{1, "a", true}, {2, "b", true}, {3, "c", true}, {4, "small rock", false}});
  ScoreOptions options;
  options.min_object_pixels = 5;
  const FrameScore s = MustScore(truth, {}, Labels(l, 5),
                                 Verdicts({kKept, kKept, kKept, kKept, kRejected}), options);
  EXPECT_EQ(s.score.objects_counted, 2);
  EXPECT_EQ(s.score.objects_found, 1);
  EXPECT_EQ(s.score.objects_small, 1);
  EXPECT_EQ(s.score.non_obstacles_counted, 1);
  EXPECT_EQ(s.score.non_obstacles_marked, 1);
  EXPECT_EQ(s.score.segments, 5);
  EXPECT_EQ(s.score.kept_segments, 4);
  EXPECT_EQ(s.score.false_obstacles, 2);
  EXPECT_TRUE(s.segments[2].false_obstacle);
  EXPECT_TRUE(s.segments[3].false_obstacle);
  EXPECT_FALSE(s.segments[0].false_obstacle);
  EXPECT_FALSE(s.segments[4].false_obstacle);  // rejected: never a false obstacle
  EXPECT_TRUE(s.objects[0].found);
  EXPECT_FALSE(s.objects[1].found);
  EXPECT_EQ(s.objects[1].detected, 4);
  EXPECT_FALSE(s.objects[2].counted);
  // found_fraction decides: with 0.35 object 2 (4 of 10) is found too.
  options.found_fraction = 0.35;
  EXPECT_EQ(
      MustScore(truth, {}, Labels(l, 5), Verdicts({kKept, kKept, kKept, kKept, kRejected}), options)
          .score.objects_found,
      2);
}

TEST(Score, SegmentsPerObjectAndObjectsPerSegment) {
  // Object 1 split into segments 1 and 2; objects 2 and 3 merged in segment 3.
  const std::vector<std::string> truth_rows = {
      "1111111111.2222.3333",
      "1111111111.2222.3333",
  };
  const std::vector<std::string> label_rows = {
      "11111222223333333333",
      "11111222223333333333",
  };
  const FrameTruth truth = Truth(truth_rows, {{1, "a", true}, {2, "b", true}, {3, "c", true}});
  ScoreOptions options;
  options.min_object_pixels = 4;
  const FrameScore s =
      MustScore(truth, {}, Labels(label_rows, 3), Verdicts({kKept, kKept, kKept}), options);
  EXPECT_EQ(s.score.objects_found, 3);
  EXPECT_EQ(s.objects[0].segments, 2);
  EXPECT_EQ(s.objects[1].segments, 1);
  EXPECT_EQ(s.objects[2].segments, 1);
  EXPECT_EQ(s.score.segments_per_object_max, 2);
  EXPECT_DOUBLE_EQ(s.score.SegmentsPerObject(), 4.0 / 3.0);
  EXPECT_EQ(s.segments[2].objects, 2);
  EXPECT_EQ(s.score.objects_per_segment_max, 2);
  EXPECT_DOUBLE_EQ(s.score.ObjectsPerSegment(), 4.0 / 3.0);
  // Segment 3 takes one pixel of object 2 (of its 8) besides object 3 (8 px): linked when
  // that pixel reaches link_fraction of the smaller side, 8 px (10%: yes; 20%: no).
  const std::vector<std::string> grazing = {
      "1111111111.2223.3333",
      "1111111111.2222.3333",
  };
  const FrameScore g =
      MustScore(truth, {}, Labels(grazing, 3), Verdicts({kKept, kKept, kKept}), options);
  EXPECT_EQ(g.objects[1].segments, 2);
  EXPECT_EQ(g.segments[2].objects, 2);
  options.link_fraction = 0.2;
  const FrameScore g2 =
      MustScore(truth, {}, Labels(grazing, 3), Verdicts({kKept, kKept, kKept}), options);
  EXPECT_EQ(g2.objects[1].segments, 1);
  EXPECT_EQ(g2.segments[2].objects, 1);
  EXPECT_EQ(g2.score.objects_per_segment_max, 1);
}

TEST(Score, SizeMismatchesAndBadOptionsAreErrors) {
  const FrameTruth truth = Truth(kTruth, {{1, "pole", true}});
  EXPECT_FALSE(ScoreDetection(truth, {}, Labels({"...", "..."}, 0), Verdicts({})).ok());
  EXPECT_FALSE(ScoreDetection(truth, {1, 2}, Labels(kLabels, 2), Verdicts({kKept, kKept})).ok());
  EXPECT_FALSE(ScoreDetection(truth, {}, Labels(kLabels, 2), Verdicts({kKept})).ok());
  ScoreOptions bad;
  bad.found_fraction = 0.0;
  const Expected<FrameScore> s =
      ScoreDetection(truth, {}, Labels(kLabels, 2), Verdicts({kKept, kKept}), bad);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("found_fraction"), std::string::npos);
  // An object id the truth does not list.
  const FrameTruth unlisted = Truth(kTruth, {});
  const Expected<FrameScore> u =
      ScoreDetection(unlisted, {}, Labels(kLabels, 2), Verdicts({kKept, kKept}));
  ASSERT_FALSE(u.ok());
  EXPECT_NE(u.error().message.find("not listed"), std::string::npos);
}

TEST(Score, SumsOverFramesRecomputeTheRatios) {
  Score a, b;
  a.strict = {8, 2, 2};
  b.strict = {2, 8, 0};
  a.objects_counted = 2;
  a.objects_found = 1;
  b.objects_counted = 2;
  b.objects_found = 2;
  a.segments_per_object_max = 3;
  a += b;
  EXPECT_DOUBLE_EQ(a.strict.Precision(), 0.5);
  EXPECT_DOUBLE_EQ(a.strict.Recall(), 10.0 / 12.0);
  EXPECT_DOUBLE_EQ(a.FoundRate(), 0.75);
  EXPECT_EQ(a.segments_per_object_max, 3);
}

// ---------------------------------------------------------------------------------------
// Rendered scenes.

struct Rendered {
  Camera camera;
  DepthFrame frame;
  EvalFrame eval;
};

Rendered Render(const Scene& scene, const Camera& camera) {
  RenderOptions options;
  options.max_range_m = 40.0;
  Expected<DepthFrame> frame = RenderDepth(scene, camera, options);
  EXPECT_TRUE(frame.ok()) << (frame.ok() ? "" : frame.error().message);
  if (!frame.ok()) std::abort();
  Expected<EvalFrame> eval = FrameFromRender("test", *frame, scene);
  EXPECT_TRUE(eval.ok()) << (eval.ok() ? "" : eval.error().message);
  if (!eval.ok()) std::abort();
  return {camera, std::move(frame).value(), std::move(eval).value()};
}

TEST(FootBand, MatchesTheDefinitionAroundARenderedPole) {
  Scene scene(Terrain::Flat());
  const int pole = scene.AddPole(6.0, 0.3, 0.1, 2.0, true);
  const Camera camera =
      Camera::FromAttitude(PinholeFromFov(160, 120, 50.0 * kDegToRad),
                           Eigen::Vector3d(0.0, 0.0, 1.5), 0.0, 12.0 * kDegToRad, 0.0);
  const Rendered r = Render(scene, camera);
  const double hmax = 1.0, theta = 45.0 * kDegToRad;
  const std::vector<std::int32_t> band = FootBand(r.eval.image, r.eval.truth, hmax, theta);

  // The definition, pixel against pixel, in world coordinates made here.
  std::vector<Eigen::Vector3d> pole_points;
  const int w = r.frame.width();
  for (int i = 0; i < r.frame.size(); ++i) {
    if (r.frame.object_id[i] == pole && r.frame.depth_m[i] > 0.0f) {
      pole_points.push_back(camera.UnprojectWorld(i % w, i / w, r.frame.depth_m[i]));
    }
  }
  ASSERT_GT(pole_points.size(), 100u);
  // FootBand reduces the pole to the extremes of 5 cm cells: its reach is exact to a cell.
  const double tolerance = 0.05 * std::sqrt(2.0) + 1e-3;
  int in_band = 0, checked = 0;
  for (int i = 0; i < r.frame.size(); ++i) {
    if (r.frame.object_id[i] != kTerrainId || !(r.frame.depth_m[i] > 0.0f)) {
      EXPECT_EQ(band[i], 0) << "only terrain is in a foot band";
      continue;
    }
    const Eigen::Vector3d t = camera.UnprojectWorld(i % w, i / w, r.frame.depth_m[i]);
    double best = -1e9;  // largest reach - distance over the pole's points
    for (const Eigen::Vector3d& q : pole_points) {
      const double dh = std::abs(q.z() - t.z());
      if (dh <= 0.0) continue;
      best = std::max(best, std::min(dh, hmax) / std::tan(theta) - (q - t).head<2>().norm());
    }
    if (best > tolerance) {
      EXPECT_EQ(band[i], pole) << "pixel " << i << " lies " << best << " m inside the reach";
      ++checked;
    } else if (best < -tolerance) {
      EXPECT_EQ(band[i], 0) << "pixel " << i << " lies " << -best << " m beyond the reach";
      ++checked;
    }
    if (band[i] != 0) {
      ++in_band;
      // Analytic bound: nothing beyond radius + Hmax / tan(theta) from the pole's axis.
      EXPECT_LT((t.head<2>() - Eigen::Vector2d(6.0, 0.3)).norm(), 0.1 + 1.0 + 1e-3);
    }
  }
  EXPECT_GT(in_band, 50);
  EXPECT_GT(checked, r.frame.size() / 2);

  // A smaller Hmax shrinks the band: it is a subset.
  const std::vector<std::int32_t> narrow = FootBand(r.eval.image, r.eval.truth, 0.5, theta);
  int narrow_count = 0;
  for (std::size_t i = 0; i < band.size(); ++i) {
    if (narrow[i] != 0) {
      ++narrow_count;
      EXPECT_NE(band[i], 0);
    }
  }
  EXPECT_GT(narrow_count, 0);
  EXPECT_LT(narrow_count, in_band);
}

TEST(FootBand, ExplainsTheTerrainTheConeDetectorMarksAtAPolesFoot) {
  Scene scene(Terrain::Flat());
  scene.AddPole(6.0, 0.0, 0.1, 2.0, true);
  const Camera camera =
      Camera::FromAttitude(PinholeFromFov(160, 120, 50.0 * kDegToRad),
                           Eigen::Vector3d(0.0, 0.0, 1.5), 0.0, 12.0 * kDegToRad, 0.0);
  const Rendered r = Render(scene, camera);
  od::io::DetectSettings settings;
  Expected<FrameEvaluation> e =
      EvaluateFrame(r.eval, settings, {StandardMethods()[1]} /* cone exact, no rules */);
  ASSERT_TRUE(e.ok()) << e.error().message;
  const Score& s = e->scores[0].score;
  // The detector marks ground at the pole's foot (strict false positives), and every such
  // pixel is in the band: without it, precision is perfect.
  EXPECT_GT(s.strict.fp, 0);
  EXPECT_EQ(s.band_excluded.fp, 0);
  EXPECT_DOUBLE_EQ(s.band_excluded.Precision(), 1.0);
  EXPECT_EQ(s.objects_found, 1);
  EXPECT_EQ(s.false_obstacles, 0);
}

// Poles and rocks of several heights, a ridge with a steep sideways face, on a gentle slope.
Scene Clutter() {
  Scene scene(Terrain::Slope(0.0, 4.0 * kDegToRad, 0.0));
  scene.AddPole(5.0, -1.2, 0.08, 0.45, true);
  scene.AddPole(7.0, 1.0, 0.12, 0.9, true);
  scene.AddPole(11.0, -2.0, 0.2, 2.5, true);
  scene.AddRock(6.0, 0.0, {0.4, 0.35, 0.3}, 0.55, 0.3, true);
  scene.AddRock(8.5, -0.8, {0.3, 0.3, 0.2}, 0.2, 0.0, false);
  Ridge ridge;
  ridge.base_centre = {9.0, 2.5, 0.0};
  ridge.top_length_m = 3.0;
  ridge.top_width_m = 0.3;
  ridge.height_m = 0.7;
  ridge.right_slope_rad = 65.0 * kDegToRad;
  ridge.left_slope_rad = 25.0 * kDegToRad;
  scene.AddRidge(ridge, true);
  return scene;
}

Camera ClutterCamera() {
  return Camera::FromAttitude(PinholeFromFov(120, 90, 60.0 * kDegToRad), Eigen::Vector3d(0, 0, 1.6),
                              0.0, 10.0 * kDegToRad, 2.0 * kDegToRad);
}

std::vector<Method> NoRules() {
  Expected<std::vector<Method>> m = SelectMethods("cone_exact,column");
  EXPECT_TRUE(m.ok());
  return *m;
}

Expected<SweepScores> Sweep(const EvalFrame& frame, const std::string& text,
                            const std::vector<Method>& methods) {
  Expected<SweepSpec> spec = ParseSweep(text);
  EXPECT_TRUE(spec.ok()) << (spec.ok() ? "" : spec.error().message);
  return SweepFrame(frame, od::io::DetectSettings{}, *spec, methods);
}

// Raising HT or theta only removes compatible pairs (HT < dh, dh / |p2 - p1| > sin(theta)),
// and raising Hmax only adds them (dh < Hmax), so without rules the obstacle points, hence
// the recall, can only shrink or only grow. The rules and the paper's window (its size
// follows HT) carry no such guarantee.
TEST(Sweep, RecallNeverGrowsWithHtOrThetaAndNeverShrinksWithHmax) {
  const Rendered r = Render(Clutter(), ClutterCamera());
  const std::vector<Method> methods = NoRules();
  const struct {
    const char* sweep;
    int direction;  // -1: recall does not increase; +1: does not decrease
  } cases[] = {
      {"min_height=0.1:0.8:6", -1}, {"min_slope=20:80:5", -1}, {"max_height=0.5:2.0:4", 1}};
  for (const auto& c : cases) {
    Expected<SweepScores> scores = Sweep(r.eval, c.sweep, methods);
    ASSERT_TRUE(scores.ok()) << scores.error().message;
    for (std::size_t m = 0; m < methods.size(); ++m) {
      for (std::size_t v = 1; v < scores->size(); ++v) {
        const std::int64_t before = (*scores)[v - 1][m].strict.tp;
        const std::int64_t after = (*scores)[v][m].strict.tp;
        if (c.direction < 0) {
          EXPECT_LE(after, before) << c.sweep << " " << methods[m].key << " value " << v;
        } else {
          EXPECT_GE(after, before) << c.sweep << " " << methods[m].key << " value " << v;
        }
      }
      // The sweep does change something on this scene.
      EXPECT_NE(scores->front()[m].strict.tp + scores->front()[m].strict.fp,
                scores->back()[m].strict.tp + scores->back()[m].strict.fp)
          << c.sweep << " " << methods[m].key;
    }
  }
}

// A higher rule threshold rejects every segment a lower one rejects: kept segments and
// recall never grow along a rule sweep; methods without rules do not move at all.
TEST(Sweep, ARuleThresholdOnlyRejectsMore) {
  const Rendered r = Render(Clutter(), ClutterCamera());
  Expected<std::vector<Method>> methods = SelectMethods("cone_exact_rules,cone_exact");
  ASSERT_TRUE(methods.ok());
  Expected<SweepScores> scores = Sweep(r.eval, "rules.min_points=0:400:5", *methods);
  ASSERT_TRUE(scores.ok()) << scores.error().message;
  for (std::size_t v = 1; v < scores->size(); ++v) {
    const Score& before = (*scores)[v - 1][0];
    const Score& after = (*scores)[v][0];
    EXPECT_LE(after.kept_segments, before.kept_segments);
    EXPECT_LE(after.strict.tp, before.strict.tp);
    EXPECT_EQ((*scores)[v][1].strict.tp, (*scores)[0][1].strict.tp);
  }
  EXPECT_LT(scores->back()[0].kept_segments, scores->front()[0].kept_segments);
}

TEST(Sweep, ParsesTheSpecAndAppliesFileUnits) {
  Expected<SweepSpec> s = ParseSweep("min_slope=30:60:4");
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->key, "min_slope");
  EXPECT_EQ(s->Values(), (std::vector<double>{30.0, 40.0, 50.0, 60.0}));
  EXPECT_TRUE(s->ChangesDetection());
  od::io::DetectSettings settings;
  ASSERT_TRUE(ApplySetting(settings, "min_slope", 30.0).ok());
  EXPECT_NEAR(settings.detector.min_slope_rad, 30.0 * kDegToRad, 1e-12);  // degrees in, radians in
  ASSERT_TRUE(ApplySetting(settings, "rules.min_volume", 0.02).ok());
  EXPECT_DOUBLE_EQ(settings.rules.min_volume_m3, 0.02);
  EXPECT_FALSE(ParseSweep("rules.min_volume=0:0.1:3")->ChangesDetection());

  for (const char* bad :
       {"min_height", "min_height=0.1:0.5", "foo=1:2:3", "min_height=a:1:3", "min_height=0.5:0.1:3",
        "min_height=0.1:0.5:0", "detector.min_points=1:2:2"}) {
    EXPECT_FALSE(ParseSweep(bad).ok()) << bad;
  }
  // A value that makes the settings invalid names the key.
  const Status s2 = ApplySetting(settings, "min_height", 1.5);  // above Hmax = 1
  ASSERT_FALSE(s2.ok());
  EXPECT_NE(s2.message().find("min_height"), std::string::npos);
}

// ---------------------------------------------------------------------------------------
// Methods, figures, claims.

TEST(Methods, RunSideBySideAndShareDetections) {
  const Rendered r = Render(Clutter(), ClutterCamera());
  const std::vector<Method> methods = StandardMethods();
  ASSERT_EQ(methods.size(), 5u);
  Expected<FrameEvaluation> e = EvaluateFrame(r.eval, od::io::DetectSettings{}, methods);
  ASSERT_TRUE(e.ok()) << e.error().message;
  ASSERT_EQ(e->scores.size(), 5u);
  // With and without rules: the same detection, the rules only reject.
  EXPECT_EQ(e->runs[0].detection.labels, e->runs[1].detection.labels);
  EXPECT_LE(e->scores[0].score.kept_segments, e->scores[1].score.kept_segments);
  EXPECT_EQ(e->runs[3].detection.labels, e->runs[4].detection.labels);
  // Exact cone detections equal od::Detect's.
  Expected<od::Detection> direct = od::Detect(r.eval.image, od::DetectorConfig{});
  ASSERT_TRUE(direct.ok());
  EXPECT_EQ(direct->labels, e->runs[0].detection.labels);

  EXPECT_FALSE(SelectMethods("cone_exact,nope").ok());
  EXPECT_FALSE(SelectMethods("cone_exact,cone_exact").ok());
}

TEST(Figures, ComparisonStripHasAColumnPerMethodAndTruth) {
  const Rendered r = Render(Clutter(), ClutterCamera());
  const std::vector<Method> methods = StandardMethods();
  Expected<FrameEvaluation> e = EvaluateFrame(r.eval, od::io::DetectSettings{}, methods);
  ASSERT_TRUE(e.ok());
  Expected<od::io::RgbImage> strip = ComparisonStrip(r.eval, *e, methods);
  ASSERT_TRUE(strip.ok()) << strip.error().message;
  // 120 px wide frames are not scaled: 6 columns of 120 px and 7 gaps of 6 px.
  EXPECT_EQ(strip->width, 6 + 6 * (120 + 6));
  EXPECT_GT(strip->height, 2 * 90);
  const od::io::RgbImage figure = ComparisonFigure("clutter", {*strip, *strip});
  EXPECT_EQ(figure.width, strip->width);
  EXPECT_GT(figure.height, 2 * strip->height);
  // Kept points are blue in the first method's upper cell: some pixel there is.
  int blue = 0;
  for (const auto& p : strip->data) blue += p[2] > 180 && p[0] < 100 ? 1 : 0;
  EXPECT_GT(blue, 20);

  Expected<SweepScores> sweep = Sweep(r.eval, "min_height=0.2:0.6:3", methods);
  ASSERT_TRUE(sweep.ok());
  const od::io::RgbImage plot =
      PrecisionRecallPlot(*ParseSweep("min_height=0.2:0.6:3"), methods, *sweep, "test");
  EXPECT_GT(plot.width, 400);
  EXPECT_GT(plot.height, 400);
}

TEST(Claims, TheSidewaysMoundClaimReadsTheRightMethods) {
  const std::vector<Method> methods = StandardMethods();
  WorldScores world;
  world.name = "sideways_mounds";
  world.description = "mounds whose steep faces point sideways";
  world.per_method.resize(methods.size());
  Score& cone = world.per_method[0];
  Score& column = world.per_method[3];
  cone.objects_counted = column.objects_counted = 10;
  cone.objects_found = 10;
  column.objects_found = 4;
  cone.false_obstacles = 1;
  column.false_obstacles = 2;
  std::vector<ClaimCheck> checks = CheckWorld(world, methods);
  ASSERT_FALSE(checks.empty());
  EXPECT_NE(checks[0].claim.find("sideways"), std::string::npos);
  EXPECT_TRUE(checks[0].holds) << checks[0].measured;
  column.objects_found = 6;  // more than half: the claim fails
  checks = CheckWorld(world, methods);
  EXPECT_FALSE(checks[0].holds);
}

// ---------------------------------------------------------------------------------------
// Files: the bundled demo frame.

const std::filesystem::path kDemo =
    std::filesystem::path(CAIRN_SOURCE_DIR) / "datasets/frames/demo";

TEST(Files, TheDemoFrameLoadsWithItsTruth) {
  Expected<EvalFrame> frame = LoadFrame(kDemo / "depth.png", kDemo / "intrinsics.yaml",
                                        kDemo / "truth.png", kDemo / "truth.yaml");
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  EXPECT_EQ(frame->name, "demo");
  EXPECT_EQ(frame->truth.width, 640);
  ASSERT_EQ(frame->truth.objects.size(), 10u);
  EXPECT_TRUE(frame->truth.Find(4)->is_obstacle);   // the bush
  EXPECT_FALSE(frame->truth.Find(7)->is_obstacle);  // a small rock
  int no_return = 0;
  for (std::size_t i = 0; i < frame->truth.object_id.size(); ++i) {
    if (!(frame->depth_m.data[i] > 0.0f)) {
      EXPECT_EQ(frame->truth.object_id[i], kNoHitId);
      ++no_return;
    }
  }
  EXPECT_GT(no_return, 0);  // the sky
}

TEST(Files, TruthErrorsNameTheFileAndTheField) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("cairn_eval_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  };
  const auto expect_error = [&](const std::filesystem::path& yaml, const std::string& a,
                                const std::string& b) {
    Expected<FrameTruth> t = LoadTruth(kDemo / "truth.png", yaml);
    ASSERT_FALSE(t.ok());
    EXPECT_NE(t.error().message.find(a), std::string::npos) << t.error().message;
    EXPECT_NE(t.error().message.find(b), std::string::npos) << t.error().message;
  };
  expect_error(write("typo.yaml", "objects:\n  - {id: 1, is_obstacel: true}\n"), "typo.yaml",
               "objects[0].is_obstacel");
  expect_error(write("badid.yaml", "objects:\n  - {id: x, is_obstacle: true}\n"), "badid.yaml",
               "objects[0].id");
  // truth.png holds ids 1..10; listing only 1 leaves id 2 unexplained.
  expect_error(write("short.yaml", "objects:\n  - {id: 1, is_obstacle: true}\n"), "truth.png",
               "not listed");
  expect_error(dir / "missing.yaml", "missing.yaml", "");
  std::filesystem::remove_all(dir);
}

#ifdef CAIRN_EXE
// ---------------------------------------------------------------------------------------
// `cairn eval` end to end.

struct CliRun {
  int exit_code = -1;
  std::string out, err;
};

std::string Slurp(const std::filesystem::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

CliRun Cairn(const std::filesystem::path& dir, const std::string& args) {
  const std::string command = std::string(CAIRN_EXE) + " " + args + " >" +
                              (dir / "stdout.txt").string() + " 2>" + (dir / "stderr.txt").string();
  const int status = std::system(command.c_str());
  CliRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.out = Slurp(dir / "stdout.txt");
  run.err = Slurp(dir / "stderr.txt");
  return run;
}

class EvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("cairn_eval_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(EvalCli, WritesTheReportForOneFrame) {
  const std::filesystem::path report = dir_ / "report";
  const CliRun run =
      Cairn(dir_, "eval --depth " + (kDemo / "depth.png").string() + " --intrinsics " +
                      (kDemo / "intrinsics.yaml").string() + " --truth " +
                      (kDemo / "truth.png").string() + " --truth-yaml " +
                      (kDemo / "truth.yaml").string() + " --config " + CAIRN_SOURCE_DIR +
                      "/config/default.yaml" + " --methods cone_exact_rules,column --report " +
                      report.string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  for (const char* file : {"REPORT.md", "results.csv", "figures/demo.png"}) {
    EXPECT_TRUE(std::filesystem::is_regular_file(report / file)) << file;
  }
  const std::string md = Slurp(report / "REPORT.md");
  EXPECT_NE(md.find("| demo | cone exact + rules |"), std::string::npos) << md;
  EXPECT_NE(md.find("foot band"), std::string::npos);
  const std::string csv = Slurp(report / "results.csv");
  EXPECT_EQ(csv.rfind("world,method,label,frames,tp,fp,fn,precision,recall", 0), 0u) << csv;
  EXPECT_NE(csv.find("demo,cone_exact_rules,"), std::string::npos);
  EXPECT_NE(csv.find("all,column,"), std::string::npos);
  EXPECT_NE(run.out.find("cone exact + rules"), std::string::npos);
}

TEST_F(EvalCli, BadInputsNameTheFileAndExitOne) {
  const std::filesystem::path world = dir_ / "bad_world.yaml";
  std::ofstream(world) << "description: a world with a typo\nseeed: 3\n";
  CliRun run = Cairn(dir_, "eval --world " + world.string() + " --report " + (dir_ / "r").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("bad_world.yaml"), std::string::npos) << run.err;

  run = Cairn(
      dir_, "eval --worlds " + (dir_ / "nowhere").string() + " --report " + (dir_ / "r").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("nowhere"), std::string::npos) << run.err;

  run = Cairn(dir_, "eval --depth " + (kDemo / "depth.png").string() + " --report " +
                        (dir_ / "r").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("--intrinsics"), std::string::npos) << run.err;

  run = Cairn(dir_, "eval --world " + world.string() + " --sweep min_heihgt=0.1:0.5:3 --report " +
                        (dir_ / "r").string());
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("min_heihgt"), std::string::npos) << run.err;
}
#endif  // CAIRN_EXE

}  // namespace
}  // namespace cairn::eval
