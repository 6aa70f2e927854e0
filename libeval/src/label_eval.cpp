#include "cairn/eval/label_eval.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <utility>

#include "cairn/od/rules.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/yaml.hpp"
#include "opencv_image.hpp"

namespace cairn::eval {
namespace {

namespace io = od::io;
using Rgb = std::array<std::uint8_t, 3>;

constexpr std::uint32_t kMaxClassId = 0xFFFF;  // a .label entry's lower 16 bits
constexpr int kBirdsEyePanelsPerRow = 3;       // wider figures do not fit a page

// ---------------------------------------------------------------------------------------
// Class mapping file.

using util::Describe;

/// A decimal integer in 0..hi, the whole scalar (no sign, no spaces, no fraction).
bool ParseUnsigned(const std::string& text, std::uint32_t hi, std::uint32_t* value) {
  if (text.empty() || text.size() > 9) return false;
  std::uint32_t v = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + static_cast<std::uint32_t>(c - '0');
  }
  if (v > hi) return false;
  *value = v;
  return true;
}

class MapReader {
 public:
  explicit MapReader(std::string source) : source_(std::move(source)) {}

  Error Fail(const std::string& key, const std::string& what) const {
    return Error{source_ + ": " + key + ": " + what};
  }

  /// `node` is a mapping whose keys are all in `known`, each once.
  Status CheckKeys(const YAML::Node& node, const std::string& where,
                   const std::vector<std::string>& known) const {
    std::string list;
    for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
    if (!node.IsMap()) {
      return Fail(where.empty() ? "top level" : where,
                  "expected a mapping with keys " + list + ", got " + Describe(node));
    }
    std::set<std::string> seen;
    for (const auto& entry : node) {
      const std::string key = entry.first.Scalar();
      const std::string path = where.empty() ? key : where + "." + key;
      if (std::find(known.begin(), known.end(), key) == known.end()) {
        return Fail(path, "unknown key (expected " + list + ")");
      }
      if (!seen.insert(key).second) return Fail(path, "given twice");
    }
    return Status::Ok();
  }

  Expected<LabelClass> Class(const YAML::Node& key, const YAML::Node& value) const {
    LabelClass c;
    const std::string where = key.IsScalar() ? "classes." + key.Scalar() : "classes";
    if (!key.IsScalar() || !ParseUnsigned(key.Scalar(), kMaxClassId, &c.id)) {
      return Fail(where,
                  "expected a class id, an integer 0..65535 (the lower 16 bits of a "
                  ".label entry), got " +
                      Describe(key));
    }
    if (Status s = CheckKeys(value, where, {"name", "role", "color"}); !s) return s.error();
    const YAML::Node name = value["name"];
    if (!name) return Fail(where + ".name", "missing (the class's name)");
    if (!name.IsScalar() || name.Scalar().empty()) {
      return Fail(where + ".name", "expected a non-empty name, got " + Describe(name));
    }
    c.name = name.Scalar();
    const YAML::Node role = value["role"];
    if (!role) return Fail(where + ".role", "missing (obstacle, ground or ignored)");
    const std::string r = role.IsScalar() ? role.Scalar() : std::string();
    if (r == "obstacle") {
      c.role = ClassRole::kObstacle;
    } else if (r == "ground") {
      c.role = ClassRole::kGround;
    } else if (r == "ignored") {
      c.role = ClassRole::kIgnored;
    } else {
      return Fail(where + ".role", "expected obstacle, ground or ignored, got " + Describe(role));
    }
    const YAML::Node color = value["color"];
    if (!color) {
      c.color = io::SegmentColor(static_cast<int>(c.id) + 1);
    } else {
      if (!color.IsSequence() || color.size() != 3) {
        return Fail(where + ".color",
                    "expected [r, g, b], three integers 0..255, got " + Describe(color));
      }
      for (std::size_t k = 0; k < 3; ++k) {
        std::uint32_t v = 0;
        if (!color[k].IsScalar() || !ParseUnsigned(color[k].Scalar(), 255, &v)) {
          return Fail(where + ".color[" + std::to_string(k) + "]",
                      "expected an integer 0..255, got " + Describe(color[k]));
        }
        c.color[k] = static_cast<std::uint8_t>(v);
      }
    }
    return c;
  }

 private:
  std::string source_;
};

// ---------------------------------------------------------------------------------------
// Drawing helpers (OpenCV, BGR).

using detail::FromMat;
using detail::kFont;
const cv::Scalar kInk(20, 20, 20);
const cv::Scalar kPaper(255, 255, 255);

cv::Scalar Bgr(const Rgb& c) { return cv::Scalar(c[2], c[1], c[0]); }
cv::Vec3b Bgr3(const Rgb& c) { return cv::Vec3b(c[2], c[1], c[0]); }

// Outcome colours (see the header).
const Rgb kTpColor = {0, 158, 115};
const Rgb kFpColor = {230, 85, 0};
const Rgb kFnColor = {86, 180, 233};
const Rgb kTnColor = {165, 165, 165};
const Rgb kIgnoredColor = {80, 80, 80};
const Rgb kNoReturnColor = {0, 0, 0};

Rgb OutcomeColor(PointOutcome o) {
  switch (o) {
    case PointOutcome::kTruePositive:
      return kTpColor;
    case PointOutcome::kFalsePositive:
      return kFpColor;
    case PointOutcome::kFalseNegative:
      return kFnColor;
    case PointOutcome::kTrueNegative:
      return kTnColor;
    case PointOutcome::kIgnored:
      return kIgnoredColor;
    case PointOutcome::kNoReturn:
    default:
      return kNoReturnColor;
  }
}

struct Font {
  double scale;
  int thickness;
  int line;  ///< line height [px]
};

int TextWidth(const std::string& text, const Font& f) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, f.scale, f.thickness, &baseline).width;
}

