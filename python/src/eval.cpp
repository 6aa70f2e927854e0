// cairn.load_class_map, cairn.score_labels: the per-point scores of `cairn eval --labels`
// (cairn::eval::ScoreLabels) on any per-point result, such as DetectionResult's
// point_labels, against SemanticKITTI-style labels.
#include <cstdint>
#include <string>
#include <vector>

#include "cairn/eval/label_eval.hpp"
#include "common.hpp"

namespace cairn::python {
namespace {

namespace ev = cairn::eval;

/// cairn.LabelScore: the scored points and the classes of the map they were scored with.
struct LabelScore {
  ev::ScoredPoints scored;
  std::vector<ev::LabelClass> classes;
};

ev::ClassMap LoadClassMap(const std::string& path) {
  py::gil_scoped_release release;
  return Unwrap(ev::LoadClassMap(path));
}

/// `point_labels`: (N,) uint32, SegmentClass in the lower 16 bits (cairn's labels.label);
/// `truth`: (N,) uint32 .label entries; `has_return`: (N,) bool / uint8 (non-zero where the
/// point is a return), or None for "every point whose class word is not a no-return".
LabelScore ScoreLabels(const ev::ClassMap& map, const InArray<std::uint32_t>& truth,
                             const InArray<std::uint32_t>& point_labels,
                             const py::object& has_return, const std::string& truth_source) {
  if (truth.ndim() != 1) throw CairnError("truth: expected an (N,) array of .label entries");
  if (point_labels.ndim() != 1) {
    throw CairnError("point_labels: expected an (N,) array of cairn's labels.label words");
  }
  const auto n = static_cast<std::size_t>(point_labels.shape(0));
  std::vector<std::uint32_t> truth_labels(truth.data(), truth.data() + truth.shape(0));
  std::vector<std::uint8_t> point_class(n);
  for (std::size_t i = 0; i < n; ++i) {
    point_class[i] = static_cast<std::uint8_t>(point_labels.data()[i] & 0xFFFFu);
  }
  std::vector<std::uint8_t> returns;
  if (has_return.is_none()) {
    returns.assign(n, 1);
  } else {
    auto mask = has_return.cast<InArray<std::uint8_t>>();
    if (mask.ndim() != 1) throw CairnError("has_return: expected an (N,) array");
    returns.assign(mask.data(), mask.data() + mask.shape(0));
  }
  py::gil_scoped_release release;
  return LabelScore{Unwrap(ev::ScoreLabels(map, truth_labels, point_class, returns, truth_source)),
                    map.classes};
}

py::dict Tally(const ev::ClassTally& t, const ev::LabelClass& c) {
  py::dict d;
  d["id"] = t.id;
  d["name"] = c.name;
  d["role"] = ev::ClassRoleName(c.role);
  d["returns"] = t.returns;
  d["detected"] = t.detected;
  d["rejected"] = t.rejected;
  return d;
}

}  // namespace

void RegisterEval(py::module_& m) {
  py::class_<ev::ClassMap>(m, "ClassMap",
                           "Which dataset classes are obstacles, ground or ignored "
                           "(config/classes/*.yaml, read strictly).")
      .def_readonly("source", &ev::ClassMap::source, "The file it was read from.")
      .def_readonly("dataset", &ev::ClassMap::dataset)
      .def_property_readonly(
          "classes",
          [](const ev::ClassMap& map) {
            py::list out;
            for (const ev::LabelClass& c : map.classes) {
              py::dict d;
              d["id"] = c.id;
              d["name"] = c.name;
              d["role"] = ev::ClassRoleName(c.role);
              d["color"] = py::make_tuple(c.color[0], c.color[1], c.color[2]);
              out.append(d);
            }
            return out;
          },
          "One dict per class (id, name, role: obstacle | ground | ignored, color (r, g, b)), "
          "sorted by id.")
      .def("__repr__", [](const ev::ClassMap& map) {
        return "cairn.ClassMap('" + map.source + "', " + std::to_string(map.classes.size()) +
               " classes)";
      });
  m.def("load_class_map", &LoadClassMap, py::arg("path"),
        "Reads a class mapping YAML (`cairn eval --classes`), e.g. config/classes/rellis3d.yaml.");

  py::class_<LabelScore>(m, "LabelScore",
                               "Per-point obstacle score of one result against true labels, "
                               "as `cairn eval --labels` writes it to results.csv.")
      .def_property_readonly("tp", [](const LabelScore& s) { return s.scored.score.counts.tp; },
                             "Detected true obstacle points.")
      .def_property_readonly("fp", [](const LabelScore& s) { return s.scored.score.counts.fp; },
                             "Detected ground points.")
      .def_property_readonly("fn", [](const LabelScore& s) { return s.scored.score.counts.fn; },
                             "True obstacle points not detected (or in a rejected segment).")
      .def_property_readonly("tn", [](const LabelScore& s) { return s.scored.score.tn; })
      .def_property_readonly("ignored", [](const LabelScore& s) { return s.scored.score.ignored; },
                             "Returns of ignored classes, not scored.")
      .def_property_readonly("no_return",
                             [](const LabelScore& s) { return s.scored.score.no_return; },
                             "Points without a return, not scored.")
      .def_property_readonly(
          "precision", [](const LabelScore& s) { return s.scored.score.counts.Precision(); },
          "tp / (tp + fp); NaN when undefined.")
      .def_property_readonly("recall",
                             [](const LabelScore& s) { return s.scored.score.counts.Recall(); },
                             "tp / (tp + fn); NaN when undefined.")
      .def_property_readonly("f1", [](const LabelScore& s) { return s.scored.score.counts.F1(); })
      .def_property_readonly("iou", [](const LabelScore& s) { return s.scored.score.counts.IoU(); },
                             "tp / (tp + fp + fn).")
      .def_property_readonly(
          "outcome",
          [](const LabelScore& s) {
            std::vector<std::uint8_t> out(s.scored.outcome.size());
            for (std::size_t i = 0; i < out.size(); ++i) {
              out[i] = static_cast<std::uint8_t>(s.scored.outcome[i]);
            }
            return Take(std::move(out), {static_cast<py::ssize_t>(s.scored.outcome.size())});
          },
          "(N,) uint8 per point: OUTCOME_NO_RETURN, OUTCOME_IGNORED, OUTCOME_TP, OUTCOME_FP, "
          "OUTCOME_FN, OUTCOME_TN.")
      .def_property_readonly(
          "per_class",
          [](const LabelScore& s) {
            py::list out;
            for (std::size_t c = 0; c < s.classes.size(); ++c) {
              out.append(Tally(s.scored.score.per_class[c], s.classes[c]));
            }
            return out;
          },
          "One dict per class of the map (id, name, role, returns, detected, rejected).")
      .def("__repr__", [](const LabelScore& s) {
        const ev::PointCounts& c = s.scored.score.counts;
        return "cairn.LabelScore(tp=" + std::to_string(c.tp) + ", fp=" + std::to_string(c.fp) +
               ", fn=" + std::to_string(c.fn) + ")";
      });
  m.attr("OUTCOME_NO_RETURN") = static_cast<int>(ev::PointOutcome::kNoReturn);
  m.attr("OUTCOME_IGNORED") = static_cast<int>(ev::PointOutcome::kIgnored);
  m.attr("OUTCOME_TP") = static_cast<int>(ev::PointOutcome::kTruePositive);
  m.attr("OUTCOME_FP") = static_cast<int>(ev::PointOutcome::kFalsePositive);
  m.attr("OUTCOME_FN") = static_cast<int>(ev::PointOutcome::kFalseNegative);
  m.attr("OUTCOME_TN") = static_cast<int>(ev::PointOutcome::kTrueNegative);

  m.def(
      "score_labels", &ScoreLabels, py::arg("class_map"), py::arg("truth"), py::arg("point_labels"), py::kw_only(),
      py::arg("has_return") = py::none(), py::arg("truth_source") = "truth",
      "Scores per-point results (cairn's labels.label words, e.g. DetectionResult.point_labels) "
      "against SemanticKITTI-style labels (class id = lower 16 bits), as `cairn eval --labels`: "
      "a point is detected when it lies in a kept segment. `has_return`: (N,) non-zero where the "
      "point is a return (DetectionResult.cell_of_point >= 0); None scores every point.");
}

}  // namespace cairn::python
