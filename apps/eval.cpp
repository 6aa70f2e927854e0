// cairn eval: scores detection methods against ground truth, side by side, and writes a
// report folder:
//   REPORT.md        settings, the table of scores per world and method, what each world
//                    claims and whether the measurements support it, figures, the sweep
//   results.csv      every score per world and method, and over the whole gallery ("all")
//   figures/         WORLD.png (truth and every method side by side, per view),
//                    pr_KEY.png (precision-recall curve of a sweep)
//   sweep.csv        (with --sweep) scores per world, value and method
//
//   cairn eval --worlds DIR | --world W.yaml [--world ...]  --report DIR
//   cairn eval --depth D.png --intrinsics I.yaml --truth T.png --truth-yaml T.yaml --report DIR
//   ... [--config FILE] [--sweep NAME=LO:HI:N] [--methods LIST]
//
// Real labels: one LiDAR scan with SemanticKITTI-style per-point labels and a class mapping
// (which classes are obstacles, ground, ignored); writes REPORT.md, results.csv and
// figures/range_image.png, figures/birds_eye.png:
//   cairn eval --points S.bin --labels S.label --classes C.yaml --sensor PRESET --report DIR
//       [--config FILE] [--methods LIST] [--notes NOTES.md]
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/util/atomic_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/sim/eval/figures.hpp"
#include "cairn/sim/eval/label_eval.hpp"
#include "cairn/sim/eval/methods.hpp"
#include "cairn/sim/eval/report.hpp"
#include "cairn/sim/eval/score.hpp"
#include "cairn/sim/eval/sweep.hpp"
#include "cairn/sim/eval/truth.hpp"
#include "cairn/sim/world.hpp"
#include "detect.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
namespace ev = sim::eval;
using Clock = std::chrono::steady_clock;

struct EvalOptions {
  std::vector<std::string> worlds;
  std::string worlds_dir;
  std::string depth, intrinsics, truth, truth_yaml;
  // One LiDAR scan with real labels.
  std::string points, labels, classes, sensor, notes;
  std::string organised = "auto";
  int columns = 0;  ///< azimuth steps of an unorganised scan; 0: the sensor's default
  std::string up = "0,0,1";
  std::string config;
  std::string report;
  std::string sweep;
  std::string methods;
  double found_fraction = 0.5;
  int min_object_pixels = 20;
  int cell_width = 320;
};

int Fail(const std::string& message) {
  std::cerr << "cairn eval: error: " << message << "\n";
  return kExitFailure;
}

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string Fixed(double v, int decimals) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(decimals) << v;
  return out.str();
}

/// A file name made from a world or frame name.
std::string FileStem(std::string name) {
  for (char& c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_')) c = '_';
  }
  return name.empty() ? "frame" : name;
}

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
bool RulesDisabled(const od::RuleConfig& r) {
  return r.min_points == 0 && r.min_volume_m3 == 0.0 && r.min_perimeter_m == 0.0 &&
         r.min_slope_mean_rad == 0.0 && r.min_slope_max_rad == 0.0 && r.min_height_mean_m == 0.0 &&
         r.min_height_max_m == 0.0 && r.min_raised == 0;
}

std::string CommandLine(const EvalOptions& o) {
  std::string cmd = "cairn eval";
  if (!o.worlds_dir.empty()) cmd += " --worlds " + o.worlds_dir;
  for (const std::string& w : o.worlds) cmd += " --world " + w;
  if (!o.depth.empty()) {
    cmd += " --depth " + o.depth + " --intrinsics " + o.intrinsics + " --truth " + o.truth +
           " --truth-yaml " + o.truth_yaml;
  }
  if (!o.config.empty()) cmd += " --config " + o.config;
  if (!o.methods.empty()) cmd += " --methods " + o.methods;
  if (!o.sweep.empty()) cmd += " --sweep " + o.sweep;
  const EvalOptions defaults;
  if (o.found_fraction != defaults.found_fraction) {
    std::ostringstream v;
    v << o.found_fraction;
    cmd += " --found-fraction " + v.str();
  }
  if (o.min_object_pixels != defaults.min_object_pixels) {
    cmd += " --min-object-pixels " + std::to_string(o.min_object_pixels);
  }
  if (o.cell_width != defaults.cell_width) cmd += " --cell-width " + std::to_string(o.cell_width);
  cmd += " --report " + o.report;
  return cmd;
}

