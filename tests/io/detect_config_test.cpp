#include "cairn/od/io/detect_config.hpp"

#include <gtest/gtest.h>

#include <string>

#include "cairn/od/units.hpp"
#include "temp_dir.hpp"

namespace cairn::od::io {
namespace {

testing::AssertionResult StartsWith(const std::string& text, const std::string& prefix) {
  if (text.rfind(prefix, 0) == 0) return testing::AssertionSuccess();
  return testing::AssertionFailure()
         << "\"" << text << "\" does not start with \"" << prefix << "\"";
}

TEST(DetectSettings, ReadsEveryKeyDegreesToRadians) {
  const std::string yaml = R"(
detector:
  min_height: 0.25
  max_height: 1.2
  min_slope: 30
  search: paper_window
  window_scale: 5
  region_slabs: 8
  threads: 3
rules:
  min_points: 12
  min_volume: 0.01
  min_perimeter: 0.5
  min_slope_mean: 50
  min_slope_max: 60
  min_height_mean: 0.1
  min_height_max: 0.3
  min_raised: 100
column:
  min_blob_pixels: 25
)";
  Expected<DetectSettings> s = ParseDetectSettings(yaml, "cfg.yaml");
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_DOUBLE_EQ(s->detector.min_height_m, 0.25);
  EXPECT_DOUBLE_EQ(s->detector.max_height_m, 1.2);
  EXPECT_DOUBLE_EQ(s->detector.min_slope_rad, 30 * kPi / 180);
  EXPECT_EQ(s->detector.search, SearchMode::kPaperWindow);
  EXPECT_DOUBLE_EQ(s->detector.window_scale, 5.0);
  EXPECT_EQ(s->detector.region_slabs, 8);
  EXPECT_EQ(s->detector.threads, 3);
  EXPECT_EQ(s->rules.min_points, 12);
  EXPECT_DOUBLE_EQ(s->rules.min_volume_m3, 0.01);
  EXPECT_DOUBLE_EQ(s->rules.min_perimeter_m, 0.5);
  EXPECT_DOUBLE_EQ(s->rules.min_slope_mean_rad, 50 * kPi / 180);
  EXPECT_DOUBLE_EQ(s->rules.min_slope_max_rad, 60 * kPi / 180);
  EXPECT_DOUBLE_EQ(s->rules.min_height_mean_m, 0.1);
  EXPECT_DOUBLE_EQ(s->rules.min_height_max_m, 0.3);
  EXPECT_EQ(s->rules.min_raised, 100);
  EXPECT_EQ(s->min_blob_pixels, 25);
}

TEST(DetectSettings, AbsentKeysAndEmptySectionsKeepTheDefaults) {
  Expected<DetectSettings> s =
      ParseDetectSettings("detector:\n  min_height: 0.4\nrules:\n", "cfg.yaml");
  ASSERT_TRUE(s.ok()) << s.error().message;
  const DetectSettings defaults;
  EXPECT_DOUBLE_EQ(s->detector.min_height_m, 0.4);
  EXPECT_DOUBLE_EQ(s->detector.max_height_m, defaults.detector.max_height_m);
  EXPECT_DOUBLE_EQ(s->detector.min_slope_rad, defaults.detector.min_slope_rad);
  EXPECT_EQ(s->detector.search, SearchMode::kExact);
  EXPECT_EQ(s->rules.min_points, defaults.rules.min_points);
  EXPECT_EQ(s->min_blob_pixels, defaults.min_blob_pixels);
}

TEST(DetectSettings, UnknownKeyIsRejectedWithItsName) {
  Expected<DetectSettings> s = ParseDetectSettings("detector:\n  min_heigth: 0.2\n", "cfg.yaml");
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(StartsWith(s.error().message, "cfg.yaml: detector.min_heigth: unknown key"));
}

TEST(DetectSettings, UnknownSectionIsRejectedWithItsName) {
  Expected<DetectSettings> s = ParseDetectSettings("rule:\n  min_points: 3\n", "cfg.yaml");
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(StartsWith(s.error().message, "cfg.yaml: rule: unknown key"));
}

TEST(DetectSettings, KeyOfAnotherSectionIsRejected) {
  Expected<DetectSettings> s = ParseDetectSettings("rules:\n  min_height: 0.3\n", "cfg.yaml");
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(StartsWith(s.error().message, "cfg.yaml: rules.min_height: unknown key"));
}

TEST(DetectSettings, DuplicateKeyIsRejected) {
  Expected<DetectSettings> s =
      ParseDetectSettings("detector:\n  min_height: 0.2\n  min_height: 0.4\n", "cfg.yaml");
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(StartsWith(s.error().message, "cfg.yaml: detector.min_height: given twice"));
}

struct BadCase {
  const char* yaml;
  const char* prefix;  ///< the message starts with it
};

class DetectSettingsBad : public ::testing::TestWithParam<BadCase> {};

TEST_P(DetectSettingsBad, NamesFileAndField) {
  Expected<DetectSettings> s = ParseDetectSettings(GetParam().yaml, "cfg.yaml");
  ASSERT_FALSE(s.ok()) << GetParam().yaml;
  EXPECT_TRUE(StartsWith(s.error().message, GetParam().prefix));
}

INSTANTIATE_TEST_SUITE_P(
    Cases, DetectSettingsBad,
    ::testing::Values(
        // Wrong types and non-finite numbers.
        BadCase{"detector:\n  min_height: low\n", "cfg.yaml: detector.min_height: expected a"},
        BadCase{"detector:\n  max_height: .inf\n", "cfg.yaml: detector.max_height: expected a"},
        BadCase{"detector:\n  search: fast\n", "cfg.yaml: detector.search: expected exact"},
        BadCase{"detector:\n  region_slabs: 2.5\n", "cfg.yaml: detector.region_slabs: expected"},
        BadCase{"rules:\n  min_points: 1.5\n", "cfg.yaml: rules.min_points: expected an integer"},
        BadCase{"rules:\n  min_volume: [1]\n", "cfg.yaml: rules.min_volume: expected a number"},
        BadCase{"column:\n  min_blob_pixels: many\n", "cfg.yaml: column.min_blob_pixels: "},
        BadCase{"detector: 3\n", "cfg.yaml: detector: expected a mapping"},
        BadCase{"- detector\n", "cfg.yaml: expected a mapping"},
        // Out of range: Validate()'s message, located.
        BadCase{"detector:\n  min_height: 0.5\n  max_height: 0.3\n",
                "cfg.yaml: detector.max_height: "},
        BadCase{"detector:\n  min_height: -0.1\n", "cfg.yaml: detector.min_height: "},
        BadCase{"detector:\n  min_slope: 90\n", "cfg.yaml: detector.min_slope: "},
        BadCase{"detector:\n  window_scale: 0\n", "cfg.yaml: detector.window_scale: "},
        BadCase{"detector:\n  region_slabs: 0\n", "cfg.yaml: detector.region_slabs: "},
        BadCase{"rules:\n  min_volume: -1\n", "cfg.yaml: rules.min_volume: "},
        BadCase{"rules:\n  min_height_max: -0.3\n", "cfg.yaml: rules.min_height_max: "},
        BadCase{"rules:\n  min_raised: -1\n", "cfg.yaml: rules.min_raised: "},
        BadCase{"column:\n  min_blob_pixels: -4\n", "cfg.yaml: column.min_blob_pixels: "}));

TEST(DetectSettings, LoadNamesTheFile) {
  test::TempDir dir;
  const auto path = dir.Write("cfg.yaml", "detector:\n  typo: 1\n");
  Expected<DetectSettings> s = LoadDetectSettings(path);
  ASSERT_FALSE(s.ok());
  EXPECT_TRUE(StartsWith(s.error().message, path.string() + ": detector.typo"));
  Expected<DetectSettings> missing = LoadDetectSettings(dir / "none.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(StartsWith(missing.error().message, (dir / "none.yaml").string() + ": no such"));
}

}  // namespace
}  // namespace cairn::od::io

