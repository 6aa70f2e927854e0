// The detection methods an evaluation compares on the same frames, as the paper does: the
// cone detector (exact or with the paper's window) and the column-wise baseline, each with
// and without the rule-based rejection of false obstacles.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cairn/eval/score.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::eval {

enum class DetectorKind { kCone, kColumn };

struct Method {
  std::string key;    ///< for file names and CSV, e.g. "cone_exact_rules"
  std::string label;  ///< for tables and figures, e.g. "cone exact + rules"
  DetectorKind detector = DetectorKind::kCone;
  od::SearchMode search = od::SearchMode::kExact;  ///< cone only; overrides the settings'
  bool rules = true;                               ///< false: every segment kept
  bool feet = true;  ///< false: the foot counts as ground (od::WithoutFeet)
};

/// cone exact + rules, cone exact (no rules), cone paper window + rules, column + rules,
/// column (no rules). The first is the method the claims are about.
std::vector<Method> StandardMethods();

/// StandardMethods() and, besides them, "cone_exact_rules_nofeet" (cone exact + rules with
/// each obstacle's foot counted as ground), selectable by key.
std::vector<Method> KnownMethods();

/// Methods by key from KnownMethods(), comma-separated ("cone_exact_rules,column_rules"),
/// in the order given. Fails on an unknown or repeated key, naming it and the known ones.
Expected<std::vector<Method>> SelectMethods(const std::string& keys);

/// One method's result on one frame.
struct MethodRun {
  od::Detection detection;
  od::Classification classification;
  /// Time of the detection [ms]; methods that differ only by the rules share one detection
  /// and report its time.
  double detect_ms = 0.0;
};

/// Runs `methods` on `image`. The column baseline takes the detector's HT, Hmax and theta
/// and `settings.min_blob_pixels`. Fails when the settings do not validate.
Expected<std::vector<MethodRun>> RunMethods(const od::RangeImage& image,
                                            const od::io::DetectSettings& settings,
                                            const std::vector<Method>& methods);

/// Every method run and scored on one frame.
struct FrameEvaluation {
  std::vector<std::int32_t> foot_band;  ///< FootBand() for the settings' Hmax and theta
  std::vector<MethodRun> runs;          ///< runs[k] for methods[k]
  std::vector<FrameScore> scores;       ///< scores[k] for methods[k]
};

Expected<FrameEvaluation> EvaluateFrame(const EvalFrame& frame,
                                        const od::io::DetectSettings& settings,
                                        const std::vector<Method>& methods,
                                        const ScoreOptions& options = {});

}  // namespace cairn::eval