void PutText(cv::Mat& image, const std::string& text, cv::Point baseline_left, const Font& f,
             const cv::Scalar& colour = kInk) {
  cv::putText(image, text, baseline_left, kFont, f.scale, colour, f.thickness, cv::LINE_AA);
}

struct LegendItem {
  Rgb color;
  std::string text;
};

/// Height a legend needs when laid out within `width` (a heading, then swatches that wrap).
int LegendHeight(const std::string& heading, const std::vector<LegendItem>& items, int width,
                 const Font& f) {
  const int swatch = f.line * 2 / 3;
  const int indent = TextWidth(heading, f) + swatch;
  int x = indent, lines = 1;
  for (const LegendItem& item : items) {
    const int w = swatch + swatch / 2 + TextWidth(item.text, f) + 2 * swatch;
    if (x + w > width && x > indent) {  // as DrawLegend wraps
      ++lines;
      x = indent;
    }
    x += w;
  }
  return lines * f.line;
}

/// Draws a legend at (x0, y0) (top left); returns its height.
int DrawLegend(cv::Mat& image, int x0, int y0, int width, const std::string& heading,
               const std::vector<LegendItem>& items, const Font& f) {
  const int swatch = f.line * 2 / 3;
  const int indent = TextWidth(heading, f) + swatch;
  PutText(image, heading, {x0, y0 + swatch}, f);
  int x = indent, y = y0;
  for (const LegendItem& item : items) {
    const int w = swatch + swatch / 2 + TextWidth(item.text, f) + 2 * swatch;
    if (x + w > width && x > indent) {
      x = indent;
      y += f.line;
    }
    const cv::Rect box(x0 + x, y, swatch, swatch);
    cv::rectangle(image, box, Bgr(item.color), cv::FILLED);
    cv::rectangle(image, box, kInk, 1);
    PutText(image, item.text, {x0 + x + swatch + swatch / 2, y + swatch}, f);
    x += w;
  }
  return y - y0 + f.line;
}

std::string WithThousands(std::int64_t v) {
  std::string digits = std::to_string(v < 0 ? -v : v), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return v < 0 ? "-" + out : out;
}

std::string ScoreCaption(const Method& method, const LabelScore& s) {
  const PointCounts& c = s.counts;
  return method.label + ":  P " + FormatRatio3(c.Precision()) + "  R " + FormatRatio3(c.Recall()) +
         "  F1 " + FormatRatio3(c.F1()) + "  IoU " + FormatRatio3(c.IoU()) + "   (TP " +
         WithThousands(c.tp) + ", FP " + WithThousands(c.fp) + ", FN " + WithThousands(c.fn) + ")";
}

/// Classes with at least one return in the frame, obstacles first, then ground, then
/// ignored, each with its count of returns.
std::vector<std::pair<const LabelClass*, std::int64_t>> ClassesSeen(const ClassMap& map,
                                                                    const LabelScore& score) {
  std::vector<std::pair<const LabelClass*, std::int64_t>> seen;
  for (const ClassRole role : {ClassRole::kObstacle, ClassRole::kGround, ClassRole::kIgnored}) {
    for (std::size_t k = 0; k < map.classes.size(); ++k) {
      if (map.classes[k].role == role && score.per_class[k].returns > 0) {
        seen.push_back({&map.classes[k], score.per_class[k].returns});
      }
    }
  }
  return seen;
}

std::vector<LegendItem> ClassLegend(const ClassMap& map, const LabelScore& score) {
  std::vector<LegendItem> items;
  for (const auto& [c, returns] : ClassesSeen(map, score)) {
    items.push_back(
        {c->color, c->name + " (" + ClassRoleName(c->role) + ", " + WithThousands(returns) + ")"});
  }
  return items;
}

std::vector<LegendItem> OutcomeLegend(const ClassMap& map) {
  std::string ignored;
  for (const LabelClass& c : map.classes) {
    if (c.role == ClassRole::kIgnored) ignored += (ignored.empty() ? "" : ", ") + c.name;
  }
  return {{kTpColor, "TP obstacle detected"},
          {kFpColor, "FP ground detected"},
          {kFnColor, "FN obstacle missed"},
          {kTnColor, "TN ground not detected"},
          {kIgnoredColor, "ignored (" + ignored + ")"},
          {kNoReturnColor, "no return"}};
}

/// Index of the point stored in each cell (the nearest of those mapped to it, as
/// RangeImage::FromPoints keeps), -1 for empty cells.
std::vector<std::int32_t> StoredPointOfCell(const LabelFrame& frame) {
  const std::vector<std::int32_t>& cell = frame.image.cell_of_point();
  std::vector<std::int32_t> stored(static_cast<std::size_t>(frame.image.size()), -1);
  std::vector<float> best(stored.size(), std::numeric_limits<float>::infinity());
  for (std::size_t i = 0; i < cell.size(); ++i) {
    if (cell[i] < 0) continue;
    const float range = frame.points[i].norm();
    if (range < best[cell[i]]) {
      best[cell[i]] = range;
      stored[cell[i]] = static_cast<std::int32_t>(i);
    }
  }
  return stored;
}

