// Rule-based rejection of false obstacles: one threshold per segment measure.
//
// A segment is kept when it passes every rule; otherwise it is rejected and the reason
// names each rule it failed with the measured value and the threshold. A threshold of 0
// disables its rule.
#pragma once

#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"

namespace cairn::od {

/// The defaults are those of config/default.yaml (`rules:`): they reject the specks of
/// range noise and the obstacles lower than the detector's HT. None() disables every rule.
struct RuleConfig {
  int min_points = 10;                ///< least point_count
  double min_volume_m3 = 0.005;       ///< least bbox_volume_m3 [m^3]
  double min_perimeter_m = 0.0;       ///< least bbox_perimeter_m [m]
  double min_slope_mean_rad = 0.0;    ///< least slope_mean_rad [rad]
  double min_slope_max_rad = 0.0;     ///< least slope_max_rad [rad]
  double min_height_mean_m = 0.0;     ///< least height_mean_m [m]
  double min_height_max_m = 0.3;      ///< least height_max_m [m]
  int min_raised = 0;                 ///< least raised_count

  /// Every threshold 0: every segment is kept.
  static RuleConfig None() {
    RuleConfig r;
    r.min_points = 0;
    r.min_volume_m3 = 0.0;
    r.min_height_max_m = 0.0;
    return r;
  }

  /// Names the first negative or non-finite threshold, or a slope above 90 deg.
  Status Validate() const;
};

enum class SegmentClass : std::uint8_t { kNone = 0, kKept = 1, kRejected = 2 };

struct SegmentVerdict {
  int id = 0;
  SegmentClass cls = SegmentClass::kKept;
  std::string reason;  ///< empty when kept, e.g. "volume 0.004 m^3 < 0.01"
};

struct Classification {
  std::vector<SegmentVerdict> verdicts;  ///< verdicts[id - 1] for segment `id`
  int kept = 0;
  int rejected = 0;
};

/// Applies the rules to every segment of `detection`.
Expected<Classification> Classify(const Detection& detection, const RuleConfig& rules);

/// Every segment kept (what `--no-rules` means).
Classification KeepAll(const Detection& detection);

/// Class per pixel (SegmentClass values), row-major, for `detection`'s grid.
std::vector<std::uint8_t> ClassImage(const Detection& detection, const Classification& c);

}  // namespace cairn::od
