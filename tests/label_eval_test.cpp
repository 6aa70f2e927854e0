// Evaluation on real labels (cairn/eval/label_eval.hpp):
//  - the class mapping file: what it reads, and every malformed file rejected with a message
//    naming the file and the key;
//  - the per-point score against hand counts (every branch: no return, ignored, TP, FP, FN,
//    TN, instance bits) and against a brute-force reference on seeded random label sets;
//  - a hand-made scan with a pole, several points per cell, no-return and ignored points:
//    results go back to every point through cell_of_point;
//  - the figures' sizes and colours;
//  - the RELLIS-3D frame (skipped when ../shared/datasets is absent): the numbers that
//    datasets/rellis3d/REPORT.md quotes are reproduced, and the cone detector's F1 is above
//    the column baseline's; `cairn eval --points` end to end.
#include "cairn/eval/label_eval.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/rules.hpp"
#include "io/cairn_command.hpp"
#include "io/temp_dir.hpp"

namespace cairn::eval {
namespace {

namespace fs = std::filesystem;

constexpr std::uint8_t kNone = 0, kKept = 1, kRejected = 2;

// ---------------------------------------------------------------------------------------
// Class mapping file.

const char* kSmallMap = R"(dataset: Test
classes:
  4: {name: tree, role: obstacle, color: [1, 2, 3]}
  0: {name: void, role: ignored}
  3: {name: grass, role: ground, color: [0, 255, 0]}
  19: {name: bush, role: ignored}
)";

TEST(ClassMap, ReadsRolesAndColoursSortedById) {
  Expected<ClassMap> map = ParseClassMap(kSmallMap, "small.yaml");
  ASSERT_TRUE(map.ok()) << map.error().message;
  EXPECT_EQ(map->dataset, "Test");
  EXPECT_EQ(map->source, "small.yaml");
  ASSERT_EQ(map->classes.size(), 4u);
  const std::vector<std::uint32_t> ids = {0, 3, 4, 19};
  for (std::size_t k = 0; k < ids.size(); ++k) EXPECT_EQ(map->classes[k].id, ids[k]);
  const LabelClass* tree = map->Find(4);
  ASSERT_NE(tree, nullptr);
  EXPECT_EQ(tree->name, "tree");
  EXPECT_EQ(tree->role, ClassRole::kObstacle);
  EXPECT_EQ(tree->color, (std::array<std::uint8_t, 3>{1, 2, 3}));
  EXPECT_EQ(map->Find(3)->role, ClassRole::kGround);
  EXPECT_EQ(map->Find(19)->role, ClassRole::kIgnored);
  // No colour given: the segment colour of id + 1 (so that id 0 gets one too).
  EXPECT_EQ(map->Find(0)->color, od::io::SegmentColor(1));
  EXPECT_EQ(map->Find(5), nullptr);
  EXPECT_STREQ(ClassRoleName(ClassRole::kObstacle), "obstacle");
  EXPECT_STREQ(ClassRoleName(ClassRole::kGround), "ground");
  EXPECT_STREQ(ClassRoleName(ClassRole::kIgnored), "ignored");
}

TEST(ClassMap, EveryMalformedFileIsRejectedNamingFileAndKey) {
  struct Case {
    const char* yaml;
    const char* expected;  // after "bad.yaml"
  };
  const Case cases[] = {
      {"classes:\n  4: {name: tree, role: obstacle}\nclases: 1\n",
       ": clases: unknown key (expected dataset, classes)"},
      {"dataset: X\n", ": classes: missing"},
      {"classes: []\n", ": classes: expected a non-empty mapping"},
      {"classes:\n  tree: {name: tree, role: obstacle}\n", ": classes.tree: expected a class id"},
      {"classes:\n  -4: {name: tree, role: obstacle}\n", ": classes.-4: expected a class id"},
      {"classes:\n  65536: {name: tree, role: obstacle}\n",
       ": classes.65536: expected a class id, an integer 0..65535"},
      {"classes:\n  4: {name: tree, role: obstcle}\n",
       ": classes.4.role: expected obstacle, ground or ignored, got 'obstcle'"},
      {"classes:\n  4: {name: tree}\n", ": classes.4.role: missing"},
      {"classes:\n  4: {role: obstacle}\n", ": classes.4.name: missing"},
      {"classes:\n  4: {name: '', role: obstacle}\n", ": classes.4.name: expected a non-empty"},
      {"classes:\n  4: {name: tree, role: obstacle, colour: [1, 2, 3]}\n",
       ": classes.4.colour: unknown key (expected name, role, color)"},
      {"classes:\n  4: {name: tree, role: obstacle, color: [1, 2]}\n",
       ": classes.4.color: expected [r, g, b]"},
      {"classes:\n  4: {name: tree, role: obstacle, color: [1, 300, 2]}\n",
       ": classes.4.color[1]: expected an integer 0..255, got '300'"},
      {"classes:\n  4: {name: tree, role: obstacle, color: [1, 2.5, 2]}\n",
       ": classes.4.color[1]: expected an integer 0..255, got '2.5'"},
      {"classes:\n  4: tree\n", ": classes.4: expected a mapping with keys name, role, color"},
      {"classes:\n  4: {name: tree, role: obstacle}\n  04: {name: trunk, role: obstacle}\n",
       ": classes.04: class id 4 given twice"},
      {"classes:\n  4: {name: tree, role: obstacle}\n  4: {name: trunk, role: obstacle}\n",
       ": classes.4: class id 4 given twice"},
      {"classes:\n  4: {name: tree, role: obstacle, role: ground}\n",
       ": classes.4.role: given twice"},
      {"classes:\n  ? [1, 2]\n  : {name: tree, role: obstacle}\n",
       ": classes: expected a class id, an integer 0..65535 (the lower 16 bits of a .label "
       "entry), got a sequence"},
      {"dataset: [x]\nclasses:\n  4: {name: tree, role: obstacle}\n",
       ": dataset: expected the dataset's name, got a sequence"},
      {"classes:\n  3: {name: grass, role: ground}\n  0: {name: void, role: ignored}\n",
       ": classes: no class has role obstacle"},
      {"classes:\n  4: {name: tree, role: obstacle\n", ": invalid YAML"},
      {"- 1\n- 2\n", ": top level: expected a mapping with keys dataset, classes"},
  };
  for (const Case& c : cases) {
    Expected<ClassMap> map = ParseClassMap(c.yaml, "bad.yaml");
    ASSERT_FALSE(map.ok()) << c.yaml;
    const std::string& message = map.error().message;
    EXPECT_EQ(message.rfind("bad.yaml", 0), 0u) << message;
    EXPECT_NE(message.find(c.expected), std::string::npos)
        << "expected '" << c.expected << "' in: " << message;
  }
}

TEST(ClassMap, MissingFileIsNamed) {
  Expected<ClassMap> map = LoadClassMap("/nonexistent/classes.yaml");
  ASSERT_FALSE(map.ok());
  EXPECT_EQ(map.error().message, "/nonexistent/classes.yaml: no such file (class mapping)");
  test::TempDir dir;
  Expected<ClassMap> from_dir = LoadClassMap(dir.path());
  ASSERT_FALSE(from_dir.ok());
  EXPECT_NE(from_dir.error().message.find("is a directory"), std::string::npos);
}

TEST(ClassMap, ShippedRellisMappingHasEveryIdWithTheStatedRole) {
  const fs::path path = fs::path(CAIRN_SOURCE_DIR) / "config" / "classes" / "rellis3d.yaml";
  Expected<ClassMap> map = LoadClassMap(path);
  ASSERT_TRUE(map.ok()) << map.error().message;
  EXPECT_EQ(map->dataset, "RELLIS-3D");
  // RELLIS-3D's ontology (rellis_labels.yaml) with the roles the report states.
  const std::vector<std::tuple<std::uint32_t, const char*, ClassRole>> expected = {
      {0, "void", ClassRole::kIgnored},       {1, "dirt", ClassRole::kGround},
      {3, "grass", ClassRole::kGround},       {4, "tree", ClassRole::kObstacle},
      {5, "pole", ClassRole::kObstacle},      {6, "water", ClassRole::kGround},
      {7, "sky", ClassRole::kIgnored},        {8, "vehicle", ClassRole::kObstacle},
      {9, "object", ClassRole::kObstacle},    {10, "asphalt", ClassRole::kGround},
      {12, "building", ClassRole::kObstacle}, {15, "log", ClassRole::kObstacle},
      {17, "person", ClassRole::kObstacle},   {18, "fence", ClassRole::kObstacle},
      {19, "bush", ClassRole::kIgnored},      {23, "concrete", ClassRole::kGround},
      {27, "barrier", ClassRole::kObstacle},  {31, "puddle", ClassRole::kGround},
      {33, "mud", ClassRole::kGround},        {34, "rubble", ClassRole::kObstacle},
  };
  ASSERT_EQ(map->classes.size(), expected.size());
  for (const auto& [id, name, role] : expected) {
    const LabelClass* c = map->Find(id);
    ASSERT_NE(c, nullptr) << id;
    EXPECT_EQ(c->name, name) << id;
    EXPECT_EQ(c->role, role) << name;
  }
}

// ---------------------------------------------------------------------------------------
// Scoring.

ClassMap SmallMap() {
  Expected<ClassMap> map = ParseClassMap(kSmallMap, "small.yaml");
  EXPECT_TRUE(map.ok());
  return *map;
}

TEST(ScoreLabels, HandCountsOfEveryBranch) {
  // Ids: 4 tree (obstacle), 3 grass (ground), 0 void and 19 bush (ignored). Upper 16 bits
  // are instance ids and must not matter.
  struct P {
    std::uint32_t label;
    std::uint8_t cls;
    std::uint8_t ret;
    PointOutcome expected;
  };
  const std::uint32_t inst = 7u << 16;
  const std::vector<P> points = {
      {4, kKept, 1, PointOutcome::kTruePositive},         // tree in a kept segment
      {4 | inst, kKept, 1, PointOutcome::kTruePositive},  // with an instance id
      {4, kRejected, 1, PointOutcome::kFalseNegative},    // rejected = not detected
      {4, kNone, 1, PointOutcome::kFalseNegative},
      {4, kNone, 0, PointOutcome::kNoReturn},       // no return: never missed
      {3, kKept, 1, PointOutcome::kFalsePositive},  // grass detected
      {3 | inst, kKept, 1, PointOutcome::kFalsePositive},
      {3, kRejected, 1, PointOutcome::kTrueNegative},
      {3, kNone, 1, PointOutcome::kTrueNegative},
      {3, kNone, 1, PointOutcome::kTrueNegative},
      {3, kNone, 0, PointOutcome::kNoReturn},
      {19, kKept, 1, PointOutcome::kIgnored},  // bush detected: not scored
      {19, kNone, 1, PointOutcome::kIgnored},
      {0, kNone, 1, PointOutcome::kIgnored},
      {0, kNone, 0, PointOutcome::kNoReturn},
  };
  std::vector<std::uint32_t> labels;
  std::vector<std::uint8_t> cls, ret;
  for (const P& p : points) {
    labels.push_back(p.label);
    cls.push_back(p.cls);
    ret.push_back(p.ret);
  }
  Expected<ScoredPoints> scored = ScoreLabels(SmallMap(), labels, cls, ret, "hand.label");
  ASSERT_TRUE(scored.ok()) << scored.error().message;
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(scored->outcome[i], points[i].expected) << "point " << i;
  }
  const LabelScore& s = scored->score;
  EXPECT_EQ(s.counts.tp, 2);
  EXPECT_EQ(s.counts.fp, 2);
  EXPECT_EQ(s.counts.fn, 2);
  EXPECT_EQ(s.tn, 3);
  EXPECT_EQ(s.ignored, 3);
  EXPECT_EQ(s.no_return, 3);
  EXPECT_DOUBLE_EQ(s.counts.Precision(), 0.5);
  EXPECT_DOUBLE_EQ(s.counts.Recall(), 0.5);
  EXPECT_DOUBLE_EQ(s.counts.F1(), 0.5);
  EXPECT_DOUBLE_EQ(s.counts.IoU(), 2.0 / 6.0);
  // Per class: returns, detected (kept), rejected.
  const ClassTally* tree = s.Find(4);
  ASSERT_NE(tree, nullptr);
  EXPECT_EQ(tree->returns, 4);
  EXPECT_EQ(tree->detected, 2);
  EXPECT_EQ(tree->rejected, 1);
  EXPECT_EQ(s.Find(3)->returns, 5);
  EXPECT_EQ(s.Find(3)->detected, 2);
  EXPECT_EQ(s.Find(3)->rejected, 1);
  EXPECT_EQ(s.Find(19)->returns, 2);
  EXPECT_EQ(s.Find(19)->detected, 1);
  EXPECT_EQ(s.Find(0)->returns, 1);
  EXPECT_EQ(s.Find(7), nullptr);
}