/// `f` scaled down (if needed) so that `text` fits `width` pixels.
Font FitFont(const std::string& text, Font f, int width) {
  const int w = TextWidth(text, f);
  if (w > width && w > 0) f.scale *= static_cast<double>(width) / w;
  return f;
}

/// Per pixel of a side x side panel (row-major), the category most of its points have, or -1.
/// `pixel[i]` is point i's pixel (-1: not shown), `category[i]` its category (0..categories-1;
/// -1: not shown). Foreground points count on their pixel and its 8 neighbours and win over
/// background points, which count on their pixel only. Ties go to the lower category.
std::vector<std::int32_t> VotePixels(int side, const std::vector<std::int32_t>& pixel,
                                     const std::vector<std::int32_t>& category,
                                     const std::vector<std::uint8_t>& foreground, int categories) {
  // Votes as (pixel, background flag, category), sorted so that each pixel's votes are
  // together, foreground first.
  std::vector<std::uint64_t> votes;
  votes.reserve(pixel.size() * 2);
  const auto vote = [&](std::int64_t px, bool fg, std::int32_t cat) {
    votes.push_back((static_cast<std::uint64_t>(px) << 24) | (fg ? 0u : 1u << 16) |
                    static_cast<std::uint32_t>(cat));
  };
  for (std::size_t i = 0; i < pixel.size(); ++i) {
    if (pixel[i] < 0 || category[i] < 0) continue;
    if (!foreground[i]) {
      vote(pixel[i], false, category[i]);
      continue;
    }
    const int row = pixel[i] / side, col = pixel[i] % side;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int r = row + dr, c = col + dc;
        if (r >= 0 && r < side && c >= 0 && c < side)
          vote(std::int64_t(r) * side + c, true, category[i]);
      }
    }
  }
  std::sort(votes.begin(), votes.end());
  std::vector<std::int32_t> winner(static_cast<std::size_t>(side) * side, -1);
  std::vector<int> count(static_cast<std::size_t>(categories), 0);
  for (std::size_t a = 0; a < votes.size();) {
    const std::uint64_t px = votes[a] >> 24;
    const std::uint64_t layer = (votes[a] >> 16) & 1u;  // the first vote's layer wins
    std::size_t b = a;
    std::fill(count.begin(), count.end(), 0);
    while (b < votes.size() && (votes[b] >> 24) == px) {
      if (((votes[b] >> 16) & 1u) == layer) ++count[votes[b] & 0xFFFFu];
      ++b;
    }
    winner[px] =
        static_cast<std::int32_t>(std::max_element(count.begin(), count.end()) - count.begin());
    a = b;
  }
  return winner;
}

Status CheckResults(const LabelFrame& frame, const std::vector<Method>& methods,
                    const std::vector<LabelMethodResult>& results, const char* what) {
  if (results.size() != methods.size() || results.empty()) {
    return Error{std::string(what) + ": " + std::to_string(results.size()) + " results for " +
                 std::to_string(methods.size()) + " methods"};
  }
  for (const LabelMethodResult& r : results) {
    if (r.scored.outcome.size() != frame.points.size()) {
      return Error{std::string(what) + ": " + std::to_string(r.scored.outcome.size()) +
                   " outcomes for " + std::to_string(frame.points.size()) + " points"};
    }
  }
  if (!std::holds_alternative<od::SphericalModel>(frame.image.model())) {
    return Error{std::string(what) + ": the frame's range image is not a LiDAR scan"};
  }
  return Status::Ok();
}

}  // namespace

// ---------------------------------------------------------------------------------------

const char* ClassRoleName(ClassRole role) {
  switch (role) {
    case ClassRole::kObstacle:
      return "obstacle";
    case ClassRole::kGround:
      return "ground";
    case ClassRole::kIgnored:
    default:
      return "ignored";
  }
}

const LabelClass* ClassMap::Find(std::uint32_t id) const {
  const auto it = std::lower_bound(classes.begin(), classes.end(), id,
                                   [](const LabelClass& c, std::uint32_t v) { return c.id < v; });
  return it != classes.end() && it->id == id ? &*it : nullptr;
}

Expected<ClassMap> ParseClassMap(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    return Error{source + ":" + std::to_string(e.mark.line + 1) + ":" +
                 std::to_string(e.mark.column + 1) + ": invalid YAML: " + e.msg};
  }
  const MapReader reader(source);
  if (Status s = reader.CheckKeys(root, "", {"dataset", "classes"}); !s) return s.error();
  ClassMap map;
  map.source = source;
  if (const YAML::Node dataset = root["dataset"]) {
    if (!dataset.IsScalar()) {
      return reader.Fail("dataset", "expected the dataset's name, got " + Describe(dataset));
    }
    map.dataset = dataset.Scalar();
  }
  const YAML::Node classes = root["classes"];
  if (!classes) return reader.Fail("classes", "missing (a mapping from class id to its class)");
  if (!classes.IsMap() || classes.size() == 0) {
    return reader.Fail("classes",
                       "expected a non-empty mapping from class id to "
                       "{name, role, color}, got " +
                           Describe(classes));
  }
  for (const auto& entry : classes) {
    Expected<LabelClass> c = reader.Class(entry.first, entry.second);
    if (!c) return c.error();
    if (map.Find(c->id) != nullptr) {
      return reader.Fail("classes." + entry.first.Scalar(),
                         "class id " + std::to_string(c->id) + " given twice");
    }
    const auto at = std::lower_bound(map.classes.begin(), map.classes.end(), c->id,
                                     [](const LabelClass& a, std::uint32_t v) { return a.id < v; });
    map.classes.insert(at, std::move(c).value());
  }
  const bool any_obstacle = std::any_of(map.classes.begin(), map.classes.end(), [](const auto& c) {
    return c.role == ClassRole::kObstacle;
  });
  if (!any_obstacle) {
    return reader.Fail("classes", "no class has role obstacle: there would be nothing to find");
  }
  return map;
}

