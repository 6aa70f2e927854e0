// Detection methods scored on synthetic worlds or single frames with truth images, side by
// side, and the report folder of `cairn eval --worlds`: REPORT.md (settings, the claims each
// world states and whether the measurements support them, scores over the gallery and per
// world, figures, the sweep), results.csv, sweep.csv and figures/.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/io/detect_config.hpp"

namespace cairn::eval {

/// One world (or the single frame), with everything measured on it.
struct WorldRun {
  std::string name;
  std::string description;
  std::string source;  ///< the file it came from
  std::vector<Score> per_method;
  std::vector<double> ms_sum;  ///< detection time summed over its frames [ms]
  SweepScores sweep;
  std::string figure;            ///< relative to the report directory
  std::string objects_markdown;  ///< per-frame object tables
};

/// True when every rule is disabled (0): "+ rules" then equals "no rules".
inline bool RulesDisabled(const od::RuleConfig& r) {
  return r.min_points == 0 && r.min_volume_m3 == 0.0 && r.min_perimeter_m == 0.0 &&
         r.min_slope_mean_rad == 0.0 && r.min_slope_max_rad == 0.0 && r.min_height_mean_m == 0.0 &&
         r.min_height_max_m == 0.0 && r.min_raised == 0;
}

/// What a world evaluation writes and how it scores.
struct WorldEvalOptions {
  std::filesystem::path report;  ///< the report directory (figures/ must exist in it)
  std::string command;           ///< the command that made the report, quoted in REPORT.md
  std::string version;           ///< cairn's version, quoted in REPORT.md
  std::string config;            ///< the settings file, or empty for the built-in defaults
  ScoreOptions score;
  int cell_width = 320;  ///< width of each figure cell [px]
  /// Called as a frame's sweep runs: value `v` of `count` done, `seconds` since it began
  /// (from the calling thread); may be empty.
  std::function<void(const std::string& key, int v, int count, double seconds)> on_sweep;
};

/// Every world's scores, figure and claims, gathered world by world, then the report.
class WorldEvaluation {
 public:
  WorldEvaluation(WorldEvalOptions options, od::io::DetectSettings settings,
                  std::vector<Method> methods, std::optional<SweepSpec> sweep)
      : options_(std::move(options)),
        settings_(std::move(settings)),
        methods_(std::move(methods)),
        sweep_(std::move(sweep)) {}

  /// Names the first score option out of range.
  Status Validate() const { return options_.score.Validate(); }

  /// Evaluates the frames of one world (or the single frame) and writes its figure.
  Status Add(const std::string& name, const std::string& description, const std::string& source,
             const std::vector<EvalFrame>& frames);

  /// Writes REPORT.md, results.csv, and the sweep's files; returns the summary to print.
  Expected<std::string> Finish();

 private:
  WorldEvalOptions options_;
  od::io::DetectSettings settings_;
  std::vector<Method> methods_;
  std::optional<SweepSpec> sweep_;
  std::vector<WorldRun> runs_;
};

}  // namespace cairn::eval