const char* Mark(bool holds) { return holds ? "yes" : "**no**"; }

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
             const std::vector<ev::EvalFrame>& frames) {
    WorldRun run;
    run.name = name;
    run.description = description;
    run.source = source;
    run.per_method.assign(methods_.size(), ev::Score{});
    run.ms_sum.assign(methods_.size(), 0.0);
    std::vector<od::io::RgbImage> strips;
    for (const ev::EvalFrame& frame : frames) {
      Expected<ev::FrameEvaluation> e =
          ev::EvaluateFrame(frame, settings_, methods_, score_options_);
      if (!e) return e.error();
      for (std::size_t m = 0; m < methods_.size(); ++m) {
        run.per_method[m] += e->scores[m].score;
        run.ms_sum[m] += e->runs[m].detect_ms;
      }
      ev::FigureOptions figure_options;
      figure_options.cell_width = options_.cell_width;
      Expected<od::io::RgbImage> strip = ev::ComparisonStrip(frame, *e, methods_, figure_options);
      if (!strip) return strip.error();
      strips.push_back(std::move(strip).value());
      run.objects_markdown += ev::ObjectsMarkdown(frame.name, *e, methods_);
      if (sweep_) {
        const Clock::time_point start = Clock::now();
        const int count = static_cast<int>(sweep_->Values().size());
        Expected<ev::SweepScores> s =
            ev::SweepFrame(frame, settings_, *sweep_, methods_, score_options_, [&](int v) {
              std::cerr << "cairn eval:   sweep " << sweep_->key << " " << v + 1 << "/" << count
                        << " (" << Fixed(SecondsSince(start), 1) << " s)\r" << std::flush;
            });
        std::cerr << "\n";
        if (!s) return Error{"--sweep " + options_.sweep + ": " + s.error().message};
        ev::Accumulate(run.sweep, *s);
      }
    }
    const fs::path figure = fs::path("figures") / (FileStem(name) + ".png");
    std::string title = name;
    if (!description.empty()) {
      const std::size_t end = description.find_first_of(".:\n");
      title += " - " + description.substr(0, end);
    }
    if (Status s =
            ev::WritePng(fs::path(options_.report) / figure, ev::ComparisonFigure(title, strips));
        !s) {
      return s;
    }
    run.figure = figure.generic_string();
    runs_.push_back(std::move(run));
    return Status::Ok();
  }

  /// Writes REPORT.md, results.csv, and the sweep's files; returns the summary to print.
  Expected<std::string> Finish() {
    const fs::path dir = options_.report;
    std::vector<ev::ResultRow> rows, totals;
    ev::SweepScores sweep_total;
    std::vector<ev::SweepRows> sweep_rows;
    std::vector<ev::Score> all(methods_.size());
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
        ev::Accumulate(sweep_total, w.sweep);
      }
    }
    for (std::size_t m = 0; m < methods_.size(); ++m) {
      totals.push_back({"all", methods_[m], all[m], all_ms[m] / std::max(1, all[m].frames)});
    }
    std::vector<ev::ResultRow> csv_rows = rows;
    csv_rows.insert(csv_rows.end(), totals.begin(), totals.end());
    if (Status s = util::WriteFileAtomic(dir / "results.csv", ev::ResultsCsv(csv_rows)); !s) {
      return s.error();
    }

    std::string pr_figure;
    if (sweep_) {
      sweep_rows.push_back({"all", sweep_total});
      if (Status s = util::WriteFileAtomic(dir / "sweep.csv",
                                             ev::SweepCsv(*sweep_, methods_, sweep_rows));
          !s) {
        return s.error();
      }
      const std::string unit = ev::SettingUnit(sweep_->key);
      std::ostringstream title;
      title << "Precision-recall over " << sweep_->key << " = " << sweep_->lo << " .. "
            << sweep_->hi << (unit.empty() ? "" : " " + unit) << ", " << runs_.size()
            << (runs_.size() == 1 ? " world" : " worlds");
      pr_figure = (fs::path("figures") / ("pr_" + sweep_->key + ".png")).generic_string();
      if (Status s =
              ev::WritePng(dir / pr_figure,
                           ev::PrecisionRecallPlot(*sweep_, methods_, sweep_total, title.str()));
          !s) {
        return s.error();
      }
    }

    // Claims.
    std::string claims_table = "| world | claim | measured | holds |\n| --- | --- | --- | --- |\n";
    std::vector<std::vector<ev::ClaimCheck>> world_checks;
    int specific = 0, specific_holding = 0;
    for (const WorldRun& w : runs_) {
      world_checks.push_back(ev::CheckWorld({w.name, w.description, w.per_method}, methods_));
      for (const ev::ClaimCheck& c : world_checks.back()) {
        if (c.general) continue;
        ++specific;
        specific_holding += c.holds ? 1 : 0;
        claims_table +=
            "| " + w.name + " | " + c.claim + " | " + c.measured + " | " + Mark(c.holds) + " |\n";
      }
    }
    std::vector<ev::ClaimCheck> gallery;
    const auto index = [&](const std::string& key) -> int {
      for (std::size_t m = 0; m < methods_.size(); ++m) {
        if (methods_[m].key == key) return static_cast<int>(m);
      }
      return -1;
    };
    const int with = index("cone_exact_rules"), without = index("cone_exact");
    if (with >= 0 && without >= 0 && runs_.size() > 1) {
      gallery =
          ev::CheckGallery(all[with], all[without], methods_[with].label, methods_[without].label);
      for (const ev::ClaimCheck& c : gallery) {
        ++specific;
        specific_holding += c.holds ? 1 : 0;
        claims_table += "| all | " + c.claim + " | " + c.measured + " | " + Mark(c.holds) + " |\n";
      }
    }

    std::ostringstream md;
    md << "# cairn evaluation report\n\n"
       << "Made by `" << CommandLine(options_) << "` (cairn " << CAIRN_VERSION << "). Every "
       << "frame is scored against its per-pixel ground truth; the methods run on the same "
       << "frames with the same settings.\n\n"
       << ev::SettingsMarkdown(settings_, options_.config) << "\n";
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
       << ev::ResultsMarkdown(runs_.size() == 1 ? rows : totals) << "\n"
       << ev::ResultsLegend(score_options_) << "\n";
    if (runs_.size() > 1) md << "## Scores per world\n\n" << ev::ResultsMarkdown(rows) << "\n";
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
      for (const ev::ClaimCheck& c : world_checks[k]) {
        if (c.general) continue;
        any_specific = true;
        all_hold = all_hold && c.holds;
      }
      if (any_specific) {
        md << "**Verdict: the measurements " << (all_hold ? "support" : "do not support")
           << " the world's claim.**\n\n";
      } else if (!ev::StatedExpectation(w.description).empty()) {
        md << "The world states an expectation these checks do not recognise: judge it from "
              "the table and the figure.\n\n";
      }
      for (const ev::ClaimCheck& c : world_checks[k]) {
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
         << ev::SweepMarkdown(*sweep_, methods_, sweep_total) << "\n";
    }
    if (Status s = util::WriteFileAtomic(dir / "REPORT.md", md.str()); !s) return s.error();

    std::ostringstream summary;
    summary << ev::ResultsMarkdown(totals);
    if (specific > 0) summary << "claims: " << specific_holding << " of " << specific << " hold\n";
    summary << "wrote: " << (dir / "REPORT.md").string() << "\n"
            << "       " << (dir / "results.csv").string() << "\n";
    if (sweep_) summary << "       " << (dir / "sweep.csv").string() << "\n";
    summary << "       " << (dir / "figures").string() << "/ (" << runs_.size()
            << (sweep_ ? " comparison figures, 1 precision-recall curve)\n"
                       : " comparison figures)\n");
    return summary.str();
  }

 private:
  const EvalOptions& options_;
  od::io::DetectSettings settings_;
  std::vector<ev::Method> methods_;
  std::optional<ev::SweepSpec> sweep_;
  ev::ScoreOptions score_options_;
  std::vector<WorldRun> runs_;
};