Expected<ClassMap> LoadClassMap(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{name + ": no such file (class mapping)"};
  if (std::filesystem::is_directory(path, ec)) {
    return Error{name + ": is a directory, expected a class mapping YAML file"};
  }
  std::ifstream in(path);
  if (!in) return Error{name + ": cannot open for reading (class mapping)"};
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Error{name + ": read failed (class mapping)"};
  return ParseClassMap(text.str(), name);
}

const ClassTally* LabelScore::Find(std::uint32_t id) const {
  for (const ClassTally& t : per_class) {
    if (t.id == id) return &t;
  }
  return nullptr;
}

Expected<ScoredPoints> ScoreLabels(const ClassMap& map,
                                   const std::vector<std::uint32_t>& truth_labels,
                                   const std::vector<std::uint8_t>& point_class,
                                   const std::vector<std::uint8_t>& has_return,
                                   const std::string& truth_source) {
  const std::size_t n = truth_labels.size();
  if (point_class.size() != n || has_return.size() != n) {
    return Error{truth_source + ": " + std::to_string(n) + " labels, but " +
                 std::to_string(point_class.size()) + " results and " +
                 std::to_string(has_return.size()) + " return flags: one of each per point"};
  }
  // Class id -> position in map.classes (ids fit 16 bits).
  std::vector<std::int32_t> index(kMaxClassId + 1, -1);
  for (std::size_t k = 0; k < map.classes.size(); ++k) {
    index[map.classes[k].id] = static_cast<std::int32_t>(k);
  }
  ScoredPoints out;
  out.outcome.assign(n, PointOutcome::kNoReturn);
  LabelScore& s = out.score;
  s.per_class.resize(map.classes.size());
  for (std::size_t k = 0; k < map.classes.size(); ++k) s.per_class[k].id = map.classes[k].id;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t id = truth_labels[i] & kMaxClassId;
    const std::int32_t k = index[id];
    if (k < 0) {
      return Error{truth_source + ": point " + std::to_string(i) + " has class id " +
                   std::to_string(id) + ", which the class mapping " + map.source +
                   " does not list (add it with a role: obstacle, ground or ignored)"};
    }
    if (!has_return[i]) {
      ++s.no_return;
      continue;
    }
    assert(point_class[i] <= static_cast<std::uint8_t>(od::SegmentClass::kRejected));
    const bool detected = point_class[i] == static_cast<std::uint8_t>(od::SegmentClass::kKept);
    ClassTally& tally = s.per_class[k];
    ++tally.returns;
    tally.detected += detected ? 1 : 0;
    tally.rejected +=
        point_class[i] == static_cast<std::uint8_t>(od::SegmentClass::kRejected) ? 1 : 0;
    PointOutcome& o = out.outcome[i];
    switch (map.classes[k].role) {
      case ClassRole::kIgnored:
        o = PointOutcome::kIgnored;
        ++s.ignored;
        break;
      case ClassRole::kObstacle:
        o = detected ? PointOutcome::kTruePositive : PointOutcome::kFalseNegative;
        ++(detected ? s.counts.tp : s.counts.fn);
        break;
      case ClassRole::kGround:
        o = detected ? PointOutcome::kFalsePositive : PointOutcome::kTrueNegative;
        ++(detected ? s.counts.fp : s.tn);
        break;
    }
  }
  return out;
}

std::vector<std::uint8_t> LabelFrame::HasReturn() const {
  const std::vector<std::int32_t>& cell = image.cell_of_point();
  std::vector<std::uint8_t> out(cell.size());
  for (std::size_t i = 0; i < cell.size(); ++i) out[i] = cell[i] >= 0 ? 1 : 0;
  return out;
}

Expected<LabelFrame> LoadLabelFrame(const std::filesystem::path& points_bin,
                                    const std::filesystem::path& labels_file,
                                    const od::SphericalModel& preset, od::OrganisedMode mode,
                                    const Eigen::Vector3d& up_sensor) {
  Expected<od::PointCloud> cloud = io::ReadKittiBin(points_bin);
  if (!cloud) return cloud.error();
  Expected<std::vector<std::uint32_t>> labels = io::ReadLabelFile(labels_file);
  if (!labels) return labels.error();
  if (labels->size() != cloud->points.size()) {
    return Error{labels_file.string() + ": " + std::to_string(labels->size()) + " labels for the " +
                 std::to_string(cloud->points.size()) + " points of " + points_bin.string() +
                 " (expected one uint32 per point)"};
  }
  Expected<od::PointLayout> layout = od::ResolveLayout(*cloud, preset, mode, points_bin.string());
  if (!layout) return layout.error();
  Expected<od::RangeImage> image = od::RangeImage::FromPoints(
      cloud->points, layout->model, up_sensor, layout->rows, layout->cols);
  if (!image) return Error{points_bin.string() + ": " + image.error().message};
  LabelFrame frame;
  frame.name = points_bin.stem().string();
  frame.points_source = points_bin.string();
  frame.labels_source = labels_file.string();
  frame.points = std::move(cloud->points);
  frame.truth = std::move(labels).value();
  frame.organised = layout->organised;
  frame.image = std::move(image).value();
  return frame;
}

