// The evaluation's tables: scores per world and method (Markdown and CSV), sweep tables,
// and the checks of what each world claims against what was measured.
#pragma once

#include <string>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/od/io/detect_config.hpp"

namespace cairn::eval {

/// Scores of one method on one world (summed over its frames), or on the whole gallery.
struct ResultRow {
  std::string world;  ///< world name; "all" for the gallery total
  Method method;
  Score score;
  double detect_ms = 0.0;  ///< mean detection time per frame [ms]
};

/// A ratio as the tables print it: two decimals, "-" when undefined.
std::string FormatRatio(double value);

/// One row per world and method: counts, ratios (strict and foot band excluded), objects
/// found and counted, false obstacles, segmentation, time. The header names every column.
std::string ResultsCsv(const std::vector<ResultRow>& rows);

/// The same as a Markdown table with the columns a reader compares (see the legend that
/// ResultsLegend() returns).
std::string ResultsMarkdown(const std::vector<ResultRow>& rows);

/// What the Markdown table's columns mean, as a Markdown list.
std::string ResultsLegend(const ScoreOptions& options);

/// The settings in one paragraph of Markdown; `config` names their file (empty: the
/// built-in defaults).
std::string SettingsMarkdown(const od::io::DetectSettings& settings, const std::string& config);

/// What happened to each object of one frame under each method, as a Markdown table: its
/// valid pixels, the share of them detected, "found" and "(small)" (not counted).
std::string ObjectsMarkdown(const std::string& frame, const FrameEvaluation& evaluation,
                            const std::vector<Method>& methods);

/// A sweep's scores for one world ("all" for the gallery), [value][method].
struct SweepRows {
  std::string world;
  SweepScores scores;
};

/// One row per world, value and method.
std::string SweepCsv(const SweepSpec& sweep, const std::vector<Method>& methods,
                     const std::vector<SweepRows>& rows);

/// The gallery's sweep as Markdown: a row per value, precision / recall / objects found per
/// method.
std::string SweepMarkdown(const SweepSpec& sweep, const std::vector<Method>& methods,
                          const SweepScores& scores);

/// One claim checked against the measurements.
struct ClaimCheck {
  std::string claim;     ///< what is expected, in words
  std::string measured;  ///< the numbers that decide it
  bool holds = false;
  bool general = false;  ///< checked on every world, not a claim this world states
};

/// What a world's description says it expects: the text from "Expected:" to the end (or
/// empty when it has none), on one line.
std::string StatedExpectation(const std::string& description);

/// A world's scores per method (methods[k] -> per_method[k]), as the claims read them.
struct WorldScores {
  std::string name;
  std::string description;
  std::vector<Score> per_method;
};

/// The checks that apply to one world, on "cone exact + rules" (the cone detector), the
/// column baseline ("column + rules", else "column") and "cone exact" (for the rules):
///  - the paper's claim when the world speaks of faces that point sideways ("sideways-
///    facing", "point(s) sideways", "face(s) sideways"): the cone detector finds
///    >= 90% of the obstacles, the column baseline at most half, with no more false ones;
///  - what the description's "Expected:" sentence states (the whole description when it has
///    none), phrase by phrase: "finds every / all / each / both / the", "marks the",
///    "every obstacle is" (every obstacle found); "finds nearly every" (>= 90%); "at least N%"; "at
///    most half" (column); "own segment", "one segment" (one segment per found obstacle, one
///    obstacle per segment; with "about one segment", on average: means <= 1.1); "merges" (the
///    column's blobs merge objects); "shares a segment" (some cone segment holds two obstacles, for
///    objects that touch in 3-D); "none of the", "not marked" (no non-obstacle marked); "no false
///    obstacle" ("neither": nor the column); "no fewer / no more false" (cone <= column);
///    "rules keep" (found objects kept); "rules remove" (false obstacles halved);
///  - general checks on every world (ClaimCheck::general): the cone detector finds >= 90%
///    of the obstacles, and no cone segment holds two.
/// Methods the checks need but `methods` lacks are skipped.
std::vector<ClaimCheck> CheckWorld(const WorldScores& world, const std::vector<Method>& methods);

/// The gallery-wide claim: across all worlds the rules remove most (more than half) of the
/// cone detector's false obstacles while keeping its recall (objects found drop by at most
/// 5 points, per-point recall by at most 5 points).
std::vector<ClaimCheck> CheckGallery(const Score& cone_rules, const Score& cone_no_rules,
                                     const std::string& with, const std::string& without);

}  // namespace cairn::eval
