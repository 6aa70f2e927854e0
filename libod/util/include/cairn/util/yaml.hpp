// Strict reading of YAML fields: every failure becomes an Error naming the source file and
// the field's dotted path (cairn::util: od_io, map and the apps read their files with it).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::util {

/// Reads a whole text file; fails with "<path>: ..." when it is missing or unreadable.
Expected<std::string> ReadTextFile(const std::filesystem::path& path);

/// Parses YAML text; syntax errors carry line and column.
Expected<YAML::Node> ParseYaml(const std::string& text, const std::string& source);

class FieldReader {
 public:
  explicit FieldReader(std::string source) : source_(std::move(source)) {}

  /// "<source>: <field>: <what>".
  Error Fail(const std::string& field, const std::string& what) const;
  const std::string& source() const { return source_; }

  /// `node` must be a mapping whose keys are all in `known`, each once. `where` names it
  /// ("" for the top level, else the section).
  Status CheckMapping(const YAML::Node& node, const std::string& where,
                      const std::vector<std::string>& known) const;

  Expected<double> Double(const YAML::Node& node, const std::string& field) const;
  Expected<std::int64_t> Integer(const YAML::Node& node, const std::string& field) const;
  Expected<std::string> String(const YAML::Node& node, const std::string& field) const;

 private:
  std::string source_;
};

/// An angle in degrees within [-max_abs_deg, max_abs_deg], returned in degrees; the error
/// names the field and the range.
Expected<double> Angle(const FieldReader& reader, const YAML::Node& node, const std::string& field,
                       double max_abs_deg);

/// A number of a settings section read into a struct member; `scale` turns the file's unit
/// into the member's (degrees to radians).
struct DoubleField {
  const char* key;
  double* target;
  double scale = 1.0;
};
/// A whole number of a settings section, within [min, max].
struct IntField {
  const char* key;
  int* target;
  std::int64_t min, max;
};

/// Reads the keys present in `section` (a mapping named `name`, or null: nothing set) into
/// their fields. Its keys must be these fields' and `other_keys` (read by the caller); a
/// value of the wrong type or out of range is an error naming "name.key".
Status ReadFields(const FieldReader& reader, const YAML::Node& section, const std::string& name,
                  const std::vector<DoubleField>& doubles, const std::vector<IntField>& ints,
                  std::vector<std::string> other_keys = {});

/// "a scalar 'abc'", "a sequence", "a mapping", "null": what was found, for messages.
std::string Describe(const YAML::Node& node);

}  // namespace cairn::util