Expected<std::vector<LabelMethodResult>> EvaluateLabels(const LabelFrame& frame,
                                                        const ClassMap& map,
                                                        const od::io::DetectSettings& settings,
                                                        const std::vector<Method>& methods) {
  Expected<std::vector<MethodRun>> runs = RunMethods(frame.image, settings, methods);
  if (!runs) return Error{frame.points_source + ": " + runs.error().message};
  const std::vector<std::uint8_t> has_return = frame.HasReturn();
  std::vector<LabelMethodResult> results;
  for (std::size_t k = 0; k < methods.size(); ++k) {
    LabelMethodResult r;
    r.run = std::move((*runs)[k]);
    // Per point through cell_of_point, exactly as `cairn detect` writes labels.label.
    Expected<std::vector<std::uint32_t>> labels =
        io::PointLabels(frame.image, r.run.detection, r.run.classification);
    if (!labels) return Error{methods[k].label + ": " + labels.error().message};
    r.point_class.resize(labels->size());
    for (std::size_t i = 0; i < labels->size(); ++i) {
      r.point_class[i] = static_cast<std::uint8_t>((*labels)[i] & 0xFFFFu);
    }
    Expected<ScoredPoints> scored =
        ScoreLabels(map, frame.truth, r.point_class, has_return, frame.labels_source);
    if (!scored) return scored.error();
    r.scored = std::move(scored).value();
    results.push_back(std::move(r));
  }
  return results;
}

// ---------------------------------------------------------------------------------------
// Figures.

Expected<io::RgbImage> LabelRangeFigure(const LabelFrame& frame, const ClassMap& map,
                                        const std::vector<Method>& methods,
                                        const std::vector<LabelMethodResult>& results,
                                        const LabelFigureOptions& options) {
  if (Status s = CheckResults(frame, methods, results, "range image figure"); !s) return s.error();
  if (options.pixels_per_ring < 1 || options.pixels_per_ring > 16) {
    return Error{"range image figure: pixels_per_ring must be 1..16"};
  }
  const od::SphericalModel& model = std::get<od::SphericalModel>(frame.image.model());
  const int width = frame.image.width(), rings = frame.image.height();
  const int ppr = options.pixels_per_ring;
  const Font title{1.1, 2, 44}, text{0.8, 2, 36}, small{0.65, 2, 30};
  const int margin = 16, left = 120;  // left: ring labels
  const int canvas_width = left + width + margin;
  const int panel_height = rings * ppr;
  const int axis_height = small.line + 8;
  const int panels = 1 + static_cast<int>(methods.size());
  const std::vector<LegendItem> class_items = ClassLegend(map, results[0].scored.score);
  const std::vector<LegendItem> outcome_items = OutcomeLegend(map);
  const int legend_width = canvas_width - 2 * margin;
  const int legend_height = LegendHeight("true class:", class_items, legend_width, text) +
                            LegendHeight("outcome:", outcome_items, legend_width, text) + 8;
  const int canvas_height = margin + 2 * title.line +
                            panels * (text.line + panel_height + axis_height + 8) + legend_height +
                            margin;
  cv::Mat canvas(canvas_height, canvas_width, CV_8UC3, kPaper);

  const std::string dataset = map.dataset.empty() ? "" : map.dataset + " ";
  const std::string heading = dataset + frame.name + ": range image, " + std::to_string(rings) +
                              " rings x " + std::to_string(width) + " azimuth steps (" +
                              std::to_string(ppr) + " px per ring), " +
                              WithThousands(frame.image.valid_count()) + " cells with a return";
  PutText(canvas, heading, {margin, margin + title.line - 12},
          FitFont(heading, title, legend_width));
  const std::string sub =
      "Top beam first. Azimuth in degrees, +x (ahead) in the middle; columns sweep clockwise "
      "seen from above: behind, left, ahead, right, behind. Each cell shows its nearest point.";
  PutText(canvas, sub, {margin, margin + 2 * title.line - 14}, FitFont(sub, text, legend_width));

  // Display column of each image column: +x (azimuth 0) in the middle.
  const int col_ahead = model.Column(Eigen::Vector3d::UnitX());
  const auto display = [&](int col) {
    return ((col - col_ahead + width / 2) % width + width) % width;
  };
  std::vector<std::pair<int, std::string>> ticks;  // every 45 deg, the main directions named
  for (int deg = 180; deg > -180; deg -= 45) {
    const double a = deg * kPi / 180.0;
    std::string label = std::to_string(deg);
    if (deg == 0) label += " ahead (+x)";
    if (deg == 90) label += " left";
    if (deg == -90) label += " right";
    if (deg == 180) label += " behind";
    ticks.push_back({display(model.Column(Eigen::Vector3d(std::cos(a), std::sin(a), 0.0))), label});
  }

  const std::vector<std::int32_t> stored = StoredPointOfCell(frame);
  int y = margin + 2 * title.line;
  for (int p = 0; p < panels; ++p) {
    const std::string caption =
        p == 0 ? "true class" : ScoreCaption(methods[p - 1], results[p - 1].scored.score);
    PutText(canvas, caption, {left, y + text.line - 10}, FitFont(caption, text, width));
    y += text.line;
    cv::Mat panel(panel_height, width, CV_8UC3, cv::Scalar(0, 0, 0));
    for (int cell = 0; cell < frame.image.size(); ++cell) {
      const std::int32_t i = stored[cell];
      if (i < 0) continue;
      Rgb colour = kNoReturnColor;
      if (p == 0) {
        const LabelClass* c = map.Find(frame.truth[i] & kMaxClassId);
        colour = c ? c->color : kNoReturnColor;
      } else {
        colour = OutcomeColor(results[p - 1].scored.outcome[i]);
      }
      const int row = cell / width, col = display(cell % width);
      panel(cv::Rect(col, row * ppr, 1, ppr)).setTo(Bgr(colour));
    }
    panel.copyTo(canvas(cv::Rect(left, y, width, panel_height)));
    cv::rectangle(canvas, cv::Rect(left - 1, y - 1, width + 2, panel_height + 2), kInk, 1);
    PutText(canvas, "ring 0", {margin, y + small.line - 10}, small);
    PutText(canvas, "ring " + std::to_string(rings - 1), {margin, y + panel_height}, small);
    y += panel_height;
    PutText(canvas, "azimuth", {margin, y + 6 + small.line - 6}, small);
    for (const auto& [col, label] : ticks) {
      const int x = left + col;
      cv::line(canvas, {x, y}, {x, y + 7}, kInk, 2);
      const int w = TextWidth(label, small);
      const int tx = std::clamp(x - w / 2, left, left + width - w);
      PutText(canvas, label, {tx, y + 6 + small.line - 6}, small);
    }
    y += axis_height + 8;
  }
  y += 4;
  y += DrawLegend(canvas, margin, y, legend_width, "true class:", class_items, text);
  DrawLegend(canvas, margin, y, legend_width, "outcome:", outcome_items, text);
  return FromMat(canvas);
}