/// World files named by --world and found in --worlds (sorted), or an error naming the path.
Expected<std::vector<std::string>> WorldFiles(const EvalOptions& o) {
  std::vector<std::string> files = o.worlds;
  if (!o.worlds_dir.empty()) {
    std::error_code ec;
    if (!fs::is_directory(o.worlds_dir, ec)) {
      return Error{o.worlds_dir + ": --worlds: not a directory"};
    }
    std::vector<std::string> found;
    for (const auto& entry : fs::directory_iterator(o.worlds_dir, ec)) {
      if (entry.is_regular_file() && entry.path().extension() == ".yaml") {
        found.push_back(entry.path().string());
      }
    }
    if (ec) return Error{o.worlds_dir + ": --worlds: " + ec.message()};
    if (found.empty()) return Error{o.worlds_dir + ": --worlds: no world files (*.yaml) in it"};
    std::sort(found.begin(), found.end());
    files.insert(files.end(), found.begin(), found.end());
  }
  return files;
}

// ---------------------------------------------------------------------------------------
// Real labels: one scan, its .label file and a class mapping.

/// Azimuth steps of an unorganised scan when --columns is not given (as `cairn detect`).
int DefaultColumns(const std::string& sensor) {
  if (sensor == "VLP-16" || sensor == "VLP-32C") return 1800;  // 0.2 deg
  return 2048;                                                 // HDL-64E, OS1-64
}

