#include "cairn/map/mapper_config_file.hpp"

#include <cmath>
#include <cstdint>
#include <string>
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

// `true` or `false` into each of `fields` present in `section` (named `name`).
struct BoolField {
  const char* key;
  bool* target;
};
Status ReadBools(const yaml::FieldReader& reader, const YAML::Node& section,
                 const std::string& name, const std::vector<BoolField>& fields) {
  for (const BoolField& f : fields) {
    const YAML::Node v = section[f.key];
    if (!v) continue;
    bool ok = v.IsScalar();
    if (ok) {
      try {
        *f.target = v.as<bool>();
      } catch (const YAML::Exception&) {
        ok = false;
      }
    }
    if (!ok) {
      return reader.Fail(name + "." + f.key, "expected true or false, got " + yaml::Describe(v));
    }
  }
  return {};
}

std::vector<std::string> KeysOf(const std::vector<BoolField>& fields) {
  std::vector<std::string> keys;
  for (const BoolField& f : fields) keys.emplace_back(f.key);
  return keys;
}

// A Validate() failure, "<path>: what", as the file's error: prefix + path names the field
// (`section` when the message names none).
Status FailAtField(const yaml::FieldReader& reader, const Status& failed, const std::string& prefix,
                   const std::string& section) {
  const std::string& m = failed.message();
  const std::size_t colon = m.find(": ");
  if (colon == std::string::npos) return reader.Fail(section, m);
  return reader.Fail(prefix + m.substr(0, colon), m.substr(colon + 2));
}

// tilt.gravity: the estimator's stated noises, priors and switches, under its own field
// names (units in the suffix: _rad, _radps, _mps2, _m), and the frame-to-map ground height's.
Status ParseGravity(const yaml::FieldReader& reader, const YAML::Node& section, TiltConfig& tilt) {
  if (!section || section.IsNull()) return {};
  GravityEstimatorConfig& g = tilt.gravity;
  const std::vector<DoubleField> doubles = {
      {"gravity_mps2", &g.gravity_mps2},
      {"accel_sigma_mps2", &g.accel_sigma_mps2},
      {"motion_sigma_mps2", &g.motion_sigma_mps2},
      {"odometry_sigma_m", &g.odometry_sigma_m},
      {"odometry_walk_sigma", &g.odometry_walk_sigma},
      {"accel_huber", &g.accel_huber},
      {"gyro_sigma_radps", &g.gyro_sigma_radps},
      {"rotation_floor_rad", &g.rotation_floor_rad},
      {"attitude_prior_sigma_rad", &g.attitude_prior_sigma_rad},
      {"attitude_bias_sigma_rad", &g.attitude_bias_sigma_rad},
      {"yaw_sigma_rad", &g.yaw_sigma_rad},
      {"vertical_sigma_rad", &g.vertical_sigma_rad},
      {"vertical_cauchy", &g.vertical_cauchy},
      {"wall_sigma_rad", &g.wall_sigma_rad},
      {"height_step_sigma_m", &g.height_step_sigma_m},
      {"height_step_sigma_per_m", &g.height_step_sigma_per_m},
      {"ground_height_huber", &g.ground_height_huber},
      {"accel_bias_sigma_mps2", &g.accel_bias_sigma_mps2},
      {"gyro_bias_sigma_radps", &g.gyro_bias_sigma_radps},
      {"mount_sigma_rad", &g.mount_sigma_rad},
      {"odometry_scale_sigma", &g.odometry_scale_sigma},
      {"observable_ratio", &g.observable_ratio},
      {"ground_sigma_m", &tilt.gravity_ground_sigma_m},
      {"rise_sigma_m", &tilt.gravity_rise_sigma_m},
      {"smooth_ground_sigma_m", &tilt.smooth_ground_sigma_m}};
  const std::vector<IntField> ints = {
      {"window_frames", &g.window_frames, 2, 10000},
      {"accel_half_span_frames", &g.accel_half_span_frames, 1, 10000},
      {"accel_warmup_spans", &g.accel_warmup_spans, 0, 10000},
      {"max_iterations", &g.max_iterations, 1, 100000000},
      {"ground_min_verticals", &tilt.gravity_ground_min_verticals, 0, 1000000000},
      {"rise_frames_back", &tilt.gravity_rise_frames_back, 0, 10000}};
  const std::vector<BoolField> bools = {{"estimate_accel_bias", &g.estimate_accel_bias},
                                        {"estimate_gyro_bias", &g.estimate_gyro_bias},
                                        {"estimate_mount", &g.estimate_mount},
                                        {"estimate_odometry_scale", &g.estimate_odometry_scale},
                                        {"covariance", &g.covariance}};
  if (Status s = ReadFields(reader, section, "tilt.gravity", doubles, ints, KeysOf(bools)); !s) {
    return s;
  }
  if (Status s = ReadBools(reader, section, "tilt.gravity", bools); !s) return s;
  // Its messages name the field as "gravity.<field>: ...".
  if (Status s = g.Validate(); !s) return FailAtField(reader, s, "tilt.", "tilt.gravity");
  if (!(tilt.gravity_ground_sigma_m > 0.0 && std::isfinite(tilt.gravity_ground_sigma_m))) {
    return reader.Fail("tilt.gravity.ground_sigma_m", "must be > 0 m");
  }
  if (!(tilt.gravity_rise_sigma_m > 0.0 && std::isfinite(tilt.gravity_rise_sigma_m))) {
    return reader.Fail("tilt.gravity.rise_sigma_m", "must be > 0 m");
  }
  if (!(tilt.smooth_ground_sigma_m >= 0.0 && std::isfinite(tilt.smooth_ground_sigma_m))) {
    return reader.Fail("tilt.gravity.smooth_ground_sigma_m", "must be >= 0 m (0: left out)");
  }
  if (tilt.gravity_rise_frames_back >= g.window_frames) {
    return reader.Fail("tilt.gravity.rise_frames_back",
                       "must be under window_frames (" + std::to_string(g.window_frames) + ")");
  }
  return {};
}

