// The C++ objects behind the Python classes that more than one binding file uses.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cairn/map/mapper_config_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/detect_run.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "common.hpp"

namespace cairn::python {

/// cairn.Settings: one settings file as both loaders the command line uses read it
/// (`cairn detect --config`: od::io::LoadDetectSettings; `cairn map --config`:
/// map::LoadMapperSettings), or the built-in defaults.
struct Settings {
  od::io::DetectSettings detect;
  map::MapperSettings map;
  std::string path;  ///< empty: the defaults
};

/// cairn.Detection: one detection run and the range image it was made on.
struct DetectionResult {
  od::RangeImage image;
  od::Detection detection;
  od::Classification classification;
  std::vector<std::uint8_t> classes;  ///< od::ClassImage, row-major
  /// od::io::PointLabels, one per input point; empty for depth images.
  std::vector<std::uint32_t> point_labels;
  bool from_points = false;
  std::string segments_json;  ///< what segments.json holds
  std::string method;
  double detect_s = 0.0;
  /// Wall time of all the C++ work of the call (layout, image, detection, rules, labels,
  /// segments.json text), GIL released [s]: what the call costs without Python.
  double cpp_s = 0.0;
};

/// What the command line's --method, --no-rules and --no-feet choose, checked.
od::io::DetectRunOptions RunOptions(const std::string& method, bool rules, bool feet);

/// "auto" | "yes" | "no" (--organised); anything else fails.
od::OrganisedMode ParseOrganised(const std::string& text);

/// Detection (and classes, segments.json text and, for scans, point labels) on `image`.
/// Runs without the GIL; the caller must hold no Python object inside.
DetectionResult DetectOn(od::RangeImage image, const Settings& settings,
                         const od::io::DetectRunOptions& options, od::io::RunDescription run);

/// cairn.Frame: one frame of a recorded sequence (sources::SequenceFrame).
struct Frame {
  int index = 0;
  double stamp_s = 0.0;
  std::string name;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  bool tilt_from_imu = false;
  std::vector<map::ImuSample> imu;
  std::string skip;  ///< "" when used, else SourceSkipName
  std::string skip_detail;
  od::RangeImage image;
};

}  // namespace cairn::python