/// The methods of a labels run when --methods is not given: the cone detector and the column
/// baseline, both with the rules.
const char* kLabelMethods = "cone_exact_rules,column_rules";

std::string LabelCommandLine(const EvalOptions& o) {
  std::string cmd = "cairn eval --points " + o.points + " \\\n    --labels " + o.labels +
                    " \\\n    --classes " + o.classes + " --sensor " + o.sensor;
  const EvalOptions defaults;
  if (o.organised != defaults.organised) cmd += " --organised " + o.organised;
  if (o.columns != defaults.columns) cmd += " --columns " + std::to_string(o.columns);
  if (o.up != defaults.up) cmd += " --up " + o.up;
  if (!o.config.empty()) cmd += " \\\n    --config " + o.config;
  if (!o.methods.empty()) cmd += " \\\n    --methods " + o.methods;
  if (!o.notes.empty()) cmd += " --notes " + o.notes;
  cmd += " \\\n    --report " + o.report;
  return cmd;
}

Expected<std::string> ReadText(const std::string& path, const char* flag) {
  std::ifstream in(path);
  if (!in) return Error{path + ": " + flag + ": cannot open for reading"};
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Error{path + ": " + flag + ": read failed"};
  return text.str();
}

/// "tree (4), pole (5)": the classes of one role.
std::string ClassesWithRole(const ev::ClassMap& map, ev::ClassRole role) {
  std::string out;
  for (const ev::LabelClass& c : map.classes) {
    if (c.role == role)
      out += (out.empty() ? "" : ", ") + c.name + " (" + std::to_string(c.id) + ")";
  }
  return out.empty() ? "none" : out;
}

