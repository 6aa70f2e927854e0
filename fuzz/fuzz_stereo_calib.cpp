// Stereo calibration files, all three formats through LoadStereoCalibration (which tells
// them apart by content): cairn's YAML, FoundationStereo's K.txt, OpenCV FileStorage.
#include "cairn/od/io/stereo_files.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)cairn::od::io::LoadStereoCalibration(cairn::fuzz::WriteInput(data, size, "rig.yaml"));
  return 0;
}