// tilt.verticals: which segments are vertical cues.
Status ParseVerticals(const yaml::FieldReader& reader, const YAML::Node& section,
                      VerticalCueConfig& v) {
  if (!section || section.IsNull()) return {};
  const std::vector<DoubleField> doubles = {
      {"min_height", &v.min_height_m},   {"min_elongation", &v.min_elongation},
      {"max_radius", &v.max_radius_m},   {"min_wall_width", &v.min_wall_width_m},
      {"min_flatness", &v.min_flatness}, {"max_angle", &v.max_angle_rad, kDegToRad},
      {"max_range", &v.max_range_m}};
  const std::vector<IntField> ints = {{"min_points", &v.min_points, 3, 1000000000}};
  const std::vector<BoolField> bools = {{"walls", &v.walls}};
  if (Status s = ReadFields(reader, section, "tilt.verticals", doubles, ints, KeysOf(bools)); !s) {
    return s;
  }
  if (Status s = ReadBools(reader, section, "tilt.verticals", bools); !s) return s;
  // Its messages name the field as "tilt.verticals.<field>: ...".
  if (Status s = v.Validate(); !s) return FailAtField(reader, s, "", "tilt.verticals");
  return {};
}

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
  if (Status s = ReadFields(reader, section, "tilt", doubles, ints,
                            {"refine", "mode", "smooth", "gravity", "verticals"});
      !s) {
    return s;
  }
  if (Status s = ParseGravity(reader, section["gravity"], tilt); !s) return s;
  if (Status s = ParseVerticals(reader, section["verticals"], tilt.verticals); !s) return s;
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
  if (Status s = ReadBools(reader, section, "tilt", {{"smooth", &tilt.smooth}}); !s) return s;
  if (section["refine"]) {
    bool refine = false;
    if (Status s = ReadBools(reader, section, "tilt", {{"refine", &refine}}); !s) return s;
    tilt.mode = refine ? TiltMode::kRefineToMap : TiltMode::kPrior;
  }
  if (tilt.smooth && tilt.mode != TiltMode::kGravity) {
    return reader.Fail("tilt.smooth", "smooths the gravity mode's run: set tilt.mode: gravity");
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
