// The settings file: detector, rules, column and stereo sections (ParseDetectSettings) and
// the map section (map::ParseMapConfig), as `cairn detect` and `cairn map` read it.
#include "cairn/map/map_config_file.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cairn::fuzz::Text(data, size);
  (void)cairn::od::io::ParseDetectSettings(text, "fuzz.yaml");
  (void)cairn::map::ParseMapConfig(text, "fuzz.yaml");
  return 0;
}
