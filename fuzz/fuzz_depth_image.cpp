// Depth images (16-bit PNG, float or 16-bit TIFF) through ReadDepthImage, and the same
// bytes as a grey stereo image (ReadGreyImage).
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = cairn::fuzz::WriteInput(data, size, "depth.png");
  (void)cairn::od::io::ReadDepthImage(path, 32, 24, 0.001);
  (void)cairn::od::io::ReadGreyImage(path);
  return 0;
}
