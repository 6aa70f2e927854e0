// What a rawlog holds, for `cairn info`: object counts per class, the sensors with their
// rates and data sizes, the time span, the format, the odometry.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sources/frame.hpp"

namespace cairn::sources {

enum class RawlogFormat {
  kEmpty,          ///< no object
  kObservations,   ///< a flat list of observations
  kSensoryFrames,  ///< sensory frames and action collections
  kMixed,          ///< both (unusual, but MRPT reads it)
};
/// "empty", "observations", "sensory frames (actions and observations)", "mixed".
const char* FormatName(RawlogFormat format);

/// The observations of one sensor (one label and class).
struct SensorSummary {
  std::string label;       ///< sensorLabel, may be empty
  std::string mrpt_class;  ///< without namespace
  int count = 0;
  double first_stamp_s = kNoStamp, last_stamp_s = kNoStamp;
  /// (count - 1) / (last - first) [Hz]; NaN with fewer than two stamps or none apart.
  double rate_hz = kNoStamp;
  /// Image size (3-D range scans, stereo and camera images) [px]; 0 for other kinds.
  int width = 0, height = 0;
  /// Points per scan for LiDARs and 2-D scans (returns, or rays for 2-D scans); 0 else.
  std::int64_t points_min = 0, points_max = 0;
  double points_mean = 0.0;
  int rings = 0;  ///< LiDAR rows of the decoded range image
  /// Range data that could not be decoded: the first reason (and how many failed).
  std::string problem;
  int problems = 0;
};

struct RawlogSummary {
  std::filesystem::path path;
  std::uintmax_t file_bytes = 0;
  bool gzip = false;
  RawlogFormat format = RawlogFormat::kEmpty;
  int entries = 0;  ///< top-level objects
  /// Every object by class (without namespace): top-level ones, the observations inside
  /// sensory frames and the actions inside action collections.
  std::map<std::string, int> class_counts;
  std::vector<SensorSummary> sensors;  ///< by label, then class
  double first_stamp_s = kNoStamp, last_stamp_s = kNoStamp;  ///< over observations and actions
  int odometry_poses = 0;           ///< odometry observations and integrated actions
  double odometry_path_m = 0.0;     ///< length of the odometry path [m]
};

/// Reads the whole file. Fails, naming the file and the entry, when it is not a rawlog or is
/// truncated or corrupt; range data that cannot be decoded is reported per sensor instead.
Expected<RawlogSummary> SummarizeRawlog(const std::filesystem::path& path);

}  // namespace cairn::sources
