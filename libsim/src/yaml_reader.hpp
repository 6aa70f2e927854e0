// Strict reading of one YAML file into structs, internal to cairn_sim.
//
// Each mapping is read through a MapReader that knows its allowed keys up front: an unknown
// or repeated key is the first error it records, before any missing or bad value, so that a
// misspelt key is reported as such rather than as the missing field it was meant to be.
// Errors read "<file>: <path>.<key>: <what>" (e.g. "w.yaml: objects[3].radius: must be > 0");
// only the first is kept, and reads after it return their fallbacks.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::sim::detail {

/// "'abc'", "a sequence", "a mapping", "nothing (null)": what was found, for messages.
using util::Describe;

/// The first error met while reading one file.
class ErrorSink {
 public:
  explicit ErrorSink(std::string file) : file_(std::move(file)) {}
  const std::string& file() const { return file_; }
  bool failed() const { return error_.has_value(); }
  const Error& error() const { return *error_; }
  /// Records "<file>: <field>: <what>" unless an error is already recorded (an empty field
  /// or what is left out, so a message that names its own field can be passed as `field`).
  void Fail(const std::string& field, const std::string& what);

 private:
  std::string file_;
  std::optional<Error> error_;
};

class MapReader {
 public:
  /// `path` names the mapping ("" for the top level, "objects[3]", "camera.noise").
  MapReader(ErrorSink& sink, const YAML::Node& node, std::string path,
            const std::vector<std::string>& allowed);

  bool Has(const std::string& key) const;
  /// "<path>.<key>" (or "<key>" at the top level).
  std::string Field(const std::string& key) const;
  /// Records an error about `key` when `ok` is false; returns ok.
  bool Check(bool ok, const std::string& key, const std::string& what);
  ErrorSink& sink() { return sink_; }

  /// The raw node under `key` (undefined when absent).
  YAML::Node Node(const std::string& key) const;

  // Required fields record "missing" when absent; the others return their fallback.
  double Number(const std::string& key);
  double Number(const std::string& key, double fallback);
  /// Degrees in the file, within [-360, 360], radians returned.
  double Degrees(const std::string& key);
  double Degrees(const std::string& key, double fallback_rad);
  std::int64_t Integer(const std::string& key, std::int64_t fallback);
  bool Bool(const std::string& key);
  bool Bool(const std::string& key, bool fallback);
  std::string String(const std::string& key);
  std::string String(const std::string& key, const std::string& fallback);
  /// A sequence of exactly N numbers.
  Eigen::Vector2d Vec2(const std::string& key);
  Eigen::Vector3d Vec3(const std::string& key);
  Eigen::Vector3d Vec3(const std::string& key, const Eigen::Vector3d& fallback);
  /// A sequence of numbers of any length.
  std::vector<double> Numbers(const std::string& key);

 private:
  bool Present(const std::string& key, bool required);
  std::optional<double> ScalarNumber(const YAML::Node& node, const std::string& field);
  template <int N>
  Eigen::Matrix<double, N, 1> Vector(const std::string& key);

  ErrorSink& sink_;
  YAML::Node node_;
  std::string path_;
};

}  // namespace cairn::sim::detail
