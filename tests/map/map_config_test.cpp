// MapConfig's validation and the strict `map:` section loader.
#include "cairn/map/map_config.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "cairn/map/map_config_file.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/units.hpp"

namespace cairn::map {
namespace {

TEST(MapConfig, DefaultsValidate) { EXPECT_TRUE(MapConfig{}.Validate().ok()); }

TEST(MapConfig, ValidateNamesTheBadField) {
  struct Case {
    std::function<void(MapConfig&)> spoil;
    const char* key;
  };
  const std::vector<Case> cases = {
      {[](MapConfig& c) { c.voxel_size_m = 0.0; }, "voxel_size"},
      {[](MapConfig& c) { c.voxel_size_m = 1e-4; }, "voxel_size"},
      {[](MapConfig& c) { c.max_range_m = -1.0; }, "max_range"},
      {[](MapConfig& c) { c.voxel_hit_probability = 0.4; }, "voxel_hit"},
      {[](MapConfig& c) { c.voxel_miss_probability = 0.6; }, "voxel_miss"},
      {[](MapConfig& c) { c.voxel_min_probability = 0.0; }, "voxel_min"},
      {[](MapConfig& c) { c.voxel_max_probability = 1.0; }, "voxel_max"},
      {[](MapConfig& c) { c.cell_size_m = std::nan(""); }, "cell_size"},
      {[](MapConfig& c) { c.window_size_m = 0.5; }, "window_size"},
      {[](MapConfig& c) { c.window_size_m = -3.0; }, "window_size"},
      {[](MapConfig& c) { c.cell_hit_probability = 0.5; }, "cell_hit"},
      {[](MapConfig& c) { c.cell_miss_probability = 0.5; }, "cell_miss"},
      {[](MapConfig& c) { c.cell_min_probability = 0.7; }, "cell_min"},
      {[](MapConfig& c) { c.cell_max_probability = 0.2; }, "cell_max"},
      {[](MapConfig& c) { c.obstacle_probability = 0.99; }, "obstacle_probability"},
      {[](MapConfig& c) { c.obstacle_min_height_m = -0.1; }, "obstacle_min_height"},
      {[](MapConfig& c) { c.ground_radius_m = -1.0; }, "ground_radius"},
      {[](MapConfig& c) { c.ground_max_slope_rad = 90.0 * kDegToRad; }, "ground_max_slope"},
      {[](MapConfig& c) { c.merge_distance_m = INFINITY; }, "merge_distance"},
      {[](MapConfig& c) { c.plane_fit_radius_m = 0.0; }, "plane_fit_radius"},
      {[](MapConfig& c) { c.slope_cost_max_rad = 95.0 * kDegToRad; }, "slope_cost_max"},
      {[](MapConfig& c) { c.roughness_cost_max_m = 0.0; }, "roughness_cost_max"},
      {[](MapConfig& c) { c.robot_radius_m = -0.5; }, "robot_radius"},
      {[](MapConfig& c) { c.inflation_radius_m = 0.3; }, "inflation_radius"},
      {[](MapConfig& c) { c.cost_scaling_factor = -1.0; }, "cost_scaling_factor"},
  };
  for (const Case& c : cases) {
    MapConfig config;
    c.spoil(config);
    const Status s = config.Validate();
    ASSERT_FALSE(s.ok()) << c.key;
    EXPECT_NE(s.message().find(std::string("'") + c.key + "'"), std::string::npos)
        << c.key << ": " << s.message();
  }
}

TEST(MapConfigFile, ReadsTheMapSectionInFileUnits) {
  const Expected<MapConfig> c = ParseMapConfig(
      "detector: {min_height: 0.3}\n"
      "map:\n"
      "  voxel_size: 0.05\n"
      "  cell_size: 0.25\n"
      "  window_size: 30\n"
      "  slope_cost_max: 20\n"
      "  robot_radius: 0.7\n"
      "  inflation_radius: 2\n"
      "  threads: 3\n",
      "test.yaml");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_DOUBLE_EQ(c->voxel_size_m, 0.05);
  EXPECT_DOUBLE_EQ(c->cell_size_m, 0.25);
  EXPECT_DOUBLE_EQ(c->window_size_m, 30.0);
  EXPECT_NEAR(c->slope_cost_max_rad, 20.0 * kDegToRad, 1e-15);
  EXPECT_DOUBLE_EQ(c->robot_radius_m, 0.7);
  EXPECT_DOUBLE_EQ(c->inflation_radius_m, 2.0);
  EXPECT_EQ(c->threads, 3);
  EXPECT_DOUBLE_EQ(c->max_range_m, MapConfig{}.max_range_m);  // absent: default
}

TEST(MapConfigFile, NoMapSectionGivesTheDefaults) {
  const Expected<MapConfig> c = ParseMapConfig("rules: {min_points: 3}\n", "test.yaml");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_DOUBLE_EQ(c->cell_size_m, MapConfig{}.cell_size_m);
  EXPECT_TRUE(ParseMapConfig("", "empty.yaml").ok());
  EXPECT_TRUE(ParseMapConfig("map:\n", "null.yaml").ok());
}

TEST(MapConfigFile, ErrorsNameTheFileAndTheField) {
  const struct {
    const char* yaml;
    const char* expected;
  } cases[] = {
      {"map: {cell_sise: 0.2}\n", "test.yaml: map.cell_sise: unknown key in map"},
      {"map: {cell_size: abc}\n", "test.yaml: map.cell_size: expected a number"},
      {"map: {cell_size: [1, 2]}\n", "test.yaml: map.cell_size: expected a number"},
      {"map: {cell_size: .nan}\n", "test.yaml: map.cell_size: expected a finite number"},
      {"map: {cell_size: 0.2, cell_size: 0.3}\n", "test.yaml: map.cell_size: given twice"},
      {"map: {cell_size: -0.2}\n", "test.yaml: map.cell_size: map config: 'cell_size'"},
      {"map: {inflation_radius: 0.2}\n", "test.yaml: map.inflation_radius:"},
      {"map: {slope_cost_max: 90}\n", "test.yaml: map.slope_cost_max:"},
      {"map: {threads: -1}\n",
       "test.yaml: map.threads: map config: 'threads' must be an integer in 0..256"},
      {"map: {threads: 99999999999}\n", "test.yaml: map.threads: map config: 'threads'"},
      {"map: {threads: 1.5}\n", "test.yaml: map.threads: expected an integer"},
      {"map: 3\n", "test.yaml: map: expected a mapping"},
      {"- 1\n- 2\n", "test.yaml: expected a mapping"},
      {"map: {cell_size: 0.2\n", "test.yaml:"},
  };
  for (const auto& c : cases) {
    const Expected<MapConfig> r = ParseMapConfig(c.yaml, "test.yaml");
    ASSERT_FALSE(r.ok()) << c.yaml;
    EXPECT_EQ(r.error().message.rfind(c.expected, 0), 0u)
        << c.yaml << " gave: " << r.error().message;
  }
}

TEST(MapConfigFile, DefaultYamlHasAMapSectionThatBothLoadersAccept) {
  const std::filesystem::path file =
      std::filesystem::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml";
  const Expected<MapConfig> map = LoadMapConfig(file);
  ASSERT_TRUE(map.ok()) << map.error().message;
  // The file documents the built-in defaults.
  const MapConfig defaults;
  EXPECT_DOUBLE_EQ(map->voxel_size_m, defaults.voxel_size_m);
  EXPECT_DOUBLE_EQ(map->cell_size_m, defaults.cell_size_m);
  EXPECT_DOUBLE_EQ(map->max_range_m, defaults.max_range_m);
  EXPECT_DOUBLE_EQ(map->window_size_m, defaults.window_size_m);
  EXPECT_NEAR(map->slope_cost_max_rad, defaults.slope_cost_max_rad, 1e-12);
  EXPECT_DOUBLE_EQ(map->robot_radius_m, defaults.robot_radius_m);
  EXPECT_DOUBLE_EQ(map->inflation_radius_m, defaults.inflation_radius_m);
  EXPECT_DOUBLE_EQ(map->cost_scaling_factor, defaults.cost_scaling_factor);
  EXPECT_DOUBLE_EQ(map->obstacle_min_height_m, defaults.obstacle_min_height_m);
  EXPECT_NEAR(map->ground_max_slope_rad, defaults.ground_max_slope_rad, 1e-12);
  EXPECT_TRUE(od::io::LoadDetectSettings(file, MapperSettingsSections()).ok());
  // And the tilt step's, gravity and vertical cues included.
  const Expected<MapperSettings> mapper = LoadMapperSettings(file);
  ASSERT_TRUE(mapper.ok()) << mapper.error().message;
  const TiltConfig tilt;
  const GravityEstimatorConfig& g = mapper->mapper.tilt.gravity;
  EXPECT_EQ(g.window_frames, tilt.gravity.window_frames);
  EXPECT_DOUBLE_EQ(g.accel_sigma_mps2, tilt.gravity.accel_sigma_mps2);
  EXPECT_DOUBLE_EQ(g.gyro_sigma_radps, tilt.gravity.gyro_sigma_radps);
  EXPECT_DOUBLE_EQ(g.motion_sigma_mps2, tilt.gravity.motion_sigma_mps2);
  EXPECT_DOUBLE_EQ(g.odometry_sigma_m, tilt.gravity.odometry_sigma_m);
  EXPECT_DOUBLE_EQ(g.odometry_walk_sigma, tilt.gravity.odometry_walk_sigma);
  EXPECT_DOUBLE_EQ(g.attitude_prior_sigma_rad, tilt.gravity.attitude_prior_sigma_rad);
  EXPECT_DOUBLE_EQ(g.attitude_bias_sigma_rad, tilt.gravity.attitude_bias_sigma_rad);
  EXPECT_DOUBLE_EQ(g.accel_bias_sigma_mps2, tilt.gravity.accel_bias_sigma_mps2);
  EXPECT_DOUBLE_EQ(g.gyro_bias_sigma_radps, tilt.gravity.gyro_bias_sigma_radps);
  EXPECT_DOUBLE_EQ(g.mount_sigma_rad, tilt.gravity.mount_sigma_rad);
  EXPECT_DOUBLE_EQ(g.odometry_scale_sigma, tilt.gravity.odometry_scale_sigma);
  EXPECT_DOUBLE_EQ(mapper->mapper.tilt.gravity_ground_sigma_m, tilt.gravity_ground_sigma_m);
  EXPECT_EQ(mapper->mapper.tilt.gravity_ground_min_verticals, tilt.gravity_ground_min_verticals);
  EXPECT_EQ(mapper->mapper.tilt.gravity_rise_frames_back, tilt.gravity_rise_frames_back);
  EXPECT_DOUBLE_EQ(mapper->mapper.tilt.gravity_rise_sigma_m, tilt.gravity_rise_sigma_m);
  EXPECT_DOUBLE_EQ(mapper->mapper.tilt.smooth_ground_sigma_m, tilt.smooth_ground_sigma_m);
  EXPECT_EQ(mapper->mapper.tilt.smooth, tilt.smooth);
  const VerticalCueConfig& v = mapper->mapper.tilt.verticals;
  EXPECT_DOUBLE_EQ(v.min_height_m, tilt.verticals.min_height_m);
  EXPECT_EQ(v.min_points, tilt.verticals.min_points);
  EXPECT_DOUBLE_EQ(v.min_elongation, tilt.verticals.min_elongation);
  EXPECT_DOUBLE_EQ(v.max_radius_m, tilt.verticals.max_radius_m);
  EXPECT_DOUBLE_EQ(v.min_wall_width_m, tilt.verticals.min_wall_width_m);
  EXPECT_DOUBLE_EQ(v.min_flatness, tilt.verticals.min_flatness);
  EXPECT_DOUBLE_EQ(v.max_angle_rad, tilt.verticals.max_angle_rad);
  EXPECT_DOUBLE_EQ(v.max_range_m, tilt.verticals.max_range_m);
  EXPECT_EQ(v.walls, tilt.verticals.walls);
  const Expected<MapConfig> missing = LoadMapConfig("/nonexistent/cairn.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("/nonexistent/cairn.yaml"), std::string::npos);
}

}  // namespace
}  // namespace cairn::map
