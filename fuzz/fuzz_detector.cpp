// The detectors on small arbitrary range images: the first bytes choose the size (1..16 a
// side), the camera's tilt and the detector's thresholds; the rest are depths (16-bit,
// millimetres, 0 = no return). The cone detector (exact and paper window), the column
// baseline and the rules must each give a result or an error, and the exact detector must
// agree with itself on one thread and several.
#include <cmath>
#include <cstdlib>
#include <vector>

#include "cairn/od/column_detector.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 6) return 0;
  const int width = 1 + data[0] % 16, height = 1 + data[1] % 16;
  const double pitch = (static_cast<int>(data[2]) - 128) * (80.0 / 128.0) * M_PI / 180.0;
  cairn::od::DetectorConfig config;
  config.min_height_m = 0.05 + data[3] * 0.004;
  config.max_height_m = config.min_height_m + 0.05 + data[4] * 0.01;
  config.min_slope_rad = (5.0 + data[5] * (80.0 / 255.0)) * M_PI / 180.0;
  config.threads = 1;
  std::vector<float> depth(static_cast<std::size_t>(width) * height, 0.0f);
  for (std::size_t i = 0; i < depth.size() && 6 + 2 * i + 1 < size; ++i) {
    depth[i] = (data[6 + 2 * i] | (data[6 + 2 * i + 1] << 8)) * 0.001f;
  }
  cairn::od::PinholeModel model;
  model.width = width;
  model.height = height;
  model.fx = model.fy = 0.8 * width + 1.0;
  model.cx = 0.5 * (width - 1);
  model.cy = 0.5 * (height - 1);
  auto image = cairn::od::RangeImage::FromDepth(depth, model,
                                                cairn::od::CameraUpFromPitchRoll(pitch, 0.0));
  if (!image) return 0;
  auto exact = cairn::od::Detect(*image, config);
  if (exact) {
    (void)cairn::od::Classify(*exact, cairn::od::RuleConfig{});
    config.threads = 3;
    auto threaded = cairn::od::Detect(*image, config);
    if (!threaded || threaded->labels != exact->labels) std::abort();
  }
  config.search = cairn::od::SearchMode::kPaperWindow;
  (void)cairn::od::Detect(*image, config);
  (void)cairn::od::DetectColumns(*image, cairn::od::ColumnConfig::From(config));
  return 0;
}