TEST(ScoreLabels, MatchesBruteForceOnRandomLabelSets) {
  const ClassMap map = SmallMap();
  const std::uint32_t ids[] = {0, 3, 4, 19};
  const std::set<std::uint32_t> obstacle = {4}, ignored = {0, 19};
  std::mt19937 rng(20240604);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 1 + static_cast<int>(rng() % 400);
    std::vector<std::uint32_t> labels(n);
    std::vector<std::uint8_t> cls(n), ret(n);
    for (int i = 0; i < n; ++i) {
      labels[i] = ids[rng() % 4] | ((rng() % 5) << 16);
      cls[i] = static_cast<std::uint8_t>(rng() % 3);
      ret[i] = rng() % 5 != 0;
    }
    Expected<ScoredPoints> scored = ScoreLabels(map, labels, cls, ret, "random.label");
    ASSERT_TRUE(scored.ok()) << scored.error().message;
    std::int64_t tp = 0, fp = 0, fn = 0, tn = 0, ign = 0, none = 0;
    std::map<std::uint32_t, std::array<std::int64_t, 3>> per_class;  // returns, kept, rejected
    for (int i = 0; i < n; ++i) {
      const std::uint32_t id = labels[i] & 0xFFFFu;
      if (!ret[i]) {
        ++none;
        continue;
      }
      per_class[id][0] += 1;
      per_class[id][1] += cls[i] == kKept;
      per_class[id][2] += cls[i] == kRejected;
      if (ignored.count(id)) {
        ++ign;
        continue;
      }
      const bool obs = obstacle.count(id) > 0, det = cls[i] == kKept;
      tp += obs && det;
      fp += !obs && det;
      fn += obs && !det;
      tn += !obs && !det;
    }
    const LabelScore& s = scored->score;
    EXPECT_EQ(s.counts.tp, tp);
    EXPECT_EQ(s.counts.fp, fp);
    EXPECT_EQ(s.counts.fn, fn);
    EXPECT_EQ(s.tn, tn);
    EXPECT_EQ(s.ignored, ign);
    EXPECT_EQ(s.no_return, none);
    for (const std::uint32_t id : ids) {
      EXPECT_EQ(s.Find(id)->returns, per_class[id][0]);
      EXPECT_EQ(s.Find(id)->detected, per_class[id][1]);
      EXPECT_EQ(s.Find(id)->rejected, per_class[id][2]);
    }
  }
}