Expected<io::RgbImage> LabelBirdsEyeFigure(const LabelFrame& frame, const ClassMap& map,
                                           const std::vector<Method>& methods,
                                           const std::vector<LabelMethodResult>& results,
                                           const LabelFigureOptions& options) {
  if (Status s = CheckResults(frame, methods, results, "bird's-eye figure"); !s) return s.error();
  const double mpp = options.birds_eye_m_per_px, half = options.birds_eye_half_extent_m;
  if (!(mpp > 0.0) || !(half > 0.0) || half / mpp > 4000.0) {
    return Error{
        "bird's-eye figure: birds_eye_m_per_px and birds_eye_half_extent_m must be "
        "positive, at most 8000 px across"};
  }
  const int side = static_cast<int>(std::ceil(2.0 * half / mpp));
  const Font title{1.1, 2, 44}, text{0.8, 2, 36}, small{0.65, 2, 30};
  const int margin = 16, gap = 24;
  const int panels = 1 + static_cast<int>(methods.size());
  const int per_row = std::min(panels, kBirdsEyePanelsPerRow);
  const int panel_rows = (panels + per_row - 1) / per_row;
  const int caption_height = 3 * text.line;
  const int scale_height = small.line + 14;
  const int cell_height = caption_height + side + scale_height;
  const int canvas_width = 2 * margin + per_row * side + (per_row - 1) * gap;
  const std::vector<LegendItem> class_items = ClassLegend(map, results[0].scored.score);
  const std::vector<LegendItem> outcome_items = OutcomeLegend(map);
  const int legend_width = canvas_width - 2 * margin;
  const int legend_height = LegendHeight("true class:", class_items, legend_width, text) +
                            LegendHeight("outcome:", outcome_items, legend_width, text) + 8;
  const int canvas_height =
      margin + 2 * title.line + panel_rows * (cell_height + gap) + legend_height + margin;
  cv::Mat canvas(canvas_height, canvas_width, CV_8UC3, kPaper);

  const std::string dataset = map.dataset.empty() ? "" : map.dataset + " ";
  std::ostringstream heading;
  heading << dataset << frame.name << " from above: level frame, x forward (up), y left, sensor "
          << "at the centre (white triangle), +-" << half << " m, " << mpp << " m per px";
  PutText(canvas, heading.str(), {margin, margin + title.line - 12},
          FitFont(heading.str(), title, legend_width));
  const std::string sub =
      "Circles every 10 m. Each pixel shows the class (outcome) most of its points have; "
      "obstacle points and detections (TP, FP, FN) are drawn 3 px wide and win over ground and "
      "ignored points.";
  PutText(canvas, sub, {margin, margin + 2 * title.line - 14}, FitFont(sub, text, legend_width));

  const Eigen::Matrix3f R = frame.image.R_level_sensor().cast<float>();
  std::vector<std::int32_t> pixel(frame.points.size(), -1);  // row * side + col
  const std::vector<std::uint8_t> has_return = frame.HasReturn();
  for (std::size_t i = 0; i < frame.points.size(); ++i) {
    if (!has_return[i]) continue;
    const Eigen::Vector3f q = R * frame.points[i];
    const double row = std::floor((half - q.x()) / mpp), col = std::floor((half - q.y()) / mpp);
    if (row >= 0 && row < side && col >= 0 && col < side) {
      pixel[i] = static_cast<std::int32_t>(row) * side + static_cast<std::int32_t>(col);
    }
  }
  const LabelScore& score0 = results[0].scored.score;
  for (int p = 0; p < panels; ++p) {
    const int x0 = margin + (p % per_row) * (side + gap);
    const int top = margin + 2 * title.line + (p / per_row) * (cell_height + gap);
    std::vector<std::string> caption;
    std::vector<std::int32_t> category(frame.points.size(), -1);
    std::vector<std::uint8_t> foreground(frame.points.size(), 0);
    std::vector<Rgb> palette;
    if (p == 0) {
      caption = {"true class",
                 WithThousands(score0.counts.tp + score0.counts.fn) + " obstacle, " +
                     WithThousands(score0.tn + score0.counts.fp) + " ground returns",
                 WithThousands(score0.ignored) + " ignored, " + WithThousands(score0.no_return) +
                     " without a return"};
      for (const LabelClass& c : map.classes) palette.push_back(c.color);
      for (std::size_t i = 0; i < frame.points.size(); ++i) {
        const LabelClass* c = map.Find(frame.truth[i] & kMaxClassId);
        if (c == nullptr) continue;
        category[i] = static_cast<std::int32_t>(c - map.classes.data());
        foreground[i] = c->role == ClassRole::kObstacle ? 1 : 0;
      }
    } else {
      const LabelScore& s = results[p - 1].scored.score;
      caption = {methods[p - 1].label,
                 "P " + FormatRatio3(s.counts.Precision()) + "  R " +
                     FormatRatio3(s.counts.Recall()) + "  F1 " + FormatRatio3(s.counts.F1()) +
                     "  IoU " + FormatRatio3(s.counts.IoU()),
                 "TP " + WithThousands(s.counts.tp) + "  FP " + WithThousands(s.counts.fp) +
                     "  FN " + WithThousands(s.counts.fn)};
      for (int o = 0; o <= static_cast<int>(PointOutcome::kTrueNegative); ++o) {
        palette.push_back(OutcomeColor(static_cast<PointOutcome>(o)));
      }
      const std::vector<PointOutcome>& outcome = results[p - 1].scored.outcome;
      for (std::size_t i = 0; i < frame.points.size(); ++i) {
        category[i] = static_cast<std::int32_t>(outcome[i]);
        foreground[i] = outcome[i] == PointOutcome::kTruePositive ||
                                outcome[i] == PointOutcome::kFalsePositive ||
                                outcome[i] == PointOutcome::kFalseNegative
                            ? 1
                            : 0;
      }
    }
    for (std::size_t k = 0; k < caption.size(); ++k) {
      PutText(canvas, caption[k], {x0, top + static_cast<int>(k + 1) * text.line - 10},
              FitFont(caption[k], text, side));
    }
    const int panel_top = top + caption_height;
    cv::Mat panel(side, side, CV_8UC3, cv::Scalar(0, 0, 0));
    const cv::Point centre(static_cast<int>(std::lround(half / mpp)),
                           static_cast<int>(std::lround(half / mpp)));
    for (int r_m = 10; r_m < half * std::sqrt(2.0); r_m += 10) {
      cv::circle(panel, centre, static_cast<int>(std::lround(r_m / mpp)), cv::Scalar(70, 70, 70), 1,
                 cv::LINE_AA);
      const double a = kPi / 4.0;  // labels up and to the right
      const cv::Point at(centre.x + static_cast<int>(r_m / mpp * std::cos(a)) + 4,
                         centre.y - static_cast<int>(r_m / mpp * std::sin(a)) - 4);
      if (at.x < side - 60 && at.y > 24) {
        PutText(panel, std::to_string(r_m) + " m", at, small, cv::Scalar(170, 170, 170));
      }
    }
    const std::vector<std::int32_t> winner =
        VotePixels(side, pixel, category, foreground, static_cast<int>(palette.size()));
    for (int k = 0; k < side * side; ++k) {
      if (winner[k] >= 0) panel.at<cv::Vec3b>(k / side, k % side) = Bgr3(palette[winner[k]]);
    }
    // The sensor, pointing forward (up).
    const std::vector<cv::Point> triangle = {centre + cv::Point(0, -10), centre + cv::Point(7, 8),
                                             centre + cv::Point(-7, 8)};
    cv::fillConvexPoly(panel, triangle, cv::Scalar(255, 255, 255), cv::LINE_AA);
    panel.copyTo(canvas(cv::Rect(x0, panel_top, side, side)));
    cv::rectangle(canvas, cv::Rect(x0 - 1, panel_top - 1, side + 2, side + 2), kInk, 1);
    // Scale bar under each panel: 10 m.
    const int bar = static_cast<int>(std::lround(10.0 / mpp));
    const int by = panel_top + side + 10;
    cv::rectangle(canvas, cv::Rect(x0, by, bar, 6), kInk, cv::FILLED);
    PutText(canvas, "10 m", {x0 + bar + 10, by + 12}, small);
  }
  int y = margin + 2 * title.line + panel_rows * (cell_height + gap);
  y += DrawLegend(canvas, margin, y, legend_width, "true class:", class_items, text);
  DrawLegend(canvas, margin, y, legend_width, "outcome:", outcome_items, text);
  return FromMat(canvas);
}

