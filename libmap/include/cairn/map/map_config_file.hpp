// The `map:` section of a settings file (config/default.yaml) into a MapConfig.
//
// Strict like the detection settings: an unknown key in `map:`, a duplicate, a value of the
// wrong type or a non-finite number is an error naming the file and the field
// ("config.yaml: map.cell_size: ..."); keys left out keep MapConfig's defaults; an
// out-of-range value gets MapConfig::Validate()'s message, prefixed with the file and the
// field. Other top-level sections belong to other loaders and are not looked at here;
// the file must still be a YAML mapping. Keys are MapConfig's members without their unit
// suffix (voxel_size for voxel_size_m, voxel_hit for voxel_hit_probability); slope_cost_max
// is in degrees.
#pragma once

#include <filesystem>
#include <string>

#include "cairn/map/map_config.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::map {

Expected<MapConfig> LoadMapConfig(const std::filesystem::path& path);

/// The same from YAML text; `source` names it in error messages.
Expected<MapConfig> ParseMapConfig(const std::string& yaml_text, const std::string& source);

/// The same from a settings file already parsed (`root`, its top level); `reader` names it.
Expected<MapConfig> ReadMapConfig(const YAML::Node& root, const util::FieldReader& reader);

}  // namespace cairn::map
