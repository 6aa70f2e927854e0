// One detection run as `cairn detect` makes it, for every caller that must give the same
// answer (the command, the Python module): the chosen method on a range image with the
// settings of a settings file (detect_config.hpp), the foot taken out or not, then the
// rules or none.
#pragma once

#include <string>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::od::io {

enum class DetectMethod {
  kCone,    ///< od::Detect: the cone detector
  kColumn,  ///< od::DetectColumns: the column-wise baseline (min_blob_pixels of the settings)
};

/// "cone" | "column" -> the method; anything else fails, naming the accepted names.
Expected<DetectMethod> ParseDetectMethod(const std::string& name);
/// "cone" | "column".
const char* DetectMethodName(DetectMethod method);

/// What `--method`, `--no-rules` and `--no-feet` choose.
struct DetectRunOptions {
  DetectMethod method = DetectMethod::kCone;
  bool apply_rules = true;  ///< false: every segment kept (od::KeepAll)
  bool keep_feet = true;    ///< false: od::WithoutFeet (the foot counts as ground)
};

struct DetectRun {
  Detection detection;
  Classification classification;
  double detect_s = 0.0;  ///< wall time of the detection (and the feet), not of the rules [s]
};

/// The run on one image. Fails when the settings do not validate.
Expected<DetectRun> DetectAndClassify(const RangeImage& image, const DetectSettings& settings,
                                      const DetectRunOptions& options = {});

}  // namespace cairn::od::io
