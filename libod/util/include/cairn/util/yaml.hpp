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

/// "a scalar 'abc'", "a sequence", "a mapping", "null": what was found, for messages.
std::string Describe(const YAML::Node& node);

}  // namespace cairn::util
