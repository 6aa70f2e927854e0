// Camera intrinsics and tilt from a YAML file, for z-depth PNG frames.
//
// The file (every key required unless marked optional; any other key is an error):
//   width: 640            # [px], 1..16384, width x height at most 64 Mpx (limits.hpp)
//   height: 480           # [px], 1..16384
//   fx: 525.0             # focal lengths [px], (0, 1e6]
//   fy: 525.0
//   cx: 319.5             # principal point [px], pixel centres at integer coordinates,
//   cy: 239.5             #   in [-width, 2 width] and [-height, 2 height]
//   depth_scale: 0.0002   # metres per PNG unit (TUM: 1/5000), (0, 1]
//   up: [0.0, -0.985, -0.174]  # gravity's up vector in the optical frame (x right, y down,
//                              # z forward); need not be unit length, must not be zero
// or, instead of `up`:
//   pitch_deg: 10.0       # optical axis below the horizontal is positive [deg], [-90, 90]
//   roll_deg: 0.0         # optional, 0 when absent [deg], [-90, 90] (od::CameraUpFromPitchRoll)
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::od::io {

struct CameraIntrinsics {
  PinholeModel model;
  double depth_scale_m = 0.0;                    ///< metres per PNG unit
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< unit, optical frame
};

/// Reads and validates an intrinsics file. Errors name the file and the field.
Expected<CameraIntrinsics> LoadIntrinsics(const std::filesystem::path& path);

/// The same from YAML text; `source` names it in error messages.
Expected<CameraIntrinsics> ParseIntrinsics(const std::string& yaml_text, const std::string& source);

/// Writes an intrinsics file that LoadIntrinsics reads back to the same values (up as a
/// vector), atomically, with `comment` as its first line. Fails on an invalid model.
Status WriteIntrinsics(const std::filesystem::path& path, const CameraIntrinsics& intrinsics,
                       const std::string& comment);

}  // namespace cairn::od::io