// ---------------------------------------------------------------------------------------
// Tables.

std::string FormatRatio3(double value) {
  if (!std::isfinite(value)) return "-";
  return util::Fixed(value, 3);
}

std::string LabelResultsMarkdown(const std::vector<Method>& methods,
                                 const std::vector<LabelMethodResult>& results) {
  assert(methods.size() == results.size());
  std::ostringstream md;
  md << "| method | precision | recall | F1 | IoU | TP | FP | FN | TN | ignored | no return | "
        "segments kept / rejected |\n"
     << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const LabelScore& s = results[k].scored.score;
    const od::Classification& c = results[k].run.classification;
    md << "| " << methods[k].label << " | " << FormatRatio3(s.counts.Precision()) << " | "
       << FormatRatio3(s.counts.Recall()) << " | " << FormatRatio3(s.counts.F1()) << " | "
       << FormatRatio3(s.counts.IoU()) << " | " << s.counts.tp << " | " << s.counts.fp << " | "
       << s.counts.fn << " | " << s.tn << " | " << s.ignored << " | " << s.no_return << " | "
       << c.kept << " / " << c.rejected << " |\n";
  }
  return md.str();
}

std::string LabelClassesMarkdown(const ClassMap& map, const std::vector<Method>& methods,
                                 const std::vector<LabelMethodResult>& results) {
  assert(methods.size() == results.size() && !results.empty());
  std::ostringstream md;
  md << "| class (id) | role | returns |";
  for (const Method& m : methods) md << " " << m.label << " |";
  md << "\n| --- | --- | --- |";
  for (std::size_t k = 0; k < methods.size(); ++k) md << " --- |";
  md << "\n";
  for (const auto& [c, returns] : ClassesSeen(map, results[0].scored.score)) {
    md << "| " << c->name << " (" << c->id << ") | " << ClassRoleName(c->role) << " | " << returns
       << " |";
    for (const LabelMethodResult& r : results) {
      const ClassTally* t = r.scored.score.Find(c->id);
      md << " " << FormatRatio3(double(t->detected) / double(t->returns)) << " (" << t->detected
         << ") |";
    }
    md << "\n";
  }
  return md.str();
}

