// Point files by the reader the first byte picks: KITTI .bin, PLY (ascii or binary),
// "x y z" text, bzip2 text, SemanticKITTI .label; the rest of the input is the file.
// A cloud that reads is laid out (FindLayout) as `cairn detect --points` does.
#include "cairn/od/io/point_cloud.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kNames[] = {"scan.bin", "scan.ply", "scan.txt", "scan.txt.bz2",
                                       "scan.label"};
  const char* name = kNames[data[0] % 5];
  const auto path = cairn::fuzz::WriteInput(data + 1, size - 1, name);
  if (data[0] % 5 == 4) {
    (void)cairn::od::io::ReadLabelFile(path);
    return 0;
  }
  cairn::Expected<cairn::od::PointCloud> cloud = cairn::od::io::ReadPointFile(path);
  if (cloud && cloud->points.size() <= 4096) {
    (void)cairn::od::FindLayout(*cloud, cairn::od::LayoutOptions{}, "fuzz");
  }
  return 0;
}