int RunLabelEval(const EvalOptions& o) {
  const Clock::time_point start = Clock::now();
  for (const auto& [value, flag] :
       {std::pair{o.labels, "--labels"}, {o.classes, "--classes"}, {o.sensor, "--sensor"}}) {
    if (value.empty()) return Fail(std::string(flag) + " is required with --points");
  }
  if (!o.sweep.empty()) {
    return Fail("--sweep is for synthetic worlds and depth frames, not with --points");
  }
  od::io::DetectSettings settings;
  std::string config_text;
  if (!o.config.empty()) {
    Expected<od::io::DetectSettings> loaded = od::io::LoadDetectSettings(o.config);
    if (!loaded) return Fail(loaded.error().message);
    settings = *loaded;
    Expected<std::string> text = ReadText(o.config, "--config");
    if (!text) return Fail(text.error().message);
    config_text = *text;
  }
  Expected<std::vector<ev::Method>> methods =
      ev::SelectMethods(o.methods.empty() ? kLabelMethods : o.methods);
  if (!methods) return Fail("--methods: " + methods.error().message);
  std::string notes;
  if (!o.notes.empty()) {
    Expected<std::string> text = ReadText(o.notes, "--notes");
    if (!text) return Fail(text.error().message);
    notes = *text;
  }
  Expected<ev::ClassMap> map = ev::LoadClassMap(o.classes);
  if (!map) return Fail(map.error().message);
  Expected<Eigen::Vector3d> up = ParseUpVector(o.up);
  if (!up) return Fail(up.error().message);
  const int columns = o.columns > 0 ? o.columns : DefaultColumns(o.sensor);
  Expected<od::SphericalModel> preset = od::SphericalModel::Preset(o.sensor, columns);
  if (!preset) return Fail("--sensor: " + preset.error().message);
  const od::io::OrganisedMode mode = o.organised == "yes"  ? od::io::OrganisedMode::kYes
                                     : o.organised == "no" ? od::io::OrganisedMode::kNo
                                                           : od::io::OrganisedMode::kAuto;
  Expected<ev::LabelFrame> frame = ev::LoadLabelFrame(o.points, o.labels, *preset, mode, *up);
  if (!frame) return Fail(frame.error().message);
  const od::RangeImage& image = frame->image;
  std::int64_t returns = 0;
  for (const std::int32_t cell : image.cell_of_point()) returns += cell >= 0 ? 1 : 0;
  std::cerr << "cairn eval: " << o.points << ": " << frame->points.size() << " points ("
            << (frame->organised ? "organised" : "unorganised") << ", range image "
            << image.height() << "x" << image.width() << ", " << returns << " returns)\n";

  Expected<std::vector<ev::LabelMethodResult>> results =
      ev::EvaluateLabels(*frame, *map, settings, *methods);
  if (!results) return Fail(results.error().message);

  const fs::path dir = o.report;
  std::error_code ec;
  fs::create_directories(dir / "figures", ec);
  if (ec) return Fail(o.report + ": --report: cannot create the directory: " + ec.message());
  const ev::LabelFigureOptions figure_options;
  Expected<od::io::RgbImage> range_figure =
      ev::LabelRangeFigure(*frame, *map, *methods, *results, figure_options);
  if (!range_figure) return Fail(range_figure.error().message);
  Expected<od::io::RgbImage> birds_eye =
      ev::LabelBirdsEyeFigure(*frame, *map, *methods, *results, figure_options);
  if (!birds_eye) return Fail(birds_eye.error().message);
  const std::string range_png = "figures/range_image.png", birds_eye_png = "figures/birds_eye.png";
  if (Status s = ev::WritePng(dir / range_png, *range_figure); !s) return Fail(s.message());
  if (Status s = ev::WritePng(dir / birds_eye_png, *birds_eye); !s) return Fail(s.message());
  if (Status s = util::WriteFileAtomic(dir / "results.csv",
                                         ev::LabelResultsCsv(*map, *methods, *results));
      !s) {
    return Fail(s.message());
  }

  const std::string dataset = map->dataset.empty() ? "" : map->dataset + " ";
  const std::string results_table = ev::LabelResultsMarkdown(*methods, *results);
  std::ostringstream md;
  md << "# " << dataset << "scan " << frame->name
     << ": obstacle points found by the cone detector and the column baseline\n\n"
     << "Made with cairn " << CAIRN_VERSION << " by this command (paths as given to it):\n\n```sh\n"
     << LabelCommandLine(o) << "\n```\n\n"
     << "Data: `" << o.points << "`, " << frame->points.size() << " points, "
     << (frame->organised ? "organised (index = col * " + std::to_string(image.height()) +
                                " + ring: every point has its own cell)"
                          : std::string("unorganised (cells from the sensor preset's rings "
                                        "and azimuth steps)"))
     << "; range image " << image.height() << " rings x " << image.width() << " columns, "
     << returns << " points with a return. Truth: `" << o.labels
     << "` (class id = lower 16 bits of each entry), classes as `" << o.classes << "`.\n\n"
     << "Every method runs on this one range image with the same settings and, where it "
        "applies them, the same rules. Each point takes the result of its range-image cell.\n\n"
     << "## Scores\n\n"
     << "Per point, over the points with a return whose true class is not ignored. A point is "
        "*detected* when its cell lies in a kept segment (segments the rules reject count as "
        "not detected). TP: detected obstacle point; FP: detected ground point; FN: obstacle "
        "point not detected; TN: ground point not detected. Precision TP / (TP + FP), recall "
        "TP / (TP + FN), F1 2TP / (2TP + FP + FN), IoU TP / (TP + FP + FN). *Ignored*: returns "
        "of ignored classes; *no return*: points without a return (left out whatever their "
        "label).\n\n"
     << results_table << "\n"
     << "Every count per method and class: [results.csv](results.csv).\n\n"
     << "## Per true class\n\n"
     << "Share of each class's returns that are detected (count in brackets).\n\n"
     << ev::LabelClassesMarkdown(*map, *methods, *results) << "\n"
     << "## Where the errors are\n\n"
     << "False positives by true class (ground classes) and false negatives by true class "
        "(obstacle classes), largest first, with their share of the method's total.\n\n"
     << ev::LabelErrorsMarkdown(*map, *methods, *results) << "\n"
     << "## Figures\n\n"
     << "The range image, coloured by true class, then by each method's outcome:\n\n"
     << "![range image by true class and by outcome](" << range_png << ")\n\n"
     << "The same points from above (level frame, x forward up the image):\n\n"
     << "![bird's-eye view by true class and by outcome](" << birds_eye_png << ")\n\n"
     << "## Parameters\n\n"
     << "- Sensor preset `" << o.sensor << "`"
     << (frame->organised ? " (rings; columns from the organised layout)"
                          : " (" + std::to_string(columns) + " azimuth steps)")
     << ", layout `--organised " << o.organised << "`, gravity's up vector `" << o.up
     << "` in the sensor frame.\n"
     << "- " << ev::SettingsMarkdown(settings, o.config) << "- Class mapping `" << o.classes << "`"
     << (map->dataset.empty() ? "" : " (" + map->dataset + ")")
     << ": obstacle: " << ClassesWithRole(*map, ev::ClassRole::kObstacle)
     << "; ground: " << ClassesWithRole(*map, ev::ClassRole::kGround)
     << "; ignored: " << ClassesWithRole(*map, ev::ClassRole::kIgnored)
     << ". The file gives the reason for each choice.\n\n";
  if (!config_text.empty()) {
    while (!config_text.empty() && config_text.back() == '\n') config_text.pop_back();
    md << "<details><summary><code>" << o.config << "</code></summary>\n\n```yaml\n"
       << config_text << "\n```\n\n</details>\n\n";
  }
  if (!notes.empty()) {
    while (!notes.empty() && notes.back() == '\n') notes.pop_back();
    md << "## Notes\n\n" << notes << "\n";
  }
  if (Status s = util::WriteFileAtomic(dir / "REPORT.md", md.str()); !s) return Fail(s.message());

  std::cout << results_table << "wrote: " << (dir / "REPORT.md").string() << "\n"
            << "       " << (dir / "results.csv").string() << "\n"
            << "       " << (dir / range_png).string() << "\n"
            << "       " << (dir / birds_eye_png).string() << "\n"
            << "time: " << Fixed(SecondsSince(start), 1) << " s\n";
  return kExitOk;
}