TEST(ScoreLabels, UnlistedIdAndSizeMismatchAreErrors) {
  const ClassMap map = SmallMap();
  // An unlisted id fails even on a point without a return: the mapping must cover the file.
  Expected<ScoredPoints> unlisted =
      ScoreLabels(map, {4, 3, 8}, {kNone, kNone, kNone}, {1, 1, 0}, "scan.label");
  ASSERT_FALSE(unlisted.ok());
  EXPECT_EQ(unlisted.error().message,
            "scan.label: point 2 has class id 8, which the class mapping small.yaml does not "
            "list (add it with a role: obstacle, ground or ignored)");
  Expected<ScoredPoints> sizes = ScoreLabels(map, {4, 3}, {kNone}, {1, 1}, "scan.label");
  ASSERT_FALSE(sizes.ok());
  EXPECT_NE(sizes.error().message.find("scan.label: 2 labels, but 1 results and 2 return flags"),
            std::string::npos)
      << sizes.error().message;
}

// ---------------------------------------------------------------------------------------
// A hand-made scan: flat ground 1.5 m below a VLP-16, a 2 m pole 6 m ahead, duplicates.

constexpr std::uint32_t kGrass = 3, kTree = 4, kBush = 19, kVoid = 0;

struct Scan {
  od::PointCloud cloud;
  std::vector<std::uint32_t> labels;
};

