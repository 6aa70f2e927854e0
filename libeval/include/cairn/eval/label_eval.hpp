// Evaluation on real labels: a LiDAR scan with per-point SemanticKITTI-style labels (such as
// RELLIS-3D's), a class mapping file that says which dataset classes are obstacles, ground or
// ignored, and the methods of methods.hpp run on the scan's one range image and scored per
// point.
//
// Scoring, per input point (labels go back to points through RangeImage::cell_of_point, so
// every point of a cell shares its cell's result):
//  - a point with no return is left out (neither found nor missed), whatever its label;
//  - a point whose true class is ignored is left out;
//  - otherwise it is *detected* when its cell lies in a kept segment (a segment the rules
//    rejected counts as not detected), and a *true obstacle point* when its class is an
//    obstacle: TP detected obstacle, FP detected ground, FN undetected obstacle, TN the rest.
// Precision, recall, F1 and IoU of the obstacle points follow from TP, FP, FN (PointCounts).
//
// Class mapping file (YAML, read strictly: unknown keys, duplicate ids, bad roles or colours
// are errors naming the file and the key):
//   dataset: RELLIS-3D                  # optional, for reports
//   classes:                            # semantic id (lower 16 bits of a .label entry)
//     4: {name: tree, role: obstacle, color: [0, 255, 0]}   # color optional, [r, g, b]
//     3: {name: grass, role: ground}
//     0: {name: void, role: ignored}
// Roles: obstacle (should be detected), ground (traversable: should not be), ignored (not
// scored). At least one class must be an obstacle. A label id the file does not list is an
// error when scoring, so that a new class is never scored silently.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/eval/methods.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::eval {

/// What a dataset class is for the obstacle score.
enum class ClassRole : std::uint8_t { kObstacle, kGround, kIgnored };

/// "obstacle" | "ground" | "ignored".
const char* ClassRoleName(ClassRole role);

struct LabelClass {
  std::uint32_t id = 0;  ///< semantic id, 0..65535
  std::string name;
  ClassRole role = ClassRole::kIgnored;
  std::array<std::uint8_t, 3> color{};  ///< r, g, b in figures (SegmentColor(id) when not given)
};

struct ClassMap {
  std::string source;               ///< the file it was read from, for messages
  std::string dataset;              ///< may be empty
  std::vector<LabelClass> classes;  ///< sorted by id, ids unique

  /// The class with this semantic id, or nullptr.
  const LabelClass* Find(std::uint32_t id) const;
};

/// Reads a class mapping file (format above). Errors name the file and the key, e.g.
/// "rellis3d.yaml: classes.4.role: expected obstacle, ground or ignored, got 'tre'".
Expected<ClassMap> LoadClassMap(const std::filesystem::path& path);

/// The same from YAML text; `source` names it in messages.
Expected<ClassMap> ParseClassMap(const std::string& yaml_text, const std::string& source);

/// What one point counts as.
enum class PointOutcome : std::uint8_t {
  kNoReturn,  ///< no return: not scored
  kIgnored,   ///< a return of an ignored class: not scored
  kTruePositive,
  kFalsePositive,
  kFalseNegative,
  kTrueNegative,
};

/// Returns of one true class and what a method did with them.
struct ClassTally {
  std::uint32_t id = 0;
  std::int64_t returns = 0;   ///< points with a return
  std::int64_t detected = 0;  ///< ..in a kept segment
  std::int64_t rejected = 0;  ///< ..in a segment the rules rejected
};

/// One method's per-point score on one scan.
struct LabelScore {
  PointCounts counts;                 ///< obstacle TP, FP, FN over scored points
  std::int64_t tn = 0;                ///< scored ground points not detected
  std::int64_t ignored = 0;           ///< returns of ignored classes
  std::int64_t no_return = 0;         ///< points without a return
  std::vector<ClassTally> per_class;  ///< one per class of the map, in its order

  /// The tally of class `id`, or nullptr when the map has no such class.
  const ClassTally* Find(std::uint32_t id) const;
};

struct ScoredPoints {
  std::vector<PointOutcome> outcome;  ///< per point
  LabelScore score;
};

/// Scores one method's per-point result. `truth_labels`: .label entries per point (semantic
/// id = lower 16 bits); `point_class`: SegmentClass per point (0 none, 1 kept, 2 rejected, as
/// the lower 16 bits of PointLabels); `has_return`: non-zero where the point is a return.
/// Fails on size mismatches, and when a label's id is not in `map`, naming `truth_source`,
/// the point's index, the id and the map's file.
Expected<ScoredPoints> ScoreLabels(const ClassMap& map,
                                   const std::vector<std::uint32_t>& truth_labels,
                                   const std::vector<std::uint8_t>& point_class,
                                   const std::vector<std::uint8_t>& has_return,
                                   const std::string& truth_source);