int RunEval(const EvalOptions& o) {
  if (!o.points.empty()) {
    if (!o.worlds.empty() || !o.worlds_dir.empty() || !o.depth.empty()) {
      return Fail("give worlds, one depth frame or one scan with --points, not several");
    }
    return RunLabelEval(o);
  }
  for (const auto& [value, flag] : {std::pair{o.labels, "--labels"},
                                    {o.classes, "--classes"},
                                    {o.sensor, "--sensor"},
                                    {o.notes, "--notes"}}) {
    if (!value.empty()) return Fail(std::string(flag) + " needs --points");
  }
  const Clock::time_point start = Clock::now();
  const bool frame_mode =
      !o.depth.empty() || !o.intrinsics.empty() || !o.truth.empty() || !o.truth_yaml.empty();
  const bool world_mode = !o.worlds.empty() || !o.worlds_dir.empty();
  if (frame_mode == world_mode) {
    return Fail(
        "give worlds (--world FILE.yaml ... or --worlds DIR) or one frame (--depth, "
        "--intrinsics, --truth, --truth-yaml), not both or neither");
  }
  if (frame_mode) {
    for (const auto& [value, flag] : {std::pair{o.depth, "--depth"},
                                      {o.intrinsics, "--intrinsics"},
                                      {o.truth, "--truth"},
                                      {o.truth_yaml, "--truth-yaml"}}) {
      if (value.empty()) return Fail(std::string(flag) + " is required with a single frame");
    }
  }

  od::io::DetectSettings settings;
  if (!o.config.empty()) {
    Expected<od::io::DetectSettings> loaded = od::io::LoadDetectSettings(o.config);
    if (!loaded) return Fail(loaded.error().message);
    settings = *loaded;
  }
  std::vector<ev::Method> methods = ev::StandardMethods();
  if (!o.methods.empty()) {
    Expected<std::vector<ev::Method>> chosen = ev::SelectMethods(o.methods);
    if (!chosen) return Fail("--methods: " + chosen.error().message);
    methods = *chosen;
  }
  std::optional<ev::SweepSpec> sweep;
  if (!o.sweep.empty()) {
    Expected<ev::SweepSpec> parsed = ev::ParseSweep(o.sweep);
    if (!parsed) return Fail("--sweep: " + parsed.error().message);
    for (const double v : parsed->Values()) {
      od::io::DetectSettings trial = settings;
      if (Status s = ev::ApplySetting(trial, parsed->key, v); !s) {
        return Fail("--sweep " + o.sweep + ": " + s.message());
      }
    }
    sweep = *parsed;
  }

  if (RulesDisabled(settings.rules)) {
    std::cerr << "cairn eval: warning: every rule is disabled (the config sets them all to "
                 "0): \"+ rules\" methods equal their \"no rules\" twins\n";
  }
  Evaluation evaluation(o, settings, methods, sweep);
  if (Status s = evaluation.Validate(); !s) {
    // The message starts with the field: name it as the flag that sets it.
    std::string message = s.message();
    const std::size_t end = message.find(' ');
    for (std::size_t i = 0; i < end && i < message.size(); ++i) {
      if (message[i] == '_') message[i] = '-';
    }
    return Fail("--" + message);
  }
  std::error_code ec;
  fs::create_directories(fs::path(o.report) / "figures", ec);
  if (ec) return Fail(o.report + ": --report: cannot create the directory: " + ec.message());

  if (frame_mode) {
    Expected<ev::EvalFrame> frame = ev::LoadFrame(o.depth, o.intrinsics, o.truth, o.truth_yaml);
    if (!frame) return Fail(frame.error().message);
    std::cerr << "cairn eval: " << frame->name << " (" << frame->truth.width << "x"
              << frame->truth.height << " px)\n";
    const std::string name = frame->name;
    if (Status s = evaluation.Add(name, "", o.depth, {std::move(frame).value()}); !s) {
      return Fail(s.message());
    }
  } else {
    Expected<std::vector<std::string>> files = WorldFiles(o);
    if (!files) return Fail(files.error().message);
    const int count = static_cast<int>(files->size());
    for (int k = 0; k < count; ++k) {
      const std::string& path = (*files)[k];
      const Clock::time_point world_start = Clock::now();
      Expected<sim::World> world = sim::LoadWorld(path);
      if (!world) return Fail(world.error().message);
      std::cerr << "cairn eval: [" << k + 1 << "/" << count << "] " << world->name << ": "
                << world->views.size() << (world->views.size() == 1 ? " view" : " views") << "\n";
      std::vector<ev::EvalFrame> frames;
      for (int v = 0; v < static_cast<int>(world->views.size()); ++v) {
        Expected<sim::DepthFrame> rendered = sim::RenderView(*world, v);
        if (!rendered)
          return Fail(path + ": views[" + std::to_string(v) + "]: " + rendered.error().message);
        const std::string name =
            world->views.size() == 1 ? world->name : world->name + "/view" + std::to_string(v);
        Expected<ev::EvalFrame> frame = ev::FrameFromRender(name, *rendered, world->scene);
        if (!frame) return Fail(path + ": " + frame.error().message);
        frames.push_back(std::move(frame).value());
      }
      if (Status s = evaluation.Add(world->name, world->description, path, frames); !s) {
        return Fail(path + ": " + s.message());
      }
      std::cerr << "cairn eval:   done in " << Fixed(SecondsSince(world_start), 1) << " s\n";
    }
  }

  Expected<std::string> summary = evaluation.Finish();
  if (!summary) return Fail(summary.error().message);
  std::cout << *summary << "time: " << Fixed(SecondsSince(start), 1) << " s\n";
  return kExitOk;
}

}  // namespace