/// Every ray of a VLP-16 at 360 azimuth steps that hits the ground (z = -1.5) within 25 m or
/// the pole (|y| < 0.15 m at x = 6, z from -1.5 to 0.5). Pole points are trees; ground
/// points grass, except a bush patch to the left (y > 4), and some rays are no returns
/// labelled as tree (their truth must not count). Every tenth pole point is repeated 1 cm
/// farther, so that two points share its cell.
Scan MakeScan() {
  Expected<od::SphericalModel> model = od::SphericalModel::Preset("VLP-16", 360);
  EXPECT_TRUE(model.ok());
  Scan scan;
  int pole_points = 0;
  for (int c = 0; c < model->width; ++c) {
    const double az = model->ColumnAzimuth(c);
    for (int r = 0; r < model->height(); ++r) {
      const double el = model->ring_elevation_rad[r];
      const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                              std::sin(el));
      Eigen::Vector3d hit;
      std::uint32_t label = kGrass;
      bool found = false;
      if (d.x() > 0) {
        const double t = 6.0 / d.x();
        const Eigen::Vector3d p = t * d;
        if (std::abs(p.y()) < 0.15 && p.z() > -1.5 && p.z() < 0.5) {
          hit = p;
          label = kTree;
          found = true;
        }
      }
      if (!found && d.z() < 0) {
        const Eigen::Vector3d p = (-1.5 / d.z()) * d;
        if (p.head<2>().norm() < 25.0) {
          hit = p;
          label = p.y() > 4.0 ? kBush : kGrass;
          found = true;
        }
      }
      if (!found) {
        // No return: half of them claim to be tree, which must not count as a miss.
        scan.cloud.points.push_back(Eigen::Vector3f::Zero());
        scan.labels.push_back((c + r) % 2 == 0 ? kTree : kVoid);
        continue;
      }
      scan.cloud.points.push_back(hit.cast<float>());
      scan.labels.push_back(label);
      if (label == kTree && pole_points++ % 10 == 0) {
        scan.cloud.points.push_back((hit * (1.0 + 0.01 / hit.norm())).cast<float>());
        scan.labels.push_back(kTree);
      }
    }
  }
  scan.cloud.intensity.assign(scan.cloud.points.size(), 0.f);
  return scan;
}

const char* kScanMap = R"(classes:
  0: {name: void, role: ignored}
  3: {name: grass, role: ground}
  4: {name: tree, role: obstacle}
  19: {name: bush, role: ignored}
)";

struct ScanFixture {
  test::TempDir dir;
  Scan scan = MakeScan();
  fs::path bin, label;

  ScanFixture() {
    bin = dir / "scan.bin";
    label = dir / "scan.label";
    EXPECT_TRUE(od::io::WriteKittiBin(bin, scan.cloud).ok());
    EXPECT_TRUE(od::io::WriteLabelFile(label, scan.labels).ok());
  }
};

Expected<LabelFrame> LoadScan(const fs::path& bin, const fs::path& label) {
  Expected<od::SphericalModel> preset = od::SphericalModel::Preset("VLP-16", 360);
  EXPECT_TRUE(preset.ok());
  return LoadLabelFrame(bin, label, *preset, od::OrganisedMode::kNo, Eigen::Vector3d::UnitZ());
}

od::io::DetectSettings ScanSettings() {
  od::io::DetectSettings settings;
  settings.detector.min_height_m = 0.3;
  settings.detector.max_height_m = 1.0;
  settings.detector.min_slope_rad = 45.0 * 3.141592653589793 / 180.0;
  settings.rules.min_points = 3;
  return settings;
}

