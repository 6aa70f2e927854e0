#include "cairn/od/io/detect_run.hpp"

#include <chrono>
#include <utility>

#include "cairn/od/column_detector.hpp"

namespace cairn::od::io {

Expected<DetectMethod> ParseDetectMethod(const std::string& name) {
  if (name == "cone") return DetectMethod::kCone;
  if (name == "column") return DetectMethod::kColumn;
  return Error{"method: expected cone or column, got '" + name + "'"};
}

const char* DetectMethodName(DetectMethod method) {
  return method == DetectMethod::kColumn ? "column" : "cone";
}

Expected<DetectRun> DetectAndClassify(const RangeImage& image, const DetectSettings& settings,
                                      const DetectRunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  Expected<Detection> detection = Error{"no method"};
  if (options.method == DetectMethod::kColumn) {
    ColumnConfig column = ColumnConfig::From(settings.detector);
    column.min_blob_pixels = settings.min_blob_pixels;
    detection = DetectColumns(image, column);
  } else {
    detection = Detect(image, settings.detector);
  }
  if (!detection) return detection.error();
  if (!options.keep_feet) detection = WithoutFeet(std::move(*detection));
  const double detect_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  Expected<Classification> classification = options.apply_rules
                                                ? Classify(*detection, settings.rules)
                                                : Expected<Classification>(KeepAll(*detection));
  if (!classification) return classification.error();
  return DetectRun{std::move(*detection), std::move(*classification), detect_s};
}

}  // namespace cairn::od::io
