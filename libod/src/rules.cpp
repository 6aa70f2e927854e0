#include "cairn/od/rules.hpp"

#include <cmath>
#include <sstream>

#include "cairn/od/units.hpp"

namespace cairn::od {
namespace {

struct Rule {
  const char* name;
  double value;
  double threshold;
  const char* unit;
  double scale;  // to the unit shown
};

}  // namespace

Status RuleConfig::Validate() const {
  const std::pair<const char*, double> fields[] = {
      {"min_points", static_cast<double>(min_points)},
      {"min_volume", min_volume_m3},
      {"min_perimeter", min_perimeter_m},
      {"min_slope_mean", min_slope_mean_rad},
      {"min_slope_max", min_slope_max_rad},
      {"min_height_mean", min_height_mean_m},
      {"min_height_max", min_height_max_m},
      {"min_raised", static_cast<double>(min_raised)},
  };
  for (const auto& [name, value] : fields) {
    if (!std::isfinite(value) || value < 0.0) {
      return Error{std::string("rules config: '") + name + "' must be finite and >= 0 (got " +
                   std::to_string(value) + ")"};
    }
  }
  const std::pair<const char*, double> angles[] = {{"min_slope_mean", min_slope_mean_rad},
                                                   {"min_slope_max", min_slope_max_rad}};
  for (const auto& [name, value] : angles) {
    if (value > 90.0 / kRadToDeg + 1e-12) {
      return Error{std::string("rules config: '") + name + "' must lie in [0, 90] deg (got " +
                   std::to_string(value * kRadToDeg) + ")"};
    }
  }
  return Status::Ok();
}

Expected<Classification> Classify(const Detection& detection, const RuleConfig& rules) {
  if (Status s = rules.Validate(); !s) return s.error();
  Classification out;
  for (const SegmentFeatures& f : detection.segments) {
    const Rule checks[] = {
        {"points", double(f.point_count), double(rules.min_points), "", 1.0},
        {"raised points", double(f.raised_count), double(rules.min_raised), "", 1.0},
        {"volume", f.bbox_volume_m3, rules.min_volume_m3, " m^3", 1.0},
        {"perimeter", f.bbox_perimeter_m, rules.min_perimeter_m, " m", 1.0},
        {"mean slope", f.slope_mean_rad, rules.min_slope_mean_rad, " deg", kRadToDeg},
        {"max slope", f.slope_max_rad, rules.min_slope_max_rad, " deg", kRadToDeg},
        {"mean height", f.height_mean_m, rules.min_height_mean_m, " m", 1.0},
        {"max height", f.height_max_m, rules.min_height_max_m, " m", 1.0},
    };
    SegmentVerdict verdict;
    verdict.id = f.id;
    std::ostringstream reason;
    for (const Rule& rule : checks) {
      if (rule.threshold <= 0.0 || rule.value >= rule.threshold) continue;
      if (verdict.cls == SegmentClass::kRejected) reason << "; ";
      verdict.cls = SegmentClass::kRejected;
      reason << rule.name << ' ' << rule.value * rule.scale << rule.unit << " < "
             << rule.threshold * rule.scale;
    }
    verdict.reason = reason.str();
    (verdict.cls == SegmentClass::kKept ? out.kept : out.rejected) += 1;
    out.verdicts.push_back(std::move(verdict));
  }
  return out;
}

Classification KeepAll(const Detection& detection) {
  Classification out;
  for (const SegmentFeatures& f : detection.segments) {
    out.verdicts.push_back({f.id, SegmentClass::kKept, {}});
  }
  out.kept = static_cast<int>(detection.segments.size());
  return out;
}

std::vector<std::uint8_t> ClassImage(const Detection& detection, const Classification& c) {
  std::vector<std::uint8_t> classes(detection.labels.size(), 0);
  for (std::size_t i = 0; i < classes.size(); ++i) {
    const int id = detection.labels[i];
    if (id > 0) classes[i] = static_cast<std::uint8_t>(c.verdicts[id - 1].cls);
  }
  return classes;
}

}  // namespace cairn::od