/// A scan with its true labels, projected into its range image.
struct LabelFrame {
  std::string name;                     ///< the scan's file stem, e.g. "000104"
  std::string points_source;            ///< the .bin, as given
  std::string labels_source;            ///< the .label, as given
  std::vector<Eigen::Vector3f> points;  ///< sensor frame (x forward, z up) [m], input order
  std::vector<std::uint32_t> truth;     ///< .label entries, one per point
  bool organised = false;               ///< layout found from the data (see ResolveLayout)
  od::RangeImage image;                 ///< cell_of_point() maps every point to its cell

  /// Per point: 1 where the point is a return (it has a cell).
  std::vector<std::uint8_t> HasReturn() const;
};

/// Reads a KITTI-layout .bin and its .label, resolves the layout for `preset` (`mode` as
/// `cairn detect --organised`) and makes the range image with `up_sensor`. Fails, naming the
/// files, when either cannot be read or their point counts differ.
Expected<LabelFrame> LoadLabelFrame(const std::filesystem::path& points_bin,
                                    const std::filesystem::path& labels_file,
                                    const od::SphericalModel& preset, od::OrganisedMode mode,
                                    const Eigen::Vector3d& up_sensor);

/// One method on a labelled scan.
struct LabelMethodResult {
  MethodRun run;
  std::vector<std::uint8_t> point_class;  ///< SegmentClass per point, through cell_of_point
  ScoredPoints scored;
};

/// Runs `methods` on the frame's one range image (RunMethods: same image, same settings,
/// same rules) and scores each against the labels.
Expected<std::vector<LabelMethodResult>> EvaluateLabels(const LabelFrame& frame,
                                                        const ClassMap& map,
                                                        const od::io::DetectSettings& settings,
                                                        const std::vector<Method>& methods);

// ---------------------------------------------------------------------------------------
// Figures. Outcome colours (r, g, b): TP bluish green, FP vermillion, FN sky blue (Okabe-Ito,
// readable with colour-blindness), TN light grey, ignored dark grey, no return black.

struct LabelFigureOptions {
  int pixels_per_ring = 3;                ///< range image rows are stretched by this [px]
  double birds_eye_m_per_px = 0.08;       ///< [m/px]
  double birds_eye_half_extent_m = 40.0;  ///< shown: |x|, |y| up to this [m]
};

/// The range image (one row per ring, top beam first; one column per azimuth step), first
/// coloured by true class, then by each method's outcome, each panel captioned, with an
/// azimuth axis and the legends. Fails when `results` does not match `methods`.
Expected<od::io::RgbImage> LabelRangeFigure(const LabelFrame& frame, const ClassMap& map,
                                            const std::vector<Method>& methods,
                                            const std::vector<LabelMethodResult>& results,
                                            const LabelFigureOptions& options = {});

/// The points from above (level frame, x forward up the image, sensor at the centre, rings
/// every 10 m, a scale bar), side by side three to a row: true class, then each method's
/// outcome.
Expected<od::io::RgbImage> LabelBirdsEyeFigure(const LabelFrame& frame, const ClassMap& map,
                                               const std::vector<Method>& methods,
                                               const std::vector<LabelMethodResult>& results,
                                               const LabelFigureOptions& options = {});

// ---------------------------------------------------------------------------------------
// Tables.

/// A ratio with three decimals, "-" when undefined.
std::string FormatRatio3(double value);

/// One row per method: precision, recall, F1, IoU (three decimals), TP, FP, FN, TN, ignored
/// and no-return points, segments kept / rejected.
std::string LabelResultsMarkdown(const std::vector<Method>& methods,
                                 const std::vector<LabelMethodResult>& results);

/// One row per class present in the scan: its role, returns, and per method the share (and
/// count) of its returns detected.
std::string LabelClassesMarkdown(const ClassMap& map, const std::vector<Method>& methods,
                                 const std::vector<LabelMethodResult>& results);

/// Per method, where its errors are: false positives and false negatives by true class,
/// largest first, as a Markdown list.
std::string LabelErrorsMarkdown(const ClassMap& map, const std::vector<Method>& methods,
                                const std::vector<LabelMethodResult>& results);

/// results.csv: a row per method (the score) and a row per method and class (its tally).
std::string LabelResultsCsv(const ClassMap& map, const std::vector<Method>& methods,
                            const std::vector<LabelMethodResult>& results);

}  // namespace cairn::eval
