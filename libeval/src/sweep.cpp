#include "cairn/eval/sweep.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/units.hpp"

namespace cairn::eval {
namespace {

enum class Unit { kMetre, kDegree, kCubicMetre, kScale, kCount, kPixels };

struct SweepKey {
  const char* section;
  const char* name;
  Unit unit;
};

const std::vector<SweepKey>& Keys() {
  static const std::vector<SweepKey> keys = {
      {"detector", "min_height", Unit::kMetre},     {"detector", "max_height", Unit::kMetre},
      {"detector", "min_slope", Unit::kDegree},     {"detector", "window_scale", Unit::kScale},
      {"column", "min_blob_pixels", Unit::kPixels}, {"rules", "min_points", Unit::kCount},
      {"rules", "min_volume", Unit::kCubicMetre},   {"rules", "min_perimeter", Unit::kMetre},
      {"rules", "min_slope_mean", Unit::kDegree},   {"rules", "min_slope_max", Unit::kDegree},
      {"rules", "min_height_mean", Unit::kMetre},   {"rules", "min_height_max", Unit::kMetre},
      {"rules", "min_raised", Unit::kCount},
  };
  return keys;
}

std::string KnownKeys() {
  std::string text;
  for (const SweepKey& k : Keys()) text += (text.empty() ? "" : ", ") + std::string(k.name);
  return text;
}

/// The key without its section prefix, or nullptr when unknown (or the prefix is wrong).
const SweepKey* FindKey(const std::string& key) {
  const std::size_t dot = key.find('.');
  const std::string section = dot == std::string::npos ? "" : key.substr(0, dot);
  const std::string name = dot == std::string::npos ? key : key.substr(dot + 1);
  for (const SweepKey& k : Keys()) {
    if (name == k.name && (section.empty() || section == k.section)) return &k;
  }
  return nullptr;
}

bool IsInteger(Unit u) { return u == Unit::kCount || u == Unit::kPixels; }

}  // namespace

const std::vector<std::string>& SweepableKeys() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const SweepKey& k : Keys()) v.emplace_back(k.name);
    return v;
  }();
  return names;
}

std::string SettingUnit(const std::string& key) {
  const SweepKey* k = FindKey(key);
  if (k == nullptr) return "";
  switch (k->unit) {
    case Unit::kMetre:
      return "m";
    case Unit::kDegree:
      return "deg";
    case Unit::kCubicMetre:
      return "m^3";
    case Unit::kPixels:
      return "px";
    case Unit::kScale:
    case Unit::kCount:
      break;
  }
  return "";
}

Status ApplySetting(od::io::DetectSettings& settings, const std::string& key, double value) {
  const SweepKey* k = FindKey(key);
  if (k == nullptr)
    return Error{key + ": not a sweepable setting (expected one of " + KnownKeys() + ")"};
  if (!std::isfinite(value)) return Error{key + ": value is not finite"};
  const std::string name = k->name;
  const long long integer = std::llround(value);
  od::DetectorConfig& d = settings.detector;
  od::RuleConfig& r = settings.rules;
  if (name == "min_height") d.min_height_m = value;
  if (name == "max_height") d.max_height_m = value;
  if (name == "min_slope") d.min_slope_rad = value * kDegToRad;
  if (name == "window_scale") d.window_scale = value;
  if (name == "min_blob_pixels") settings.min_blob_pixels = static_cast<int>(integer);
  if (name == "min_points") r.min_points = static_cast<int>(integer);
  if (name == "min_volume") r.min_volume_m3 = value;
  if (name == "min_perimeter") r.min_perimeter_m = value;
  if (name == "min_slope_mean") r.min_slope_mean_rad = value * kDegToRad;
  if (name == "min_slope_max") r.min_slope_max_rad = value * kDegToRad;
  if (name == "min_height_mean") r.min_height_mean_m = value;
  if (name == "min_height_max") r.min_height_max_m = value;
  if (name == "min_raised") r.min_raised = static_cast<int>(integer);
  if (IsInteger(k->unit) && (integer < 0 || integer > 1000000000)) {
    return Error{name + " = " + std::to_string(integer) + ": out of range"};
  }
  std::ostringstream shown;
  shown << value;
  const std::string where = name + " = " + shown.str() + ": ";
  if (Status s = d.Validate(); !s) return Error{where + s.message()};
  if (Status s = r.Validate(); !s) return Error{where + s.message()};
  od::ColumnConfig column = od::ColumnConfig::From(d);
  column.min_blob_pixels = settings.min_blob_pixels;
  if (Status s = column.Validate(); !s) return Error{where + s.message()};
  return Status::Ok();
}

