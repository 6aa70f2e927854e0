// cairn eval over synthetic worlds or one depth frame with truth images (eval_run.hpp): the
// sources and settings from the command line, then cairn::eval's WorldEvaluation
// (world_eval.hpp) scores them and writes the report folder.
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
#include "cairn/eval/world_eval.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/sim/world.hpp"
#include "detect.hpp"
#include "eval_run.hpp"

namespace cairn::apps::eval {
namespace {

namespace fs = std::filesystem;
namespace ev = cairn::eval;

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

  if (ev::RulesDisabled(settings.rules)) {
    std::cerr << "cairn eval: warning: every rule is disabled (the config sets them all to "
                 "0): \"+ rules\" methods equal their \"no rules\" twins\n";
  }
  ev::WorldEvalOptions options;
  options.report = o.report;
  options.command = CommandLine(o);
  options.version = CAIRN_VERSION;
  options.config = o.config;
  options.score.found_fraction = o.found_fraction;
  options.score.min_object_pixels = o.min_object_pixels;
  options.cell_width = o.cell_width;
  options.on_sweep = [](const std::string& key, int v, int count, double seconds) {
    std::cerr << "cairn eval:   sweep " << key << " " << v << "/" << count << " ("
              << Fixed(seconds, 1) << " s)" << (v == count ? "\n" : "\r") << std::flush;
  };
  ev::WorldEvaluation evaluation(std::move(options), settings, methods, sweep);
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
