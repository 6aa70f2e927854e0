#include "cairn/od/io/detect_config.hpp"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <limits>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::od::io {
namespace {

/// degrees to radians, integers range-checked, names to enums.
enum class Kind { kNumber, kDegrees, kInt, kInt64, kSearchMode, kStereoMode };

/// One settable value: its key in the file and the struct member it lands in. `member`
/// is the struct's field name, used to find which key a Validate() message is about.
struct Field {
  const char* key;
  Kind kind;
  const char* member;
  void* target;
};

std::vector<Field> DetectorFields(DetectorConfig& c) {
  return {{"min_height", Kind::kNumber, "min_height_m", &c.min_height_m},
          {"max_height", Kind::kNumber, "max_height_m", &c.max_height_m},
          {"min_slope", Kind::kDegrees, "min_slope_rad", &c.min_slope_rad},
          {"search", Kind::kSearchMode, "search", &c.search},
          {"window_scale", Kind::kNumber, "window_scale", &c.window_scale},
          {"region_slabs", Kind::kInt, "region_slabs", &c.region_slabs},
          {"threads", Kind::kInt, "threads", &c.threads},
          {"min_range", Kind::kNumber, "min_range_m", &c.min_range_m}};
}

std::vector<Field> RuleFields(RuleConfig& c) {
  return {{"min_points", Kind::kInt, "min_points", &c.min_points},
          {"min_volume", Kind::kNumber, "min_volume_m3", &c.min_volume_m3},
          {"min_perimeter", Kind::kNumber, "min_perimeter_m", &c.min_perimeter_m},
          {"min_slope_mean", Kind::kDegrees, "min_slope_mean_rad", &c.min_slope_mean_rad},
          {"min_slope_max", Kind::kDegrees, "min_slope_max_rad", &c.min_slope_max_rad},
          {"min_height_mean", Kind::kNumber, "min_height_mean_m", &c.min_height_mean_m},
          {"min_height_max", Kind::kNumber, "min_height_max_m", &c.min_height_max_m},
          {"min_raised", Kind::kInt, "min_raised", &c.min_raised}};
}

std::vector<Field> ColumnFields(DetectSettings& s) {
  return {{"min_blob_pixels", Kind::kInt, "min_blob_pixels", &s.min_blob_pixels}};
}

std::vector<Field> StereoFields(StereoConfig& c) {
  return {{"min_depth", Kind::kNumber, "min_depth_m", &c.min_depth_m},
          {"num_disparities", Kind::kInt, "num_disparities", &c.num_disparities},
          {"max_depth", Kind::kNumber, "max_depth_m", &c.max_depth_m},
          {"block_size", Kind::kInt, "block_size", &c.block_size},
          {"p1", Kind::kInt, "p1", &c.p1},
          {"p2", Kind::kInt, "p2", &c.p2},
          {"uniqueness", Kind::kInt, "uniqueness", &c.uniqueness},
          {"speckle_window", Kind::kInt, "speckle_window", &c.speckle_window},
          {"speckle_range", Kind::kInt, "speckle_range", &c.speckle_range},
          {"disp12_max_diff", Kind::kInt, "disp12_max_diff", &c.disp12_max_diff},
          {"pre_filter_cap", Kind::kInt, "pre_filter_cap", &c.pre_filter_cap},
          {"mode", Kind::kStereoMode, "mode", &c.mode},
          {"min_texture", Kind::kNumber, "min_texture", &c.min_texture},
          {"disparity_sigma", Kind::kNumber, "disparity_sigma_px", &c.disparity_sigma_px}};
}

std::vector<std::string> Keys(const std::vector<Field>& fields) {
  std::vector<std::string> keys;
  for (const Field& f : fields) keys.emplace_back(f.key);
  return keys;
}

Status ReadField(const util::FieldReader& reader, const YAML::Node& node, const std::string& name,
                 const Field& f) {
  switch (f.kind) {
    case Kind::kNumber:
    case Kind::kDegrees: {
      Expected<double> v = reader.Double(node, name);
      if (!v) return v.error();
      *static_cast<double*>(f.target) = f.kind == Kind::kDegrees ? *v * kDegToRad : *v;
      return Status::Ok();
    }
    case Kind::kInt:
    case Kind::kInt64: {
      Expected<std::int64_t> v = reader.Integer(node, name);
      if (!v) return v.error();
      if (f.kind == Kind::kInt64) {
        *static_cast<std::int64_t*>(f.target) = *v;
      } else {
        if (*v < std::numeric_limits<int>::min() || *v > std::numeric_limits<int>::max()) {
          return reader.Fail(name, "integer out of range, got " + util::Describe(node));
        }
        *static_cast<int*>(f.target) = static_cast<int>(*v);
      }
      return Status::Ok();
    }
    case Kind::kSearchMode: {
      Expected<std::string> v = reader.String(node, name);
      if (!v) return v.error();
      if (*v == "exact") {
        *static_cast<SearchMode*>(f.target) = SearchMode::kExact;
      } else if (*v == "paper_window") {
        *static_cast<SearchMode*>(f.target) = SearchMode::kPaperWindow;
      } else {
        return reader.Fail(name, "expected exact or paper_window, got " + util::Describe(node));
      }
      return Status::Ok();
    }
    case Kind::kStereoMode: {
      Expected<std::string> v = reader.String(node, name);
      if (!v) return v.error();
      for (StereoMode mode :
           {StereoMode::kSgbm, StereoMode::kSgbm3Way, StereoMode::kHh, StereoMode::kHh4}) {
        if (*v == StereoModeName(mode)) {
          *static_cast<StereoMode*>(f.target) = mode;
          return Status::Ok();
        }
      }
      return reader.Fail(name,
                         "expected sgbm, sgbm_3way, hh or hh4, got " + util::Describe(node));
    }
  }
  return Status::Ok();
}

/// Reads the keys present in `section` (a mapping, or null for "nothing set").
Status ReadSection(const util::FieldReader& reader, const YAML::Node& root,
                   const std::string& section, const std::vector<Field>& fields) {
  const YAML::Node node = root[section];
  if (!node || node.IsNull()) return Status::Ok();
  if (Status s = reader.CheckMapping(node, section, Keys(fields)); !s) return s;
  for (const Field& f : fields) {
    const YAML::Node value = node[f.key];
    if (!value) continue;
    if (Status s = ReadField(reader, value, section + "." + f.key, f); !s) return s;
  }
  return Status::Ok();
}

/// Where `name` first occurs in `message` as a whole identifier ("min_height" is not inside
/// "min_height_mean"), or npos.
std::size_t FindIdentifier(const std::string& message, const std::string& name) {
  const auto is_ident = [&](std::size_t i) {
    const char ch = message[i];
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '_';
  };
  for (std::size_t pos = message.find(name); pos != std::string::npos;
       pos = message.find(name, pos + 1)) {
    const std::size_t end = pos + name.size();
    if ((pos == 0 || !is_ident(pos - 1)) && (end == message.size() || !is_ident(end))) {
      return pos;
    }
  }
  return std::string::npos;
}

/// A Validate() failure, prefixed with the file and the key it is about: the field whose
/// key or struct member the message names first (the section when it names none).
Error Located(const util::FieldReader& reader, const std::string& section,
              const std::vector<Field>& fields, const std::string& message) {
  const Field* best = nullptr;
  std::size_t best_pos = std::string::npos;
  for (const Field& f : fields) {
    const std::size_t pos =
        std::min(FindIdentifier(message, f.key), FindIdentifier(message, f.member));
    if (pos < best_pos) {
      best_pos = pos;
      best = &f;
    }
  }
  return reader.Fail(best ? section + "." + best->key : section, message);
}

}  // namespace

