// cairn eval --maps: the map study (libeval/map, map_study.hpp) into --report, by default
// datasets/maps: REPORT.md, runs.csv, obstacles.csv, tilt.csv and figures/. Run from the
// source tree (its worlds are read from --root).
#include <iostream>

#include "cairn/eval/map_study.hpp"
#include "detect.hpp"
#include "eval_run.hpp"
#include "progress.hpp"

namespace cairn::apps::eval {

int RunMapStudy(const EvalOptions& o) {
  cairn::eval::MapStudyOptions study;
  study.root = o.root;
  Expected<od::io::DetectSettings> settings = LoadDetectSettingsFile(
      o.config.empty() ? (o.root / "config" / "default.yaml").string() : o.config);
  if (!settings) return Fail(settings.error().message);
  study.settings = std::move(*settings);
  study.settings.detector.threads = 1;  // the drives run side by side instead
  study.threads = o.threads;
  study.command =
      "cmake --build build --target cairn && build/apps/cairn eval --maps --report " + o.report;
  std::unique_ptr<Progress> progress;
  study.on_drive = [&](const std::string& line, int done, int total) {
    if (!progress)
      progress = std::make_unique<Progress>("cairn eval --maps", total, 10, 0, "drives");
    progress->Note(line);
    progress->Update(done);
  };
  if (Status st = cairn::eval::WriteMapStudy(study, o.report); !st) return Fail(st.message());
  if (progress) progress->Finish();
  std::cout << "wrote " << (std::filesystem::path(o.report) / "REPORT.md").string() << "\n";
  return 0;
}

}  // namespace cairn::apps::eval