TEST(EvaluateLabels, EveryPointTakesItsCellsResult) {
  ScanFixture f;
  Expected<LabelFrame> frame = LoadScan(f.bin, f.label);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  EXPECT_EQ(frame->name, "scan");
  EXPECT_FALSE(frame->organised);
  ASSERT_EQ(frame->points.size(), f.scan.labels.size());
  Expected<ClassMap> map = ParseClassMap(kScanMap, "scan_map.yaml");
  ASSERT_TRUE(map.ok());
  Expected<std::vector<Method>> methods = SelectMethods("cone_exact_rules,column_rules,column");
  ASSERT_TRUE(methods.ok());
  Expected<std::vector<LabelMethodResult>> results =
      EvaluateLabels(*frame, *map, ScanSettings(), *methods);
  ASSERT_TRUE(results.ok()) << results.error().message;
  ASSERT_EQ(results->size(), 3u);

  const std::vector<std::int32_t>& cell = frame->image.cell_of_point();
  int shared_cells = 0;
  for (std::size_t m = 0; m < results->size(); ++m) {
    const LabelMethodResult& r = (*results)[m];
    const std::vector<std::uint8_t> verdict = od::ClassImage(r.run.detection, r.run.classification);
    std::int64_t tp = 0, fp = 0, fn = 0;
    for (std::size_t i = 0; i < cell.size(); ++i) {
      const std::uint32_t id = f.scan.labels[i];
      const bool has_return = !f.scan.cloud.points[i].isZero();
      ASSERT_EQ(cell[i] >= 0, has_return) << i;
      // The point's class is its cell's verdict.
      const std::uint8_t expected_class = has_return ? verdict[cell[i]] : kNone;
      ASSERT_EQ(r.point_class[i], expected_class) << i;
      const bool detected = expected_class == kKept;
      PointOutcome expected = PointOutcome::kNoReturn;
      if (!has_return) {
        expected = PointOutcome::kNoReturn;
      } else if (id == kVoid || id == kBush) {
        expected = PointOutcome::kIgnored;
      } else if (id == kTree) {
        expected = detected ? PointOutcome::kTruePositive : PointOutcome::kFalseNegative;
      } else {
        expected = detected ? PointOutcome::kFalsePositive : PointOutcome::kTrueNegative;
      }
      ASSERT_EQ(r.scored.outcome[i], expected) << "method " << m << " point " << i;
      tp += expected == PointOutcome::kTruePositive;
      fp += expected == PointOutcome::kFalsePositive;
      fn += expected == PointOutcome::kFalseNegative;
      // A repeated pole point shares its cell, and so its outcome, with the one before.
      if (i > 0 && cell[i] >= 0 && cell[i] == cell[i - 1]) {
        ++shared_cells;
        EXPECT_EQ(r.scored.outcome[i], r.scored.outcome[i - 1]);
      }
    }
    EXPECT_EQ(r.scored.score.counts.tp, tp);
    EXPECT_EQ(r.scored.score.counts.fp, fp);
    EXPECT_EQ(r.scored.score.counts.fn, fn);
    EXPECT_GT(r.scored.score.no_return, 0);
    EXPECT_GT(r.scored.score.ignored, 0);
  }
  EXPECT_GT(shared_cells, 0);
  // The pole stands 2 m, well above HT: the cone detector finds most of it.
  EXPECT_GT((*results)[0].scored.score.counts.Recall(), 0.8);
}

TEST(LoadLabelFrame, CountMismatchAndBadFilesNameTheFiles) {
  ScanFixture f;
  std::vector<std::uint32_t> short_labels(f.scan.labels.begin(), f.scan.labels.end() - 1);
  const fs::path short_label = f.dir / "short.label";
  ASSERT_TRUE(od::io::WriteLabelFile(short_label, short_labels).ok());
  Expected<LabelFrame> mismatch = LoadScan(f.bin, short_label);
  ASSERT_FALSE(mismatch.ok());
  const std::string& m = mismatch.error().message;
  EXPECT_EQ(m.rfind(short_label.string() + ": " + std::to_string(short_labels.size()) +
                        " labels for the " + std::to_string(f.scan.labels.size()) + " points of " +
                        f.bin.string(),
                    0),
            0u)
      << m;
  const fs::path truncated = f.dir.Write("truncated.label", "abcdef");
  Expected<LabelFrame> bad = LoadScan(f.bin, truncated);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().message.rfind(truncated.string() + ":", 0), 0u) << bad.error().message;
  Expected<LabelFrame> missing = LoadScan(f.dir / "none.bin", f.label);
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("none.bin"), std::string::npos);
}

// ---------------------------------------------------------------------------------------
// Figures.

int CountColour(const od::io::RgbImage& image, std::array<std::uint8_t, 3> colour) {
  int n = 0;
  for (const auto& p : image.data) n += p == colour;
  return n;
}