std::vector<double> SweepSpec::Values() const {
  std::vector<double> values;
  if (count <= 1) return {lo};
  for (int i = 0; i < count; ++i) {
    // Both ends exact, whatever the rounding of the steps.
    values.push_back(i == count - 1 ? hi : lo + (hi - lo) * i / (count - 1));
  }
  return values;
}

bool SweepSpec::ChangesDetection() const {
  const SweepKey* k = FindKey(key);
  return k == nullptr || std::string(k->section) != "rules";
}

Expected<SweepSpec> ParseSweep(const std::string& text) {
  const std::string usage = "expected NAME=LO:HI:N (e.g. min_height=0.1:0.6:6), got '" + text + "'";
  const std::size_t eq = text.find('=');
  if (eq == std::string::npos) return Error{usage};
  SweepSpec spec;
  const SweepKey* k = FindKey(text.substr(0, eq));
  if (k == nullptr) {
    return Error{"'" + text.substr(0, eq) + "' is not a sweepable setting (expected one of " +
                 KnownKeys() + ")"};
  }
  spec.key = k->name;
  const std::string range = text.substr(eq + 1);
  const std::size_t c1 = range.find(':');
  const std::size_t c2 = c1 == std::string::npos ? c1 : range.find(':', c1 + 1);
  if (c2 == std::string::npos || range.find(':', c2 + 1) != std::string::npos) return Error{usage};
  const auto number = [](const std::string& s, double& out) {
    if (s.empty()) return false;
    char* end = nullptr;
    out = std::strtod(s.c_str(), &end);
    return end == s.c_str() + s.size() && std::isfinite(out);
  };
  double count = 0.0;
  if (!number(range.substr(0, c1), spec.lo)) return Error{usage + ": LO is not a number"};
  if (!number(range.substr(c1 + 1, c2 - c1 - 1), spec.hi)) {
    return Error{usage + ": HI is not a number"};
  }
  if (!number(range.substr(c2 + 1), count) || count < 1 || count > 1000 ||
      count != std::floor(count)) {
    return Error{usage + ": N must be an integer from 1 to 1000"};
  }
  spec.count = static_cast<int>(count);
  if (spec.count > 1 && !(spec.hi > spec.lo)) return Error{usage + ": HI must be above LO"};
  return spec;
}

void Accumulate(SweepScores& a, const SweepScores& b) {
  if (a.empty()) {
    a = b;
    return;
  }
  for (std::size_t v = 0; v < a.size() && v < b.size(); ++v) {
    for (std::size_t m = 0; m < a[v].size() && m < b[v].size(); ++m) a[v][m] += b[v][m];
  }
}

Expected<SweepScores> SweepFrame(const EvalFrame& frame, const od::io::DetectSettings& base,
                                 const SweepSpec& sweep, const std::vector<Method>& methods,
                                 const ScoreOptions& options,
                                 const std::function<void(int value_index)>& on_value) {
  const std::vector<double> values = sweep.Values();
  std::vector<od::io::DetectSettings> settings(values.size(), base);
  for (std::size_t v = 0; v < values.size(); ++v) {
    if (Status s = ApplySetting(settings[v], sweep.key, values[v]); !s) return s.error();
  }
  SweepScores scores(values.size());
  if (!sweep.ChangesDetection()) {
    // Detections (and the foot band) do not depend on the rules: make them once.
    Expected<FrameEvaluation> once = EvaluateFrame(frame, base, methods, options);
    if (!once) return once.error();
    for (std::size_t v = 0; v < values.size(); ++v) {
      if (on_value) on_value(static_cast<int>(v));
      for (std::size_t m = 0; m < methods.size(); ++m) {
        const MethodRun& run = once->runs[m];
        Expected<od::Classification> c =
            methods[m].rules ? od::Classify(run.detection, settings[v].rules)
                             : Expected<od::Classification>(od::KeepAll(run.detection));
        if (!c) return c.error();
        Expected<FrameScore> s =
            ScoreDetection(frame.truth, once->foot_band, run.detection, *c, options);
        if (!s) return Error{frame.name + ": " + s.error().message};
        scores[v].push_back(s->score);
      }
    }
    return scores;
  }
  for (std::size_t v = 0; v < values.size(); ++v) {
    if (on_value) on_value(static_cast<int>(v));
    Expected<FrameEvaluation> e = EvaluateFrame(frame, settings[v], methods, options);
    if (!e) return e.error();
    for (const FrameScore& s : e->scores) scores[v].push_back(s.score);
  }
  return scores;
}

}  // namespace cairn::eval
