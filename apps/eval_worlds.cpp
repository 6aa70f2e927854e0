// cairn eval over synthetic worlds or one depth frame with truth images (eval_run.hpp).
#include "eval_worlds.hpp"

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
#include "cairn/eval/methods.hpp"
#include "cairn/eval/report.hpp"
#include "cairn/eval/score.hpp"
#include "cairn/eval/sweep.hpp"
#include "cairn/eval/truth.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/sim/world.hpp"
#include "detect.hpp"

namespace cairn::apps::eval {
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

Status Evaluation::Add(const std::string& name, const std::string& description,
                       const std::string& source, const std::vector<ev::EvalFrame>& frames) {
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
                      << " (" << Fixed(util::SecondsSince(start), 1) << " s)\r" << std::flush;
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

namespace {

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

}  // namespace

int RunWorldEval(const EvalOptions& o) {
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
    Expected<od::io::DetectSettings> loaded = LoadDetectSettingsFile(o.config);
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
      std::cerr << "cairn eval:   done in " << Fixed(util::SecondsSince(world_start), 1) << " s\n";
    }
  }

  Expected<std::string> summary = evaluation.Finish();
  if (!summary) return Fail(summary.error().message);
  std::cout << *summary << "time: " << Fixed(util::SecondsSince(start), 1) << " s\n";
  return kExitOk;
}

}  // namespace cairn::apps::eval
