// The parts of the map study (map_study.hpp) its files share:
//   map_study.cpp          the drift study, the report's assembly and the files
//   map_study_tilt.cpp     the tilt study: prior, frame-to-map refiner and gravity estimator
//   map_study_figures.cpp  the cost grid and error growth figures
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/eval/drift_run.hpp"
#include "cairn/eval/map_study.hpp"
#include "cairn/util/quantile.hpp"

namespace cairn::eval::study {

/// One drive of the drift study.
struct Row {
  std::string world, condition;
  std::uint64_t seed = 1;
  DriftRunResult result;
};

/// A world by its gallery stem (datasets/worlds/NAME.yaml) or its path in the source tree
/// (ending in .yaml).
std::string WorldFile(const MapStudyOptions& options, const std::string& name);

using util::Quantile;

/// Drives mapped side by side, counted for the progress line.
class Drives {
 public:
  Drives(const MapStudyOptions& options, int total) : options_(options), total_(total) {}
  /// Calls body(k) for every k in [0, count) on the options' threads; body returns the line
  /// that describes drive k, or an error. Fails with the first error (in k order).
  Status Run(int count, const std::function<Expected<std::string>(int)>& body);

 private:
  const MapStudyOptions& options_;
  int total_ = 0;
  int done_ = 0;
  std::mutex mutex_;
};

/// The number of drives TiltStudy maps.
int TiltStudyDrives();
/// Runs the tilt study and appends its section to `md` and its rows to `csv` (tilt.csv).
Status TiltStudy(const MapStudyOptions& options, Drives& drives, std::ostringstream& md,
                 std::ostringstream& csv);

/// The cost grid of one drive (grey: cost, red: lethal, black: unknown) with the true
/// obstacle cells outlined in green, 4 pixels per cell, x to the right and y up.
Status WriteCostFigure(const DriftRunResult& r, const std::filesystem::path& path);
/// Error against the distance driven in one world, one colour per odometry drift level.
Status WriteGrowthFigure(const std::vector<Row>& rows, const std::string& world,
                         const std::filesystem::path& path);

}  // namespace cairn::eval::study
