// The detection settings file of `cairn detect --config`: detector, rules, column baseline
// and stereo matching parameters. Degrees in the file, radians in the structs.
//
// Strict: an unknown section or key, a duplicate key, a value of the wrong type or a
// non-finite number is an error naming the file and the field, so that a typo never falls
// back silently to a default. Absent keys keep the struct defaults. An out-of-range value
// gets the stage's own Validate() message, prefixed with the file and the field.
//
//   detector:
//     min_height: 0.3        # HT [m]
//     max_height: 1.0        # Hmax [m]
//     min_slope: 45          # theta [deg]
//     search: exact          # exact | paper_window
//     window_scale: 4.5      # paper_window only [x object size]
//     region_slabs: 4        # exact only
//     threads: 0             # worker threads, 0 = every core
//     min_range: 0           # nearer returns are ignored (the vehicle itself) [m]
//   rules:                   # 0 disables a rule
//     min_points: 10         min_volume: 0.005 [m^3]   min_perimeter [m]
//     min_slope_mean [deg]   min_slope_max [deg]       min_height_mean [m]
//     min_height_max [m]     min_raised
//   column:
//     min_blob_pixels: 0     # column baseline blob-area rejection [px]
//   stereo:                  # stereo pairs only (StereoConfig in stereo.hpp)
//     min_depth [m]  num_disparities [px]  max_depth [m]  block_size [px]  p1  p2
//     uniqueness [%]  speckle_window [px]  speckle_range [px]  disp12_max_diff [px]
//     pre_filter_cap  mode (sgbm | sgbm_3way | hh | hh4)  min_texture [grey levels / px]
//     disparity_sigma [px]
// One file may also configure later stages, each reading its own sections with its own
// loader (the Mapper's: cairn/map/mapper_config_file.hpp). This library knows none of their
// keys: whoever reads such a file names the other sections (`other_sections`), e.g.
// map::MapperSettingsSections().
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::od::io {

/// Everything `--config` sets for one detection run.
struct DetectSettings {
  DetectorConfig detector;
  RuleConfig rules;
  int min_blob_pixels = 0;  ///< ColumnConfig::min_blob_pixels for the column baseline [px]
  StereoConfig stereo;      ///< semi-global matching of stereo pairs
};

/// The top-level sections this loader reads: detector, rules, column, stereo.
const std::vector<std::string>& DetectSettingsSections();

/// Reads and validates a settings file (see above). `other_sections`: the top-level
/// sections other loaders read from the same file; any section not in either is an error.
Expected<DetectSettings> LoadDetectSettings(const std::filesystem::path& path,
                                            const std::vector<std::string>& other_sections = {});

/// The same from YAML text; `source` names it in error messages.
Expected<DetectSettings> ParseDetectSettings(const std::string& yaml_text,
                                             const std::string& source,
                                             const std::vector<std::string>& other_sections = {});

/// The same from a settings file already parsed (`root`, its top level), for a loader that
/// parses the file once and hands each library its sections; `reader` names the file.
Expected<DetectSettings> ReadDetectSettings(const YAML::Node& root, const util::FieldReader& reader,
                                            const std::vector<std::string>& other_sections);

/// "exact" | "paper_window".
const char* SearchModeName(SearchMode mode);

}  // namespace cairn::od::io
