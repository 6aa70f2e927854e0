// What the parts of `cairn eval` share: its options and the few helpers its runs use.
//   eval.cpp         the command line, and which run the options ask for
//   eval_worlds.cpp  synthetic worlds or one depth frame with truth images, scored and
//                    reported by cairn::eval::WorldEvaluation
//   eval_labels.cpp  one LiDAR scan with real per-point labels and a class mapping
//   eval_maps.cpp    the map study (--maps): maps of drives against their world's truth;
//                    the gravity estimator on EuRoC (--euroc)
#pragma once

#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/util/format.hpp"
#include "subcommands.hpp"

namespace cairn::apps::eval {

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
  // The map study.
  bool maps = false;
  std::filesystem::path root = ".";  ///< the source tree, where the study's worlds are
  int threads = 0;                   ///< drives mapped side by side (0: one per core)
  std::string euroc;                 ///< --euroc: the EuRoC V1_01 folder
};

inline int Fail(const std::string& message) { return CommandFailure("eval", message); }

using util::Fixed;

/// Synthetic worlds (--world, --worlds) or one depth frame with truth (--depth ...).
int RunWorldEval(const EvalOptions& o);
/// One scan with real labels (--points, --labels, --classes, --sensor).
int RunLabelEval(const EvalOptions& o);
/// The map study (--maps).
int RunMapStudy(const EvalOptions& o);
/// The gravity estimator on EuRoC V1_01 (--euroc DIR), figures printed.
int RunEurocStudy(const EvalOptions& o);

}  // namespace cairn::apps::eval