namespace cairn::od::io {
namespace {

// The detection loader knows no other stage's sections: the caller names them.
TEST(DetectSettings, OtherStagesSectionsAreTheCallersToName) {
  const std::string text = "detector:\n  min_height: 0.25\nmap:\n  cell_size: 0.2\n";
  Expected<DetectSettings> alone = ParseDetectSettings(text, "cfg.yaml");
  ASSERT_FALSE(alone.ok());
  EXPECT_NE(alone.error().message.find("cfg.yaml"), std::string::npos) << alone.error().message;
  EXPECT_NE(alone.error().message.find("map"), std::string::npos) << alone.error().message;
  Expected<DetectSettings> named = ParseDetectSettings(text, "cfg.yaml", {"map"});
  ASSERT_TRUE(named.ok()) << named.error().message;
  EXPECT_DOUBLE_EQ(named->detector.min_height_m, 0.25);
  EXPECT_EQ(DetectSettingsSections(),
            (std::vector<std::string>{"detector", "rules", "column", "stereo"}));
}

// The preset the demo uses parses and says what its comments say.
TEST(DetectSettings, DefaultPresetParses) {
  Expected<DetectSettings> s =
      LoadDetectSettings(std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml",
                         {"map", "tilt", "frames"});  // the Mapper's sections
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_DOUBLE_EQ(s->detector.min_height_m, 0.3);
  EXPECT_DOUBLE_EQ(s->detector.max_height_m, 1.0);
  EXPECT_DOUBLE_EQ(s->detector.min_slope_rad, 45 * kPi / 180);
  EXPECT_EQ(s->detector.search, SearchMode::kExact);
  EXPECT_EQ(s->rules.min_points, 10);
  EXPECT_DOUBLE_EQ(s->rules.min_volume_m3, 0.005);
  EXPECT_DOUBLE_EQ(s->rules.min_height_max_m, 0.3);
}

TEST(DetectSettings, DefaultPresetStatesTheBuiltInDefaults) {
  // config/default.yaml documents the defaults: loading it changes nothing, so a run without
  // --config behaves as one with it.
  Expected<DetectSettings> s =
      LoadDetectSettings(std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml",
                         {"map", "tilt", "frames"});  // the Mapper's sections
  ASSERT_TRUE(s.ok()) << s.error().message;
  const RuleConfig r;
  EXPECT_EQ(s->rules.min_points, r.min_points);
  EXPECT_EQ(s->rules.min_volume_m3, r.min_volume_m3);
  EXPECT_EQ(s->rules.min_perimeter_m, r.min_perimeter_m);
  EXPECT_EQ(s->rules.min_slope_mean_rad, r.min_slope_mean_rad);
  EXPECT_EQ(s->rules.min_slope_max_rad, r.min_slope_max_rad);
  EXPECT_EQ(s->rules.min_height_mean_m, r.min_height_mean_m);
  EXPECT_EQ(s->rules.min_height_max_m, r.min_height_max_m);
  EXPECT_EQ(s->rules.min_raised, r.min_raised);
  const DetectorConfig d;
  EXPECT_EQ(s->detector.min_height_m, d.min_height_m);
  EXPECT_EQ(s->detector.max_height_m, d.max_height_m);
  EXPECT_NEAR(s->detector.min_slope_rad, d.min_slope_rad, 1e-15);
  EXPECT_EQ(s->detector.search, d.search);
  EXPECT_EQ(s->detector.min_range_m, d.min_range_m);
}

}  // namespace
}  // namespace cairn::od::io
