// cairn eval on one LiDAR scan with real per-point labels (eval_run.hpp).
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

#include "cairn/eval/figures.hpp"
#include "cairn/eval/label_eval.hpp"
#include "cairn/eval/methods.hpp"
#include "cairn/eval/report.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/util/atomic_file.hpp"
#include "detect.hpp"
#include "eval_run.hpp"

namespace cairn::apps::eval {
namespace {

namespace fs = std::filesystem;
namespace ev = cairn::eval;

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

}  // namespace

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
    Expected<od::io::DetectSettings> loaded = LoadDetectSettingsFile(o.config);
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
  const od::OrganisedMode mode = o.organised == "yes"  ? od::OrganisedMode::kYes
                                 : o.organised == "no" ? od::OrganisedMode::kNo
                                                       : od::OrganisedMode::kAuto;
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
            << "time: " << Fixed(util::SecondsSince(start), 1) << " s\n";
  return kExitOk;
}

}  // namespace cairn::apps::eval