TEST(LabelFigures, PanelsPerMethodInTheOutcomeColours) {
  ScanFixture f;
  Expected<LabelFrame> frame = LoadScan(f.bin, f.label);
  ASSERT_TRUE(frame.ok()) << frame.error().message;
  Expected<ClassMap> map = ParseClassMap(
      "classes:\n  0: {name: void, role: ignored}\n  3: {name: grass, role: ground, color: [1, "
      "2, 3]}\n  4: {name: tree, role: obstacle, color: [4, 5, 6]}\n  19: {name: bush, role: "
      "ignored}\n",
      "m.yaml");
  ASSERT_TRUE(map.ok());
  Expected<std::vector<Method>> methods = SelectMethods("cone_exact_rules,column_rules");
  ASSERT_TRUE(methods.ok());
  Expected<std::vector<LabelMethodResult>> results =
      EvaluateLabels(*frame, *map, ScanSettings(), *methods);
  ASSERT_TRUE(results.ok()) << results.error().message;
  LabelFigureOptions options;
  options.pixels_per_ring = 4;
  options.birds_eye_m_per_px = 0.1;
  options.birds_eye_half_extent_m = 20.0;
  Expected<od::io::RgbImage> range = LabelRangeFigure(*frame, *map, *methods, *results, options);
  ASSERT_TRUE(range.ok()) << range.error().message;
  EXPECT_GT(range->width, 360);          // the 360 columns plus margins
  EXPECT_GT(range->height, 3 * 16 * 4);  // three panels of 16 rings x 4 px
  // The truth panel draws each cell of a tree point 4 px high in the tree's colour.
  int tree_cells = 0;
  for (const std::uint32_t id : f.scan.labels) tree_cells += id == kTree;
  EXPECT_GT(CountColour(*range, {4, 5, 6}), 0);
  EXPECT_GT(CountColour(*range, {1, 2, 3}), 0);
  EXPECT_LE(CountColour(*range, {4, 5, 6}), 4 * tree_cells + 200);  // + the legend swatch
  const std::array<std::uint8_t, 3> tp_colour = {0, 158, 115};
  EXPECT_GT(CountColour(*range, tp_colour), 0);

  Expected<od::io::RgbImage> top = LabelBirdsEyeFigure(*frame, *map, *methods, *results, options);
  ASSERT_TRUE(top.ok()) << top.error().message;
  EXPECT_GE(top->width, 3 * 400);  // three panels of 40 m / 0.1 m side by side
  EXPECT_GT(top->height, 400);
  EXPECT_GT(CountColour(*top, tp_colour), 0);
  EXPECT_GT(CountColour(*top, {4, 5, 6}), 0);

  // Results that do not match the methods are refused.
  std::vector<LabelMethodResult> one(results->begin(), results->begin() + 1);
  EXPECT_FALSE(LabelRangeFigure(*frame, *map, *methods, one).ok());
  EXPECT_FALSE(LabelBirdsEyeFigure(*frame, *map, *methods, one).ok());
}

// ---------------------------------------------------------------------------------------
// The RELLIS-3D frame.

const fs::path kRellis = fs::path(CAIRN_SHARED_DATASETS) / "rellis3d-000104";
const char* kReportMethods =
    "cone_exact_rules,column_rules,cone_exact,column,cone_exact_rules_nofeet";

/// Brute force, independent of ScoreLabels: RELLIS ids written out, no return = (0, 0, 0).
PointCounts RellisCounts(const std::vector<std::uint32_t>& truth,
                         const std::vector<Eigen::Vector3f>& points,
                         const std::vector<std::uint32_t>& result) {
  const std::set<std::uint32_t> obstacle = {4, 5, 8, 9, 12, 15, 17, 18, 27, 34};
  const std::set<std::uint32_t> ignored = {0, 7, 19};
  PointCounts c;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const std::uint32_t id = truth[i] & 0xFFFFu;
    if (points[i].isZero() || ignored.count(id)) continue;
    const bool detected = (result[i] & 0xFFFFu) == 1u;
    const bool is_obstacle = obstacle.count(id) > 0;
    c.tp += detected && is_obstacle;
    c.fp += detected && !is_obstacle;
    c.fn += !detected && is_obstacle;
  }
  return c;
}

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The F1 column of the report's score table row for `label`, or "" when absent.
std::string ReportF1(const std::string& report, const std::string& label) {
  const std::size_t at = report.find("\n| " + label + " | ");
  if (at == std::string::npos) return "";
  std::istringstream row(report.substr(at + 1, report.find('\n', at + 1) - at - 1));
  std::string cell;
  std::vector<std::string> cells;
  while (std::getline(row, cell, '|')) cells.push_back(cell);
  // "", method, precision, recall, F1, ...
  if (cells.size() < 5) return "";
  std::string f1 = cells[4];
  f1.erase(0, f1.find_first_not_of(' '));
  f1.erase(f1.find_last_not_of(' ') + 1);
  return f1;
}

struct RellisRun {
  ClassMap map;
  LabelFrame frame;
  std::vector<Method> methods;
  std::vector<LabelMethodResult> results;
};

