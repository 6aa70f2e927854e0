#include "cairn/map/mapper_config_file.hpp"

#include <cstdint>
#include <vector>

#include "cairn/map/map_config_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::map {
namespace {

namespace yaml = util;  // the strict field reader
using util::DoubleField;
using util::IntField;
using util::ReadFields;

Status ParseTilt(const yaml::FieldReader& reader, const YAML::Node& root, TiltConfig& tilt) {
  const YAML::Node section = root["tilt"];
  if (!section || section.IsNull()) return {};
  TiltRefinerConfig& c = tilt.refiner;
  const std::vector<DoubleField> doubles = {{"prior_sigma", &c.prior_sigma_rad, kDegToRad},
                                            {"prior_sigma_z", &c.prior_sigma_z_m, 1.0},
                                            {"huber", &c.huber_m, 1.0},
                                            {"max_range", &c.max_range_m, 1.0}};
  const std::vector<IntField> ints = {{"max_points", &c.max_points, 0, 100000000},
                                      {"min_points", &c.min_points, 0, 100000000},
                                      {"max_iterations", &c.max_iterations, 0, 100000000}};
  if (Status s = ReadFields(reader, section, "tilt", doubles, ints, {"refine", "mode"}); !s) {
    return s;
  }
  if (section["refine"] && section["mode"]) {
    return reader.Fail("tilt.refine", "give tilt.mode or tilt.refine, not both");
  }
  if (const YAML::Node v = section["mode"]) {
    Expected<TiltMode> mode = ParseTiltMode(v.IsScalar() ? v.Scalar() : std::string());
    if (!mode) {
      return reader.Fail("tilt.mode", "expected prior, refine_to_map or gravity, got " +
                                          yaml::Describe(v));
    }
    tilt.mode = *mode;
  }
  if (const YAML::Node v = section["refine"]) {
    bool refine = false, ok = v.IsScalar();
    if (ok) {
      try {
        refine = v.as<bool>();
      } catch (const YAML::Exception&) {
        ok = false;
      }
    }
    if (!ok) return reader.Fail("tilt.refine", "expected true or false, got " + yaml::Describe(v));
    tilt.mode = refine ? TiltMode::kRefineToMap : TiltMode::kPrior;
  }
  if (Status s = c.Validate(); !s) return reader.Fail("tilt", s.message());
  return {};
}

Status ParseFrames(const yaml::FieldReader& reader, const YAML::Node& root,
                   FrameCheckConfig& frames) {
  const YAML::Node section = root["frames"];
  if (!section || section.IsNull()) return {};
  const std::vector<DoubleField> doubles = {
      {"max_speed", &frames.max_speed_mps, 1.0},
      {"max_turn_rate", &frames.max_turn_rate_radps, kDegToRad}};
  const std::vector<IntField> ints = {{"min_valid_points", &frames.min_valid_points, 1, 1000000000}};
  if (Status s = ReadFields(reader, section, "frames", doubles, ints, {}); !s) return s;
  if (Status s = frames.Validate(); !s) {
    for (const char* key : {"min_valid_points", "max_speed", "max_turn_rate"}) {
      if (s.message().find(std::string("'") + key + "'") != std::string::npos) {
        return reader.Fail(std::string("frames.") + key, s.message());
      }
    }
    return reader.Fail("frames", s.message());
  }
  return {};
}

}  // namespace

const std::vector<std::string>& MapperSettingsSections() {
  static const std::vector<std::string> sections = {"map", "tilt", "frames"};
  return sections;
}

Expected<MapperSettings> ParseMapperSettings(const std::string& yaml_text,
                                             const std::string& source) {
  MapperSettings settings;
  // Parsed once; each library reads its own sections with the same strict reader.
  Expected<YAML::Node> root = yaml::ParseYaml(yaml_text, source);
  if (!root) return root.error();
  if (root->IsNull()) return settings;  // an empty file sets nothing
  const yaml::FieldReader reader(source);
  Expected<od::io::DetectSettings> detect =
      od::io::ReadDetectSettings(*root, reader, MapperSettingsSections());
  if (!detect) return detect.error();
  settings.mapper.detector = detect->detector;
  settings.mapper.rules = detect->rules;
  settings.stereo = detect->stereo;
  Expected<MapConfig> map = ReadMapConfig(*root, reader);
  if (!map) return map.error();
  settings.mapper.map = *map;
  if (root->IsMap()) {
    if (Status s = ParseTilt(reader, *root, settings.mapper.tilt); !s) return s.error();
    if (Status s = ParseFrames(reader, *root, settings.mapper.frames); !s) return s.error();
  }
  if (Status s = settings.mapper.Validate(); !s) return Error{source + ": " + s.message()};
  return settings;
}

Expected<MapperSettings> LoadMapperSettings(const std::filesystem::path& path) {
  if (path.empty()) return MapperSettings{};
  Expected<std::string> text = yaml::ReadTextFile(path);
  if (!text) return text.error();
  return ParseMapperSettings(*text, path.string());
}

}  // namespace cairn::map