const char* SearchModeName(SearchMode mode) {
  switch (mode) {
    case SearchMode::kExact:
      return "exact";
    case SearchMode::kPaperWindow:
      return "paper_window";
  }
  return "unknown";
}

Expected<DetectSettings> ParseDetectSettings(const std::string& yaml_text,
                                             const std::string& source,
                                             const std::vector<std::string>& other_sections) {
  Expected<YAML::Node> root = util::ParseYaml(yaml_text, source);
  if (!root) return root.error();
  return ReadDetectSettings(*root, util::FieldReader(source), other_sections);
}

Expected<DetectSettings> ReadDetectSettings(const YAML::Node& root,
                                            const util::FieldReader& reader,
                                            const std::vector<std::string>& other_sections) {
  // One settings file configures every stage; the other stages' sections are read, as
  // strictly, by their own loaders.
  std::vector<std::string> sections = DetectSettingsSections();
  sections.insert(sections.end(), other_sections.begin(), other_sections.end());
  if (Status s = reader.CheckMapping(root, "", sections); !s) return s.error();

  DetectSettings settings;
  const std::vector<Field> detector = DetectorFields(settings.detector);
  const std::vector<Field> rules = RuleFields(settings.rules);
  const std::vector<Field> column = ColumnFields(settings);
  const std::vector<Field> stereo = StereoFields(settings.stereo);
  if (Status s = ReadSection(reader, root, "detector", detector); !s) return s.error();
  if (Status s = ReadSection(reader, root, "rules", rules); !s) return s.error();
  if (Status s = ReadSection(reader, root, "column", column); !s) return s.error();
  if (Status s = ReadSection(reader, root, "stereo", stereo); !s) return s.error();

  if (Status s = settings.detector.Validate(); !s) {
    return Located(reader, "detector", detector, s.message());
  }
  // Physical ranges beyond DetectorConfig::Validate's consistency checks: obstacles of a
  // ground vehicle's world, ranges of its sensors.
  if (settings.detector.max_height_m > 100.0) {
    return reader.Fail("detector.max_height", "expected a height in (min_height, 100] m, got " +
                                                  std::to_string(settings.detector.max_height_m));
  }
  if (settings.detector.min_range_m > 1000.0) {
    return reader.Fail("detector.min_range", "expected a range in [0, 1000] m, got " +
                                                 std::to_string(settings.detector.min_range_m));
  }
  if (settings.detector.window_scale > 100.0) {
    return reader.Fail("detector.window_scale", "expected a factor in (0, 100], got " +
                                                    std::to_string(settings.detector.window_scale));
  }
  if (Status s = settings.rules.Validate(); !s) {
    return Located(reader, "rules", rules, s.message());
  }
  ColumnConfig column_config = ColumnConfig::From(settings.detector);
  column_config.min_blob_pixels = settings.min_blob_pixels;
  if (Status s = column_config.Validate(); !s) {
    return Located(reader, "column", column, s.message());
  }
  if (Status s = settings.stereo.Validate(); !s) {
    return Located(reader, "stereo", stereo, s.message());
  }
  return settings;
}

const std::vector<std::string>& DetectSettingsSections() {
  static const std::vector<std::string> sections = {"detector", "rules", "column", "stereo"};
  return sections;
}

Expected<DetectSettings> LoadDetectSettings(const std::filesystem::path& path,
                                            const std::vector<std::string>& other_sections) {
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  return ParseDetectSettings(*text, path.string(), other_sections);
}

}  // namespace cairn::od::io
