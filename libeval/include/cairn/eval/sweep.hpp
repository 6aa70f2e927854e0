// Parameter sweeps: one setting stepped over evenly spaced values, every method scored at
// each value, for precision-recall curves and for tuning a vehicle's settings.
//
// Settings are named by their key in the settings file (see cairn/od/io/detect_config.hpp)
// and take values in the file's units: metres, cubic metres, degrees for angles.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detect_config.hpp"

namespace cairn::eval {

/// Keys a sweep may step: min_height, max_height, min_slope, window_scale (detector),
/// min_blob_pixels (column) and every rules key (min_points, min_volume, min_perimeter,
/// min_slope_mean, min_slope_max, min_height_mean, min_height_max, min_raised).
const std::vector<std::string>& SweepableKeys();

/// Sets the value of `key` (optionally prefixed by its section: "rules.min_volume") in
/// file units, then validates the settings. Integer settings take the nearest integer.
/// Errors name the key.
Status ApplySetting(od::io::DetectSettings& settings, const std::string& key, double value);

/// The unit of a key as the file writes it ("m", "deg", "m^3", "px", "" for counts).
std::string SettingUnit(const std::string& key);

struct SweepSpec {
  std::string key;  ///< a SweepableKeys() entry, without section prefix
  double lo = 0.0;
  double hi = 0.0;
  int count = 2;  ///< number of values, >= 1

  /// `count` evenly spaced values from lo to hi, both included (lo alone when count is 1).
  std::vector<double> Values() const;
  /// True when the key changes detections (not only the rules' verdicts).
  bool ChangesDetection() const;
};

/// Parses "NAME=LO:HI:N" (e.g. "min_height=0.1:0.6:6"). Errors say what is wrong and list
/// the keys.
Expected<SweepSpec> ParseSweep(const std::string& text);

/// Scores, [value][method], for one frame or summed over many.
using SweepScores = std::vector<std::vector<Score>>;

/// Adds `b` into `a` (same shape; `a` may be empty).
void Accumulate(SweepScores& a, const SweepScores& b);

/// Runs `methods` on `frame` at each value of the sweep, from `base` settings. A rule key
/// detects once per method and classifies per value. Fails when a value makes the settings
/// invalid (naming the key and the value) or a method fails.
Expected<SweepScores> SweepFrame(const EvalFrame& frame, const od::io::DetectSettings& base,
                                 const SweepSpec& sweep, const std::vector<Method>& methods,
                                 const ScoreOptions& options = {},
                                 const std::function<void(int value_index)>& on_value = {});

}  // namespace cairn::eval