Expected<RellisRun> RunRellis() {
  Expected<od::SphericalModel> preset = od::SphericalModel::Preset("OS1-64", 2048);
  if (!preset) return preset.error();
  Expected<LabelFrame> frame =
      LoadLabelFrame(kRellis / "os1_bin" / "000104.bin", kRellis / "os1_label" / "000104.label",
                     *preset, od::OrganisedMode::kAuto, Eigen::Vector3d::UnitZ());
  if (!frame) return frame.error();
  Expected<od::io::DetectSettings> settings =
      od::io::LoadDetectSettings(fs::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "os1-64.yaml");
  if (!settings) return settings.error();
  Expected<ClassMap> map =
      LoadClassMap(fs::path(CAIRN_SOURCE_DIR) / "config" / "classes" / "rellis3d.yaml");
  if (!map) return map.error();
  Expected<std::vector<Method>> methods = SelectMethods(kReportMethods);
  if (!methods) return methods.error();
  Expected<std::vector<LabelMethodResult>> results =
      EvaluateLabels(*frame, *map, *settings, *methods);
  if (!results) return results.error();
  return RellisRun{*map, std::move(frame).value(), *methods, std::move(results).value()};
}

TEST(RellisFrame, ReportNumbersAreReproducedAndConeBeatsColumn) {
  if (!fs::exists(kRellis)) {
    GTEST_SKIP() << "RELLIS-3D frame not found at " << kRellis.string()
                 << " (see ../shared/datasets/README.md)";
  }
  Expected<RellisRun> run = RunRellis();
  ASSERT_TRUE(run.ok()) << run.error().message;
  ASSERT_TRUE(run->frame.organised);
  ASSERT_EQ(run->frame.points.size(), 131072u);
  ASSERT_EQ(run->methods[0].key, "cone_exact_rules");
  ASSERT_EQ(run->methods[1].key, "column_rules");

  const std::string report =
      ReadAll(fs::path(CAIRN_SOURCE_DIR) / "datasets" / "rellis3d" / "REPORT.md");
  ASSERT_FALSE(report.empty()) << "datasets/rellis3d/REPORT.md missing";
  for (std::size_t m = 0; m < run->methods.size(); ++m) {
    const LabelMethodResult& r = run->results[m];
    // The brute force agrees with the score, count for count.
    Expected<std::vector<std::uint32_t>> written =
        od::io::PointLabels(run->frame.image, r.run.detection, r.run.classification);
    ASSERT_TRUE(written.ok());
    const PointCounts brute = RellisCounts(run->frame.truth, run->frame.points, *written);
    EXPECT_EQ(r.scored.score.counts.tp, brute.tp) << run->methods[m].label;
    EXPECT_EQ(r.scored.score.counts.fp, brute.fp) << run->methods[m].label;
    EXPECT_EQ(r.scored.score.counts.fn, brute.fn) << run->methods[m].label;
    // And the report quotes it to three decimals.
    char f1[16];
    std::snprintf(f1, sizeof(f1), "%.3f", brute.F1());
    EXPECT_EQ(ReportF1(report, run->methods[m].label), f1) << run->methods[m].label;
    std::printf("%-24s P %.3f R %.3f F1 %.3f IoU %.3f\n", run->methods[m].label.c_str(),
                brute.Precision(), brute.Recall(), brute.F1(), brute.IoU());
  }
  // Every table of the report, as the library makes it now.
  const std::string scores = LabelResultsMarkdown(run->methods, run->results);
  const std::string classes = LabelClassesMarkdown(run->map, run->methods, run->results);
  const std::string errors = LabelErrorsMarkdown(run->map, run->methods, run->results);
  EXPECT_NE(report.find(scores), std::string::npos) << "expected in REPORT.md:\n" << scores;
  EXPECT_NE(report.find(classes), std::string::npos) << "expected in REPORT.md:\n" << classes;
  EXPECT_NE(report.find(errors), std::string::npos) << "expected in REPORT.md:\n" << errors;

  const PointCounts& cone = run->results[0].scored.score.counts;
  const PointCounts& column = run->results[1].scored.score.counts;
  EXPECT_GT(cone.F1(), 0.8);
  EXPECT_GT(cone.F1(), column.F1());
  // What the report reads off the per-class table: trees and people found, grass and
  // concrete mostly not.
  const LabelScore& s = run->results[0].scored.score;
  const auto share = [&](std::uint32_t id) {
    const ClassTally* t = s.Find(id);
    return double(t->detected) / double(t->returns);
  };
  EXPECT_GT(share(4), 0.9);    // tree
  EXPECT_GT(share(17), 0.9);   // person
  EXPECT_LT(share(3), 0.25);   // grass
  EXPECT_LT(share(23), 0.05);  // concrete

  // With the feet counted as ground the grass at the tree line is no longer marked
  // (measured: 18% -> 5%) at a small cost in recall, and F1 rises (0.889 -> 0.908).
  ASSERT_EQ(run->methods[4].key, "cone_exact_rules_nofeet");
  const LabelScore& nofeet = run->results[4].scored.score;
  EXPECT_GT(nofeet.counts.F1(), cone.F1());
  EXPECT_GT(nofeet.counts.Precision(), cone.Precision() + 0.05);
  const ClassTally* grass = nofeet.Find(3);
  EXPECT_LT(double(grass->detected) / double(grass->returns), 0.5 * share(3));
}

