// cairn eval over synthetic worlds or one depth frame: one Evaluation gathers the scores
// of every world (eval_worlds.cpp) and writes the report folder (eval_report.cpp).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "eval_run.hpp"

namespace cairn::apps::eval {

namespace ev = cairn::eval;

/// One world (or the single frame), with everything measured on it.
struct WorldRun {
  std::string name;
  std::string description;
  std::string source;  ///< the file it came from
  std::vector<ev::Score> per_method;
  std::vector<double> ms_sum;  ///< detection time summed over its frames [ms]
  ev::SweepScores sweep;
  std::string figure;            ///< relative to the report directory
  std::string objects_markdown;  ///< per-frame object tables
};

/// True when every rule is disabled (0): "+ rules" then equals "no rules".
inline bool RulesDisabled(const od::RuleConfig& r) {
  return r.min_points == 0 && r.min_volume_m3 == 0.0 && r.min_perimeter_m == 0.0 &&
         r.min_slope_mean_rad == 0.0 && r.min_slope_max_rad == 0.0 && r.min_height_mean_m == 0.0 &&
         r.min_height_max_m == 0.0 && r.min_raised == 0;
}

/// Everything one run needs: the sources, settings and methods, and what it measured.
class Evaluation {
 public:
  Evaluation(const EvalOptions& options, od::io::DetectSettings settings,
             std::vector<ev::Method> methods, std::optional<ev::SweepSpec> sweep)
      : options_(options),
        settings_(std::move(settings)),
        methods_(std::move(methods)),
        sweep_(std::move(sweep)) {
    score_options_.found_fraction = options.found_fraction;
    score_options_.min_object_pixels = options.min_object_pixels;
  }

  Status Validate() const { return score_options_.Validate(); }

  /// Evaluates the frames of one world (or the single frame) and writes its figure.
  Status Add(const std::string& name, const std::string& description, const std::string& source,
             const std::vector<ev::EvalFrame>& frames);

  /// Writes REPORT.md, results.csv, and the sweep's files; returns the summary to print.
  Expected<std::string> Finish();

 private:
  const EvalOptions& options_;
  od::io::DetectSettings settings_;
  std::vector<ev::Method> methods_;
  std::optional<ev::SweepSpec> sweep_;
  ev::ScoreOptions score_options_;
  std::vector<WorldRun> runs_;
};

}  // namespace cairn::apps::eval
