#include "cairn/eval/methods.hpp"

#include <chrono>
#include <map>
#include <set>
#include <tuple>
#include <utility>

#include "cairn/od/column_detector.hpp"

namespace cairn::eval {
namespace {

using Clock = std::chrono::steady_clock;

/// What decides a detection: methods with equal keys share one.
std::tuple<int, int> DetectionKey(const Method& m) {
  return {static_cast<int>(m.detector),
          m.detector == DetectorKind::kCone ? static_cast<int>(m.search) : 0};
}

}  // namespace

std::vector<Method> StandardMethods() {
  return {
      {"cone_exact_rules", "cone exact + rules", DetectorKind::kCone, od::SearchMode::kExact, true},
      {"cone_exact", "cone exact (no rules)", DetectorKind::kCone, od::SearchMode::kExact, false},
      {"cone_window_rules", "cone paper window + rules", DetectorKind::kCone,
       od::SearchMode::kPaperWindow, true},
      {"column_rules", "column + rules", DetectorKind::kColumn, od::SearchMode::kExact, true},
      {"column", "column (no rules)", DetectorKind::kColumn, od::SearchMode::kExact, false},
  };
}

std::vector<Method> KnownMethods() {
  std::vector<Method> all = StandardMethods();
  Method no_feet = all.front();
  no_feet.key = "cone_exact_rules_nofeet";
  no_feet.label = "cone exact + rules, feet as ground";
  no_feet.feet = false;
  all.push_back(no_feet);
  return all;
}

Expected<std::vector<Method>> SelectMethods(const std::string& keys) {
  const std::vector<Method> all = KnownMethods();
  std::string known;
  for (const Method& m : all) known += (known.empty() ? "" : ", ") + m.key;
  std::vector<Method> chosen;
  std::set<std::string> seen;
  std::size_t start = 0;
  while (start <= keys.size()) {
    const std::size_t comma = keys.find(',', start);
    const std::string key =
        keys.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    start = comma == std::string::npos ? keys.size() + 1 : comma + 1;
    const Method* found = nullptr;
    for (const Method& m : all) {
      if (m.key == key) found = &m;
    }
    if (found == nullptr) {
      return Error{"unknown method '" + key + "' (expected a comma-separated list of " + known +
                   ")"};
    }
    if (!seen.insert(key).second) return Error{"method '" + key + "' given twice"};
    chosen.push_back(*found);
  }
  return chosen;
}

Expected<std::vector<MethodRun>> RunMethods(const od::RangeImage& image,
                                            const od::io::DetectSettings& settings,
                                            const std::vector<Method>& methods) {
  std::map<std::tuple<int, int>, std::pair<od::Detection, double>> detections;
  std::vector<MethodRun> runs;
  runs.reserve(methods.size());
  for (const Method& method : methods) {
    const auto key = DetectionKey(method);
    auto it = detections.find(key);
    if (it == detections.end()) {
      const Clock::time_point start = Clock::now();
      Expected<od::Detection> detection = Error{"no detector"};
      if (method.detector == DetectorKind::kCone) {
        od::DetectorConfig config = settings.detector;
        config.search = method.search;
        detection = od::Detect(image, config);
      } else {
        od::ColumnConfig config = od::ColumnConfig::From(settings.detector);
        config.min_blob_pixels = settings.min_blob_pixels;
        detection = od::DetectColumns(image, config);
      }
      if (!detection) return Error{method.label + ": " + detection.error().message};
      const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      it = detections.emplace(key, std::make_pair(std::move(detection).value(), ms)).first;
    }
    MethodRun run;
    run.detection = method.feet ? it->second.first : od::WithoutFeet(it->second.first);
    run.detect_ms = it->second.second;
    if (method.rules) {
      Expected<od::Classification> c = od::Classify(run.detection, settings.rules);
      if (!c) return Error{method.label + ": " + c.error().message};
      run.classification = std::move(c).value();
    } else {
      run.classification = od::KeepAll(run.detection);
    }
    runs.push_back(std::move(run));
  }
  return runs;
}

Expected<FrameEvaluation> EvaluateFrame(const EvalFrame& frame,
                                        const od::io::DetectSettings& settings,
                                        const std::vector<Method>& methods,
                                        const ScoreOptions& options) {
  FrameEvaluation out;
  Expected<std::vector<MethodRun>> runs = RunMethods(frame.image, settings, methods);
  if (!runs) return Error{frame.name + ": " + runs.error().message};
  out.runs = std::move(runs).value();
  out.foot_band = FootBand(frame.image, frame.truth, settings.detector.max_height_m,
                           settings.detector.min_slope_rad);
  for (std::size_t k = 0; k < methods.size(); ++k) {
    Expected<FrameScore> score = ScoreDetection(frame.truth, out.foot_band, out.runs[k].detection,
                                                out.runs[k].classification, options);
    if (!score) return Error{frame.name + ": " + methods[k].label + ": " + score.error().message};
    out.scores.push_back(std::move(score).value());
  }
  return out;
}

}  // namespace cairn::eval