#ifdef CAIRN_EXE

int RunCairn(const std::vector<std::string>& args, std::string* output) {
  const test::CommandResult run = test::RunProgram(CAIRN_EXE, args);
  *output += run.output;
  return run.exit_code;
}

/// The text from `heading` to the next "## " heading.
std::string Section(const std::string& report, const std::string& heading) {
  const std::size_t at = report.find(heading);
  if (at == std::string::npos) return "";
  const std::size_t end = report.find("\n## ", at + heading.size());
  return report.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

TEST(EvalLabelsCli, RellisReportIsRemadeByTheCommand) {
  if (!fs::exists(kRellis)) {
    GTEST_SKIP() << "RELLIS-3D frame not found at " << kRellis.string()
                 << " (see ../shared/datasets/README.md)";
  }
  test::TempDir dir;
  const fs::path source = CAIRN_SOURCE_DIR;
  std::string output;
  const int code =
      RunCairn({"eval", "--points", (kRellis / "os1_bin" / "000104.bin").string(), "--labels",
                (kRellis / "os1_label" / "000104.label").string(), "--classes",
                (source / "config" / "classes" / "rellis3d.yaml").string(), "--sensor", "OS1-64",
                "--config", (source / "config" / "sensors" / "os1-64.yaml").string(), "--methods",
                kReportMethods, "--report", dir.path().string()},
               &output);
  ASSERT_EQ(code, 0) << output;
  for (const char* name :
       {"REPORT.md", "results.csv", "figures/range_image.png", "figures/birds_eye.png"}) {
    EXPECT_TRUE(fs::is_regular_file(dir / name)) << name;
  }
  const std::string made = ReadAll(dir / "REPORT.md");
  const std::string committed = ReadAll(source / "datasets" / "rellis3d" / "REPORT.md");
  for (const char* heading : {"## Scores", "## Per true class", "## Where the errors are"}) {
    const std::string section = Section(made, heading);
    EXPECT_FALSE(section.empty()) << heading;
    EXPECT_EQ(section, Section(committed, heading)) << heading;
  }
  EXPECT_NE(output.find("| cone exact + rules |"), std::string::npos) << output;
}

TEST(EvalLabelsCli, MissingOptionsAndBadMappingAreClearErrors) {
  test::TempDir dir;
  std::string output;
  EXPECT_EQ(RunCairn({"eval", "--points", "scan.bin", "--report", dir.path().string()}, &output),
            1);
  EXPECT_NE(output.find("--labels is required with --points"), std::string::npos) << output;

  output.clear();
  const fs::path bad = dir.Write("bad.yaml", "classes:\n  4: {name: tree, role: tall}\n");
  EXPECT_EQ(RunCairn({"eval", "--points", "scan.bin", "--labels", "scan.label", "--classes",
                      bad.string(), "--sensor", "OS1-64", "--report", dir.path().string()},
                     &output),
            1);
  EXPECT_NE(output.find(bad.string() + ": classes.4.role: expected obstacle, ground or "
                                       "ignored, got 'tall'"),
            std::string::npos)
      << output;

  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--labels", "scan.label", "--world", "w.yaml", "--report",
                      dir.path().string()},
                     &output),
            1);
  EXPECT_NE(output.find("--labels needs --points"), std::string::npos) << output;
}

// The map study runs on its own worlds (`cairn eval --maps`): frames or scans with it are an
// error, and so is a source tree without its worlds (checked before any drive is mapped).
TEST(EvalMapsCli, TheMapStudyTakesNoFramesAndNeedsItsWorlds) {
  test::TempDir dir;
  std::string output;
  EXPECT_EQ(
      RunCairn({"eval", "--maps", "--world", "w.yaml", "--report", dir.path().string()}, &output),
      1);
  EXPECT_NE(output.find("--maps runs the map study on its own worlds"), std::string::npos)
      << output;
  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--maps", "--root", dir.path().string(), "--report",
                      (dir.path() / "out").string()},
                     &output),
            1);
  EXPECT_NE(output.find((dir.path() / "config" / "default.yaml").string()), std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(dir.path() / "out" / "REPORT.md"));
  // --euroc runs on its own or as a section of the map study (checked before any drive),
  // and every other mode needs --report.
  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--euroc", dir.path().string(), "--world", "w.yaml"}, &output), 1);
  EXPECT_NE(output.find("--euroc runs on its own or with --maps"), std::string::npos) << output;
  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--maps", "--euroc", dir.path().string(), "--report",
                      (dir.path() / "out").string()},
                     &output),
            1);
  EXPECT_NE(output.find("expected the EuRoC V1_01 folder"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(dir.path() / "out" / "REPORT.md"));
  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--world", "w.yaml"}, &output), 1);
  EXPECT_NE(output.find("--report is required"), std::string::npos) << output;
  output.clear();
  EXPECT_EQ(RunCairn({"eval", "--maps", "--euroc", dir.path().string()}, &output), 1);
  EXPECT_NE(output.find("--report is required"), std::string::npos) << output;
}

#endif  // CAIRN_EXE

}  // namespace
}  // namespace cairn::eval
