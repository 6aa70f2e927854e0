#include "cairn/util/yaml.hpp"

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

namespace cairn::util {

Expected<std::string> ReadTextFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return Error{path.string() + ": no such file"};
  }
  if (std::filesystem::is_directory(path, ec)) {
    return Error{path.string() + ": is a directory, expected a file"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path.string() + ": cannot open for reading"};
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Error{path.string() + ": read error"};
  return text.str();
}

Expected<YAML::Node> ParseYaml(const std::string& text, const std::string& source) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    // yaml-cpp's marks are 0-based.
    return Error{source + ":" + std::to_string(e.mark.line + 1) + ":" +
                 std::to_string(e.mark.column + 1) + ": invalid YAML: " + e.msg};
  }
}

std::string Describe(const YAML::Node& node) {
  if (!node.IsDefined()) return "nothing";
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "nothing (null)";
    case YAML::NodeType::Scalar:
      return "'" + node.Scalar() + "'";
    case YAML::NodeType::Sequence:
      return "a sequence";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Undefined:
      break;
  }
  return "nothing";
}

Error FieldReader::Fail(const std::string& field, const std::string& what) const {
  return Error{source_ + ": " + field + ": " + what};
}

Status FieldReader::CheckMapping(const YAML::Node& node, const std::string& where,
                                 const std::vector<std::string>& known) const {
  const std::string prefix = where.empty() ? "" : where + ".";
  if (!node.IsMap()) {
    std::string expected = "expected a mapping of";
    for (const std::string& k : known) expected += " " + k + ",";
    expected.pop_back();
    expected += "; got " + Describe(node);
    if (where.empty()) return Error{source_ + ": " + expected};
    return Fail(where, expected);
  }
  std::set<std::string> seen;
  for (const auto& entry : node) {
    if (!entry.first.IsScalar()) {
      return Error{source_ + ": " + (where.empty() ? std::string("top level") : where) +
                   ": keys must be plain names, got " + Describe(entry.first)};
    }
    const std::string key = entry.first.Scalar();
    bool is_known = false;
    for (const std::string& k : known) is_known = is_known || k == key;
    if (!is_known) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      return Fail(prefix + key, std::string("unknown ") +
                                    (where.empty() ? "key" : "key in " + where) +
                                    " (expected one of: " + list + ")");
    }
    if (!seen.insert(key).second) return Fail(prefix + key, "given twice");
  }
  return Status::Ok();
}

Expected<double> FieldReader::Double(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) return Fail(field, "expected a number, got " + Describe(node));
  double value = 0.0;
  try {
    value = node.as<double>();
  } catch (const YAML::Exception&) {
    return Fail(field, "expected a number, got " + Describe(node));
  }
  if (!std::isfinite(value)) {
    return Fail(field, "expected a finite number, got " + Describe(node));
  }
  return value;
}

Expected<std::int64_t> FieldReader::Integer(const YAML::Node& node,
                                            const std::string& field) const {
  if (!node.IsScalar()) return Fail(field, "expected an integer, got " + Describe(node));
  try {
    return node.as<std::int64_t>();
  } catch (const YAML::Exception&) {
    return Fail(field, "expected an integer, got " + Describe(node));
  }
}

Expected<double> Angle(const FieldReader& reader, const YAML::Node& node, const std::string& field,
                       double max_abs_deg) {
  Expected<double> value = reader.Double(node, field);
  if (!value) return value.error();
  if (std::abs(*value) > max_abs_deg) {
    std::ostringstream range;
    range << "expected an angle in [-" << max_abs_deg << ", " << max_abs_deg << "] deg, got "
          << Describe(node);
    return reader.Fail(field, range.str());
  }
  return value;
}

Expected<std::string> FieldReader::String(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) return Fail(field, "expected a name, got " + Describe(node));
  return node.Scalar();
}

Status ReadFields(const FieldReader& reader, const YAML::Node& section, const std::string& name,
                  const std::vector<DoubleField>& doubles, const std::vector<IntField>& ints,
                  std::vector<std::string> other_keys) {
  if (!section || section.IsNull()) return {};
  for (const DoubleField& f : doubles) other_keys.emplace_back(f.key);
  for (const IntField& f : ints) other_keys.emplace_back(f.key);
  if (Status s = reader.CheckMapping(section, name, other_keys); !s) return s;
  for (const DoubleField& f : doubles) {
    if (const YAML::Node v = section[f.key]) {
      Expected<double> value = reader.Double(v, name + "." + f.key);
      if (!value) return value.error();
      *f.target = *value * f.scale;
    }
  }
  for (const IntField& f : ints) {
    if (const YAML::Node v = section[f.key]) {
      Expected<std::int64_t> value = reader.Integer(v, name + "." + f.key);
      if (!value) return value.error();
      if (*value < f.min || *value > f.max) {
        return reader.Fail(name + "." + f.key,
                           "expected " + std::to_string(f.min) + " .. " + std::to_string(f.max));
      }
      *f.target = static_cast<int>(*value);
    }
  }
  return {};
}

}  // namespace cairn::util
