#include "cairn/map/map_config_file.hpp"

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::map {
namespace {

using Field = util::DoubleField;

std::vector<Field> Fields(MapConfig& c) {
  return {{"voxel_size", &c.voxel_size_m, 1.0},
          {"max_range", &c.max_range_m, 1.0},
          {"voxel_hit", &c.voxel_hit_probability, 1.0},
          {"voxel_miss", &c.voxel_miss_probability, 1.0},
          {"voxel_min", &c.voxel_min_probability, 1.0},
          {"voxel_max", &c.voxel_max_probability, 1.0},
          {"cell_size", &c.cell_size_m, 1.0},
          {"window_size", &c.window_size_m, 1.0},
          {"cell_hit", &c.cell_hit_probability, 1.0},
          {"cell_miss", &c.cell_miss_probability, 1.0},
          {"cell_min", &c.cell_min_probability, 1.0},
          {"cell_max", &c.cell_max_probability, 1.0},
          {"obstacle_probability", &c.obstacle_probability, 1.0},
          {"obstacle_min_height", &c.obstacle_min_height_m, 1.0},
          {"ground_radius", &c.ground_radius_m, 1.0},
          {"ground_max_slope", &c.ground_max_slope_rad, kDegToRad},
          {"merge_distance", &c.merge_distance_m, 1.0},
          {"plane_fit_radius", &c.plane_fit_radius_m, 1.0},
          {"slope_cost_max", &c.slope_cost_max_rad, kDegToRad},
          {"roughness_cost_max", &c.roughness_cost_max_m, 1.0},
          {"robot_radius", &c.robot_radius_m, 1.0},
          {"inflation_radius", &c.inflation_radius_m, 1.0},
          {"cost_scaling_factor", &c.cost_scaling_factor, 1.0}};
}

}  // namespace

Expected<MapConfig> ParseMapConfig(const std::string& yaml_text, const std::string& source) {
  Expected<YAML::Node> root = util::ParseYaml(yaml_text, source);
  if (!root) return root.error();
  return ReadMapConfig(*root, util::FieldReader(source));
}

Expected<MapConfig> ReadMapConfig(const YAML::Node& root, const util::FieldReader& reader) {
  MapConfig config;
  if (root.IsNull()) return config;  // an empty file sets nothing
  if (!root.IsMap()) {
    return Error{reader.source() + ": expected a mapping of sections, got " +
                 util::Describe(root)};
  }
  const std::vector<Field> fields = Fields(config);
  const YAML::Node section = root["map"];
  if (Status s = util::ReadFields(reader, section, "map", fields, {}, {"threads"}); !s) {
    return s.error();
  }
  if (section && !section.IsNull()) {
    if (const YAML::Node value = section["threads"]) {
      Expected<std::int64_t> v = reader.Integer(value, "map.threads");
      if (!v) return v.error();
      // Out of int's range: Validate() names it below.
      config.threads = static_cast<int>(std::clamp<std::int64_t>(*v, -1, 1 << 20));
    }
  }
  if (Status s = config.Validate(); !s) {
    // Validate() quotes the key it is about: 'cell_size'.
    if (s.message().find("'threads'") != std::string::npos) {
      return reader.Fail("map.threads", s.message());
    }
    for (const Field& f : fields) {
      if (s.message().find(std::string("'") + f.key + "'") != std::string::npos) {
        return reader.Fail(std::string("map.") + f.key, s.message());
      }
    }
    return reader.Fail("map", s.message());
  }
  return config;
}

Expected<MapConfig> LoadMapConfig(const std::filesystem::path& path) {
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  return ParseMapConfig(*text, path.string());
}

}  // namespace cairn::map
