// The settings file of `cairn map` (config/default.yaml documents every key) into a
// MapperConfig, plus the stereo matching of stereo sources.
//
// The file is read once; each stage's section is parsed by its own strict loader: detector,
// rules, column and stereo by od::io (detect_config.hpp), map by ParseMapConfig
// (map_config_file.hpp), and tilt and frames here:
//
//   tilt:                  # the Mapper's tilt step (tilt_step.hpp)
//     refine: false        # true: refine_to_map (RefineTilt against the fused terrain)
//     prior_sigma: 2.0     # prior on the roll and pitch corrections [deg]
//     prior_sigma_z: 0.5   # prior on the height correction [m]
//     huber: 0.05          # robust loss scale of the height residuals [m]
//     max_range: 25.0      # ground points farther away are not used [m]
//     max_points: 1500     # ground points per frame
//     min_points: 50       # fewer over known terrain: the prior is kept
//     max_iterations: 50
//   frames:                # frames that are not fused (FrameCheckConfig)
//     min_valid_points: 1  # fewer valid returns: skipped
//     max_speed: 50        # the odometry moving faster between two frames: a jump [m/s]
//     max_turn_rate: 360   # or turning faster [deg/s]
//
// An unknown section or key, a duplicate, a value of the wrong type or out of range is an
// error naming the file and the field ("config.yaml: tilt.max_points: ..."). Keys left out
// keep the defaults. An empty path gives the defaults.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cairn/map/mapper.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/stereo.hpp"

namespace cairn::map {

struct MapperSettings {
  MapperConfig mapper;
  od::StereoConfig stereo;  ///< for stereo frames (the `stereo:` section)
};

Expected<MapperSettings> LoadMapperSettings(const std::filesystem::path& path);

/// The top-level sections the Mapper's loaders read besides detection's (map, tilt, frames):
/// what a detection-only reader of the same file passes as od::io's `other_sections`.
const std::vector<std::string>& MapperSettingsSections();

/// The same from YAML text; `source` names it in error messages.
Expected<MapperSettings> ParseMapperSettings(const std::string& yaml_text,
                                             const std::string& source);

}  // namespace cairn::map