std::string LabelErrorsMarkdown(const ClassMap& map, const std::vector<Method>& methods,
                                const std::vector<LabelMethodResult>& results) {
  assert(methods.size() == results.size());
  std::ostringstream md;
  const auto list = [&](const LabelScore& s, ClassRole role, std::int64_t total) {
    std::vector<std::pair<std::int64_t, const LabelClass*>> by_class;
    for (std::size_t k = 0; k < map.classes.size(); ++k) {
      if (map.classes[k].role != role) continue;
      const ClassTally& t = s.per_class[k];
      const std::int64_t n = role == ClassRole::kGround ? t.detected : t.returns - t.detected;
      if (n > 0) by_class.push_back({n, &map.classes[k]});
    }
    std::stable_sort(by_class.begin(), by_class.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    std::string text;
    for (const auto& [n, c] : by_class) {
      const long percent = std::lround(100.0 * n / total);
      text += (text.empty() ? "" : ", ") + c->name + " " + std::to_string(n) + " (" +
              (percent == 0 ? std::string("<1") : std::to_string(percent)) + "%)";
    }
    return text.empty() ? std::string("none") : text;
  };
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const LabelScore& s = results[k].scored.score;
    md << "- " << methods[k].label << ": false positives " << s.counts.fp << ": "
       << list(s, ClassRole::kGround, s.counts.fp) << "; false negatives " << s.counts.fn << ": "
       << list(s, ClassRole::kObstacle, s.counts.fn) << ".\n";
  }
  return md.str();
}

std::string LabelResultsCsv(const ClassMap& map, const std::vector<Method>& methods,
                            const std::vector<LabelMethodResult>& results) {
  assert(methods.size() == results.size());
  std::ostringstream csv;
  csv << "method,scope,class_id,class,role,returns,detected,rejected,tp,fp,fn,tn,ignored,"
         "no_return,precision,recall,f1,iou\n";
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const LabelScore& s = results[k].scored.score;
    std::int64_t returns = 0, detected = 0, rejected = 0;
    for (const ClassTally& t : s.per_class) {
      returns += t.returns;
      detected += t.detected;
      rejected += t.rejected;
    }
    csv << methods[k].key << ",all,,,," << returns << "," << detected << "," << rejected << ","
        << s.counts.tp << "," << s.counts.fp << "," << s.counts.fn << "," << s.tn << ","
        << s.ignored << "," << s.no_return << "," << FormatRatio3(s.counts.Precision()) << ","
        << FormatRatio3(s.counts.Recall()) << "," << FormatRatio3(s.counts.F1()) << ","
        << FormatRatio3(s.counts.IoU()) << "\n";
    for (std::size_t c = 0; c < map.classes.size(); ++c) {
      const ClassTally& t = s.per_class[c];
      if (t.returns == 0) continue;
      csv << methods[k].key << ",class," << t.id << "," << map.classes[c].name << ","
          << ClassRoleName(map.classes[c].role) << "," << t.returns << "," << t.detected << ","
          << t.rejected << ",,,,,,,,,,\n";
    }
  }
  return csv.str();
}

}  // namespace cairn::eval
