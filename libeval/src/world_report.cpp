// WorldEvaluation::Finish (world_eval.hpp): the report folder of a world evaluation.
#include <sstream>

#include "cairn/eval/figures.hpp"
#include "cairn/eval/report.hpp"
#include "cairn/eval/world_eval.hpp"
#include "cairn/util/atomic_file.hpp"

namespace cairn::eval {
namespace {

namespace fs = std::filesystem;

const char* Mark(bool holds) { return holds ? "yes" : "**no**"; }

}  // namespace

Expected<std::string> WorldEvaluation::Finish() {
  const fs::path dir = options_.report;
  std::vector<ResultRow> rows, totals;
  SweepScores sweep_total;
  std::vector<SweepRows> sweep_rows;
  std::vector<Score> all(methods_.size());
  std::vector<double> all_ms(methods_.size(), 0.0);
  for (const WorldRun& w : runs_) {
    for (std::size_t m = 0; m < methods_.size(); ++m) {
      const int frames = std::max(1, w.per_method[m].frames);
      rows.push_back({w.name, methods_[m], w.per_method[m], w.ms_sum[m] / frames});
      all[m] += w.per_method[m];
      all_ms[m] += w.ms_sum[m];
    }
    if (sweep_) {
      sweep_rows.push_back({w.name, w.sweep});
      Accumulate(sweep_total, w.sweep);
    }
  }
  for (std::size_t m = 0; m < methods_.size(); ++m) {
    totals.push_back({"all", methods_[m], all[m], all_ms[m] / std::max(1, all[m].frames)});
  }
  std::vector<ResultRow> csv_rows = rows;
  csv_rows.insert(csv_rows.end(), totals.begin(), totals.end());
  if (Status s = util::WriteFileAtomic(dir / "results.csv", ResultsCsv(csv_rows)); !s) {
    return s.error();
  }

  std::string pr_figure;
  if (sweep_) {
    sweep_rows.push_back({"all", sweep_total});
    if (Status s =
            util::WriteFileAtomic(dir / "sweep.csv", SweepCsv(*sweep_, methods_, sweep_rows));
        !s) {
      return s.error();
    }
    const std::string unit = SettingUnit(sweep_->key);
    std::ostringstream title;
    title << "Precision-recall over " << sweep_->key << " = " << sweep_->lo << " .. " << sweep_->hi
          << (unit.empty() ? "" : " " + unit) << ", " << runs_.size()
          << (runs_.size() == 1 ? " world" : " worlds");
    pr_figure = (fs::path("figures") / ("pr_" + sweep_->key + ".png")).generic_string();
    if (Status s = WritePng(dir / pr_figure,
                            PrecisionRecallPlot(*sweep_, methods_, sweep_total, title.str()));
        !s) {
      return s.error();
    }
  }

  // Claims.
  std::string claims_table = "| world | claim | measured | holds |\n| --- | --- | --- | --- |\n";
  std::vector<std::vector<ClaimCheck>> world_checks;
  int specific = 0, specific_holding = 0;
  for (const WorldRun& w : runs_) {
    world_checks.push_back(CheckWorld({w.name, w.description, w.per_method}, methods_));
    for (const ClaimCheck& c : world_checks.back()) {
      if (c.general) continue;
      ++specific;
      specific_holding += c.holds ? 1 : 0;
      claims_table +=
          "| " + w.name + " | " + c.claim + " | " + c.measured + " | " + Mark(c.holds) + " |\n";
    }
  }
  std::vector<ClaimCheck> gallery;
  const auto index = [&](const std::string& key) -> int {
    for (std::size_t m = 0; m < methods_.size(); ++m) {
      if (methods_[m].key == key) return static_cast<int>(m);
    }
    return -1;
  };
  const int with = index("cone_exact_rules"), without = index("cone_exact");
  if (with >= 0 && without >= 0 && runs_.size() > 1) {
    gallery = CheckGallery(all[with], all[without], methods_[with].label, methods_[without].label);
    for (const ClaimCheck& c : gallery) {
      ++specific;
      specific_holding += c.holds ? 1 : 0;
      claims_table += "| all | " + c.claim + " | " + c.measured + " | " + Mark(c.holds) + " |\n";
    }
  }

  std::ostringstream md;
  md << "# cairn evaluation report\n\n"
     << "Made by `" << options_.command << "` (cairn " << options_.version << "). Every "
     << "frame is scored against its per-pixel ground truth; the methods run on the same "
     << "frames with the same settings.\n\n"
     << SettingsMarkdown(settings_, options_.config) << "\n";
  if (RulesDisabled(settings_.rules)) {
    md << "**Every rule is disabled** (the config sets every threshold to 0): the methods "
          "\"+ rules\" equal their \"no rules\" twins here.\n\n";
  }
  md << "## Claims\n\n";
  if (specific == 0) {
    md << "No world states a claim these checks recognise; see the general checks per world "
          "below.\n\n";
  } else {
    md << specific_holding << " of " << specific << " claims hold.\n\n" << claims_table << "\n";
  }
  md << "## Scores over " << (runs_.size() == 1 ? "the frame" : "the gallery") << "\n\n"
     << ResultsMarkdown(runs_.size() == 1 ? rows : totals) << "\n"
     << ResultsLegend(options_.score) << "\n";
  if (runs_.size() > 1) md << "## Scores per world\n\n" << ResultsMarkdown(rows) << "\n";
  md << "All numbers, with the counts behind them: [results.csv](results.csv).\n\n"
     << "## Worlds\n\n";
  for (std::size_t k = 0; k < runs_.size(); ++k) {
    const WorldRun& w = runs_[k];
    md << "### " << w.name << "\n\n";
    if (!w.source.empty()) md << "Source: `" << w.source << "`.\n\n";
    if (!w.description.empty()) {
      std::string quoted = w.description;
      while (!quoted.empty() && quoted.back() == '\n') quoted.pop_back();
      std::string text = "> ";
      for (const char c : quoted) text += c == '\n' ? std::string(" ") : std::string(1, c);
      md << text << "\n\n";
    }
    bool any_specific = false, all_hold = true;
    for (const ClaimCheck& c : world_checks[k]) {
      if (c.general) continue;
      any_specific = true;
      all_hold = all_hold && c.holds;
    }
    if (any_specific) {
      md << "**Verdict: the measurements " << (all_hold ? "support" : "do not support")
         << " the world's claim.**\n\n";
    } else if (!StatedExpectation(w.description).empty()) {
      md << "The world states an expectation these checks do not recognise: judge it from "
            "the table and the figure.\n\n";
    }
    for (const ClaimCheck& c : world_checks[k]) {
      md << "- " << (c.general ? "(general) " : "") << c.claim << ": " << c.measured << " - "
         << (c.holds ? "holds" : "**does not hold**") << "\n";
    }
    md << "\n![" << w.name << "](" << w.figure << ")\n\n";
    if (!w.objects_markdown.empty()) {
      md << "<details><summary>Objects</summary>\n\n" << w.objects_markdown << "</details>\n\n";
    }
  }
  if (sweep_) {
    md << "## Sweep: " << sweep_->key << "\n\n"
       << "Every method at " << sweep_->count << " values of `" << sweep_->key
       << "`, the other settings as above, summed over all frames. Per-point precision "
          "without the foot band against per-point recall; each cell: precision / recall / "
          "objects found / false obstacles. Per world: [sweep.csv](sweep.csv).\n\n"
       << "![precision-recall](" << pr_figure << ")\n\n"
       << SweepMarkdown(*sweep_, methods_, sweep_total) << "\n";
  }
  if (Status s = util::WriteFileAtomic(dir / "REPORT.md", md.str()); !s) return s.error();

  std::ostringstream summary;
  summary << ResultsMarkdown(totals);
  if (specific > 0) summary << "claims: " << specific_holding << " of " << specific << " hold\n";
  summary << "wrote: " << (dir / "REPORT.md").string() << "\n"
          << "       " << (dir / "results.csv").string() << "\n";
  if (sweep_) summary << "       " << (dir / "sweep.csv").string() << "\n";
  summary << "       " << (dir / "figures").string() << "/ (" << runs_.size()
          << (sweep_ ? " comparison figures, 1 precision-recall curve)\n"
                     : " comparison figures)\n");
  return summary.str();
}

}  // namespace cairn::eval
