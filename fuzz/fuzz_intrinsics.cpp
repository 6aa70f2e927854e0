// Intrinsics YAML (od::io::ParseIntrinsics): any text gives a value or an error.
#include "cairn/od/io/intrinsics.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)cairn::od::io::ParseIntrinsics(cairn::fuzz::Text(data, size), "fuzz.yaml");
  return 0;
}
