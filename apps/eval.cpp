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
//
// Maps: TerrainMap on gallery worlds from drifting odometry, biased IMUs and each tilt mode,
// against the worlds' truth (datasets/maps/REPORT.md, from the source tree):
//   cairn eval --maps --report datasets/maps [--root DIR] [--threads N] [--config FILE]
//              [--euroc DIR]   (with a section on EuRoC V1_01)
//
// The gravity estimator on real data: EuRoC V1_01's IMU against its ground truth:
//   cairn eval --euroc DIR
#include <CLI/CLI.hpp>
#include <memory>
#include <string>

#include "eval_run.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

using eval::EvalOptions;
using eval::Fail;

int RunEval(const EvalOptions& o) {
  if (!o.euroc.empty() && !o.maps) {
    if (!o.points.empty() || !o.worlds.empty() || !o.worlds_dir.empty() || !o.depth.empty()) {
      return Fail(
          "--euroc runs on its own or with --maps (a section of its report): give no "
          "--world, --worlds, --depth or --points");
    }
    return eval::RunEurocStudy(o);
  }
  if (o.report.empty()) return Fail("--report is required");
  if (o.maps) {
    if (!o.points.empty() || !o.worlds.empty() || !o.worlds_dir.empty() || !o.depth.empty()) {
      return Fail(
          "--maps runs the map study on its own worlds: give no --world, --worlds, "
          "--depth or --points with it");
    }
    return eval::RunMapStudy(o);
  }
  if (!o.points.empty()) {
    if (!o.worlds.empty() || !o.worlds_dir.empty() || !o.depth.empty()) {
      return Fail("give worlds, one depth frame or one scan with --points, not several");
    }
    return eval::RunLabelEval(o);
  }
  return eval::RunWorldEval(o);
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
      ->transform(CLI::IsMember(SensorPresets(), CLI::ignore_case))
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
  app->add_flag("--maps", options->maps,
                "the map study instead: TerrainMap on gallery worlds under odometry drift, IMU "
                "errors and each tilt mode, scored against the worlds' truth (REPORT.md, "
                "runs.csv, obstacles.csv, tilt.csv, figures/)");
  app->add_option("--euroc", options->euroc,
                  "the gravity estimator's IMU terms on EuRoC V1_01 (the folder holding mav0/ "
                  "and ov_data/), and the up vector of the floor its stereo pairs see at rest, "
                  "against the truth; prints the figures (with --maps: a section of its report)")
      ->check(CLI::ExistingDirectory)
      ->type_name("DIR");
  app->add_option("--root", options->root,
                  "maps: the source tree holding the study's worlds (datasets/)")
      ->capture_default_str()
      ->check(CLI::ExistingDirectory)
      ->type_name("DIR");
  app->add_option("--threads", options->threads,
                  "maps: drives mapped side by side (0: one per core)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app->add_option("--config", options->config,
                  "settings YAML (detector, rules, column sections); defaults when absent")
      ->type_name("FILE.yaml");
  app->add_option("--report", options->report,
                  "report directory: REPORT.md, results.csv, figures/ (created when missing); "
                  "required but with --euroc")
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
