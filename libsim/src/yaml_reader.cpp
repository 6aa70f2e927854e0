#include "yaml_reader.hpp"

#include <cmath>
#include <set>

#include "cairn/od/units.hpp"

namespace cairn::sim::detail {
void ErrorSink::Fail(const std::string& field, const std::string& what) {
  if (error_) return;
  std::string message = file_;
  if (!field.empty()) message += ": " + field;
  if (!what.empty()) message += ": " + what;
  error_ = Error{message};
}

MapReader::MapReader(ErrorSink& sink, const YAML::Node& node, std::string path,
                     const std::vector<std::string>& allowed)
    : sink_(sink), node_(node), path_(std::move(path)) {
  if (!node_.IsMap()) {
    std::string keys;
    for (const std::string& k : allowed) keys += (keys.empty() ? "" : ", ") + k;
    sink_.Fail(path_, "expected a mapping (keys: " + keys + "), got " + Describe(node_));
    node_ = YAML::Node(YAML::NodeType::Map);
    return;
  }
  std::set<std::string> seen;
  for (const auto& entry : node_) {
    if (!entry.first.IsScalar()) {
      sink_.Fail(path_, "keys must be plain names, got " + Describe(entry.first));
      return;
    }
    const std::string key = entry.first.Scalar();
    bool known = false;
    for (const std::string& k : allowed) known = known || k == key;
    if (!known) {
      std::string keys;
      for (const std::string& k : allowed) keys += (keys.empty() ? "" : ", ") + k;
      sink_.Fail(Field(key), "unknown key (expected one of: " + keys + ")");
      return;
    }
    if (!seen.insert(key).second) {
      sink_.Fail(Field(key), "given twice");
      return;
    }
  }
}

std::string MapReader::Field(const std::string& key) const {
  return path_.empty() ? key : path_ + "." + key;
}

bool MapReader::Has(const std::string& key) const {
  const YAML::Node& map = node_;
  return map.IsMap() && map[key].IsDefined();
}

YAML::Node MapReader::Node(const std::string& key) const {
  const YAML::Node& map = node_;  // const access never inserts
  return Has(key) ? map[key] : YAML::Node();
}

bool MapReader::Check(bool ok, const std::string& key, const std::string& what) {
  if (!ok) sink_.Fail(Field(key), what);
  return ok;
}

bool MapReader::Present(const std::string& key, bool required) {
  if (Has(key)) return true;
  if (required) sink_.Fail(Field(key), "missing (required)");
  return false;
}

std::optional<double> MapReader::ScalarNumber(const YAML::Node& node, const std::string& field) {
  double value = 0.0;
  bool ok = node.IsScalar();
  if (ok) {
    try {
      value = node.as<double>();
    } catch (const YAML::Exception&) {
      ok = false;
    }
  }
  if (!ok) {
    sink_.Fail(field, "expected a number, got " + Describe(node));
    return std::nullopt;
  }
  if (!std::isfinite(value)) {
    sink_.Fail(field, "expected a finite number, got " + Describe(node));
    return std::nullopt;
  }
  return value;
}

double MapReader::Number(const std::string& key) {
  if (!Present(key, true)) return 0.0;
  return ScalarNumber(Node(key), Field(key)).value_or(0.0);
}

double MapReader::Number(const std::string& key, double fallback) {
  if (!Present(key, false)) return fallback;
  return ScalarNumber(Node(key), Field(key)).value_or(fallback);
}

// No angle (nor angular rate per metre) of a world file is meaningful beyond a full turn;
// a larger one is a unit mistake (radians given as degrees read fine; milliradians do not).
double MapReader::Degrees(const std::string& key) {
  const double deg = Number(key);
  Check(!(std::abs(deg) > 360.0), key, "expected an angle in [-360, 360] deg");
  return deg * kDegToRad;
}

double MapReader::Degrees(const std::string& key, double fallback_rad) {
  if (!Present(key, false)) return fallback_rad;
  return Degrees(key);
}

std::int64_t MapReader::Integer(const std::string& key, std::int64_t fallback) {
  if (!Present(key, false)) return fallback;
  const YAML::Node n = Node(key);
  if (n.IsScalar()) {
    try {
      return n.as<std::int64_t>();
    } catch (const YAML::Exception&) {
    }
  }
  sink_.Fail(Field(key), "expected an integer, got " + Describe(n));
  return fallback;
}

bool MapReader::Bool(const std::string& key) {
  if (!Present(key, true)) return false;
  return Bool(key, false);
}

bool MapReader::Bool(const std::string& key, bool fallback) {
  if (!Present(key, false)) return fallback;
  const YAML::Node n = Node(key);
  if (n.IsScalar() && (n.Scalar() == "true" || n.Scalar() == "false")) {
    return n.Scalar() == "true";
  }
  sink_.Fail(Field(key), "expected true or false, got " + Describe(n));
  return fallback;
}

std::string MapReader::String(const std::string& key) {
  if (!Present(key, true)) return {};
  return String(key, {});
}

std::string MapReader::String(const std::string& key, const std::string& fallback) {
  if (!Present(key, false)) return fallback;
  const YAML::Node n = Node(key);
  if (!n.IsScalar()) {
    sink_.Fail(Field(key), "expected text, got " + Describe(n));
    return fallback;
  }
  return n.Scalar();
}

template <int N>
Eigen::Matrix<double, N, 1> MapReader::Vector(const std::string& key) {
  Eigen::Matrix<double, N, 1> v = Eigen::Matrix<double, N, 1>::Zero();
  const YAML::Node n = Node(key);
  if (!n.IsSequence() || static_cast<int>(n.size()) != N) {
    sink_.Fail(Field(key),
               "expected a sequence of " + std::to_string(N) + " numbers, got " +
                   (n.IsSequence() ? "one of " + std::to_string(n.size()) : Describe(n)));
    return v;
  }
  for (int i = 0; i < N; ++i) {
    v[i] = ScalarNumber(n[i], Field(key) + "[" + std::to_string(i) + "]").value_or(0.0);
  }
  return v;
}

Eigen::Vector2d MapReader::Vec2(const std::string& key) {
  if (!Present(key, true)) return Eigen::Vector2d::Zero();
  return Vector<2>(key);
}

Eigen::Vector3d MapReader::Vec3(const std::string& key) {
  if (!Present(key, true)) return Eigen::Vector3d::Zero();
  return Vector<3>(key);
}

Eigen::Vector3d MapReader::Vec3(const std::string& key, const Eigen::Vector3d& fallback) {
  if (!Present(key, false)) return fallback;
  return Vector<3>(key);
}

std::vector<double> MapReader::Numbers(const std::string& key) {
  std::vector<double> values;
  if (!Present(key, true)) return values;
  const YAML::Node n = Node(key);
  if (!n.IsSequence()) {
    sink_.Fail(Field(key), "expected a sequence of numbers, got " + Describe(n));
    return values;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    values.push_back(ScalarNumber(n[i], Field(key) + "[" + std::to_string(i) + "]").value_or(0.0));
  }
  return values;
}

}  // namespace cairn::sim::detail