Subcommand AddEvalCommand(CLI::App& parent) {
  auto options = std::make_shared<EvalOptions>();
  CLI::App* app = parent.add_subcommand(
      "eval",
      "Score the detection methods (cone exact / paper window, column baseline, with and "
      "without rules) against ground truth (synthetic worlds, a depth frame with its truth, or "
      "a LiDAR scan with per-point labels) and write a report with tables and figures");
  app->add_option("--world", options->worlds, "a world file (repeatable)")->type_name("FILE.yaml");
  app->add_option("--worlds", options->worlds_dir, "every *.yaml world file in a directory")
      ->type_name("DIR");
  app->add_option("--depth", options->depth, "single frame: 16-bit z-depth PNG")
      ->type_name("FILE.png");
  app->add_option("--intrinsics", options->intrinsics, "single frame: camera YAML")
      ->type_name("FILE.yaml");
  app->add_option("--truth", options->truth,
                  "single frame: object id per pixel (0 terrain, 255 or 65535 no return)")
      ->type_name("FILE.png");
  app->add_option("--truth-yaml", options->truth_yaml,
                  "single frame: the objects (id, name, is_obstacle)")
      ->type_name("FILE.yaml");
  app->add_option("--points", options->points,
                  "real labels: a LiDAR scan, KITTI layout (float32 x, y, z, intensity)")
      ->type_name("FILE.bin");
  app->add_option("--labels", options->labels,
                  "real labels: its SemanticKITTI-style .label (uint32 per point, class id in "
                  "the lower 16 bits)")
      ->type_name("FILE.label");
  app->add_option("--classes", options->classes,
                  "real labels: class mapping YAML (id: {name, role: obstacle | ground | "
                  "ignored, color}), e.g. config/classes/rellis3d.yaml")
      ->type_name("FILE.yaml");
  app->add_option("--sensor", options->sensor, "real labels: sensor preset of the scan")
      ->check(CLI::IsMember({"HDL-64E", "VLP-16", "VLP-32C", "OS1-64"}))
      ->type_name("PRESET");
  app->add_option("--organised", options->organised,
                  "real labels: auto: organised (index = col * rings + ring) when the data says "
                  "so; yes / no to force")
      ->check(CLI::IsMember({"auto", "yes", "no"}))
      ->capture_default_str();
  app->add_option("--columns", options->columns,
                  "real labels: azimuth steps of an unorganised scan (default: 1800 for "
                  "VLP-16/VLP-32C, 2048 otherwise)")
      ->check(CLI::PositiveNumber);
  app->add_option("--up", options->up, "real labels: gravity's up vector in the LiDAR frame")
      ->capture_default_str()
      ->type_name("X,Y,Z");
  app->add_option("--notes", options->notes,
                  "real labels: Markdown included in REPORT.md under Notes (a person's reading)")
      ->type_name("FILE.md");
  app->add_option("--config", options->config,
                  "settings YAML (detector, rules, column sections); defaults when absent")
      ->type_name("FILE.yaml");
  app->add_option("--report", options->report,
                  "report directory: REPORT.md, results.csv, figures/ (created when missing)")
      ->required()
      ->type_name("DIR");
  app->add_option("--sweep", options->sweep,
                  "also step one setting (file units: m, deg, m^3): min_height, max_height, "
                  "min_slope, window_scale, min_blob_pixels or a rules key; draws the "
                  "precision-recall curve")
      ->type_name("NAME=LO:HI:N");
  app->add_option("--methods", options->methods,
                  "comma-separated subset of cone_exact_rules, cone_exact, cone_window_rules, "
                  "column_rules, column (default: all; with --points: cone_exact_rules,"
                  "column_rules)")
      ->type_name("LIST");
  app->add_option("--found-fraction", options->found_fraction,
                  "share of an obstacle's pixels that must be detected to find it")
      ->capture_default_str();
  app->add_option("--min-object-pixels", options->min_object_pixels,
                  "objects seen by fewer pixels are not counted")
      ->capture_default_str();
  app->add_option("--cell-width", options->cell_width, "width of each figure cell [px]")
      ->capture_default_str();
  return {app, [options] { return RunEval(*options); }};
}

}  // namespace cairn::apps
