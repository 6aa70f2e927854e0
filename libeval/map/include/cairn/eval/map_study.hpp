// The map study (datasets/maps/REPORT.md, `cairn eval --maps`): TerrainMap on gallery worlds
// fused at true poses, at the poses of libsim's drifting odometry (0, 1 and 3 % of the
// distance, 0.5 deg / 10 m of heading per 1 %, three drives each), and with a 2 deg IMU
// roll/pitch bias on a slope with and without the tilt refiner; per world the IoU of the
// lethal cells with the true obstacle cells, the distance from each true obstacle to the
// nearest lethal cell, the false lethal cells, the elevation RMS, and how the errors grow
// with the distance driven. Then the tilt study: the odometry prior, the frame-to-map
// refiner and the gravity estimator per error source (attitude, accelerometer and gyro bias,
// mount misalignment, odometry drift) on an uphill, a hill and an open field.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/io/detect_config.hpp"

namespace cairn::eval {

struct MapStudyOptions {
  /// The source tree: the worlds are read from datasets/worlds, datasets/maps/worlds and
  /// datasets/sequences/hill_drive.
  std::filesystem::path root;
  /// The detector and the rules of every drive (config/default.yaml's; one thread each).
  od::io::DetectSettings settings;
  /// Drives mapped side by side (0: one per core). The figures do not depend on it.
  int threads = 0;
  /// The command that remakes the report, quoted in it.
  std::string command;
  /// With a folder: the gravity estimator on EuRoC V1_01 there (euroc_gravity.hpp) gets a
  /// section of the report, real data against its truth. Empty: no such section.
  std::filesystem::path euroc;
  /// Called after each drive with a line describing it (from one thread at a time); may be
  /// empty. `done` of `total` drives are mapped.
  std::function<void(const std::string& line, int done, int total)> on_drive;
};

/// Runs the study and writes REPORT.md, runs.csv (one row per drive of the drift study),
/// obstacles.csv (one row per seen obstacle per drive), tilt.csv (one row per drive of the
/// tilt study) and figures/*.png into `out` (created when missing; each file written to a
/// temporary and renamed). Fails, naming the drive or the file, on a drive that fails or a
/// file that cannot be written.
Status WriteMapStudy(const MapStudyOptions& options, const std::filesystem::path& out);

}  // namespace cairn::eval
