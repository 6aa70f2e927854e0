#include "cairn/eval/world_eval.hpp"

#include <cctype>
#include <chrono>

#include "cairn/eval/figures.hpp"
#include "cairn/eval/report.hpp"
#include "cairn/util/format.hpp"

namespace cairn::eval {
namespace {

namespace fs = std::filesystem;

/// A file name made from a world or frame name.
std::string FileStem(std::string name) {
  for (char& c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_')) c = '_';
  }
  return name.empty() ? "frame" : name;
}

}  // namespace

Status WorldEvaluation::Add(const std::string& name, const std::string& description,
                            const std::string& source, const std::vector<EvalFrame>& frames) {
  WorldRun run;
  run.name = name;
  run.description = description;
  run.source = source;
  run.per_method.assign(methods_.size(), Score{});
  run.ms_sum.assign(methods_.size(), 0.0);
  std::vector<od::io::RgbImage> strips;
  for (const EvalFrame& frame : frames) {
    Expected<FrameEvaluation> e = EvaluateFrame(frame, settings_, methods_, options_.score);
    if (!e) return e.error();
    for (std::size_t m = 0; m < methods_.size(); ++m) {
      run.per_method[m] += e->scores[m].score;
      run.ms_sum[m] += e->runs[m].detect_ms;
    }
    FigureOptions figure_options;
    figure_options.cell_width = options_.cell_width;
    Expected<od::io::RgbImage> strip = ComparisonStrip(frame, *e, methods_, figure_options);
    if (!strip) return strip.error();
    strips.push_back(std::move(strip).value());
    run.objects_markdown += ObjectsMarkdown(frame.name, *e, methods_);
    if (sweep_) {
      const auto start = std::chrono::steady_clock::now();
      const int count = static_cast<int>(sweep_->Values().size());
      Expected<SweepScores> s =
          SweepFrame(frame, settings_, *sweep_, methods_, options_.score, [&](int v) {
            if (options_.on_sweep) {
              options_.on_sweep(sweep_->key, v + 1, count, util::SecondsSince(start));
            }
          });
      if (!s) return Error{"sweep " + sweep_->key + ": " + s.error().message};
      Accumulate(run.sweep, *s);
    }
  }
  const fs::path figure = fs::path("figures") / (FileStem(name) + ".png");
  std::string title = name;
  if (!description.empty()) {
    const std::size_t end = description.find_first_of(".:\n");
    title += " - " + description.substr(0, end);
  }
  if (Status s = WritePng(options_.report / figure, ComparisonFigure(title, strips)); !s) {
    return s;
  }
  run.figure = figure.generic_string();
  runs_.push_back(std::move(run));
  return Status::Ok();
}

}  // namespace cairn::eval
