// The `cairn` subcommands. Each lives in its own file and registers itself on the top-level
// CLI11 app: it declares its options, and hands back what to run once they are parsed.
// A run returns the process exit code and reports on stdout (results) and stderr (errors).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "cairn/od/sensor_model.hpp"

namespace cairn::apps {

/// Exit codes shared by every subcommand.
constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;    ///< bad input, unreadable file, failed write
constexpr int kExitInternal = 70;  ///< a bug: an exception escaped (EX_SOFTWARE)

/// Prints "cairn <command>: error: <message>" on stderr and gives kExitFailure.
int CommandFailure(const char* command, const std::string& message);

/// The LiDAR presets of od::SphericalModel::Preset, for the --sensor options (any case:
/// `->transform(CLI::IsMember(SensorPresets(), CLI::ignore_case))` gives the preset's name).
inline const std::vector<std::string>& SensorPresets() { return od::SphericalModel::PresetNames(); }

struct Subcommand {
  CLI::App* app = nullptr;   ///< owned by the parent app
  std::function<int()> run;  ///< called when `app` was the subcommand given
};

/// `cairn detect`: obstacles in one depth frame, written as images and JSON.
Subcommand AddDetectCommand(CLI::App& parent);
/// `cairn synth`: renders a world into frames or a rawlog sequence with ground truth.
Subcommand AddSynthCommand(CLI::App& parent);
/// `cairn eval`: scores detection methods against ground truth, writes a report.
Subcommand AddEvalCommand(CLI::App& parent);
/// `cairn info`: what a data file holds (objects, sensors, rates, time span).
Subcommand AddInfoCommand(CLI::App& parent);
/// `cairn map`: a whole sequence fused into an OctoMap and a 2.5-D cost grid.
Subcommand AddMapCommand(CLI::App& parent);
/// `cairn bench`: the detectors timed on one frame, checked against the definition; or the
/// Mapper's stages timed over a sequence.
Subcommand AddBenchCommand(CLI::App& parent);

}  // namespace cairn::apps
