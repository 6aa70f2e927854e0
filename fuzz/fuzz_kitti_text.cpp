// KITTI's text files, by the first byte: calib.txt, poses.txt, times.txt.
#include "cairn/od/io/kitti.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const int kind = data[0] % 3;
  const auto path = cairn::fuzz::WriteInput(data + 1, size - 1, "kitti.txt");
  if (kind == 0) (void)cairn::od::io::ReadKittiCalibration(path);
  if (kind == 1) (void)cairn::od::io::ReadKittiPoses(path);
  if (kind == 2) (void)cairn::od::io::ReadKittiTimes(path);
  return 0;
}
