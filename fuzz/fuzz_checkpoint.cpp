// Map checkpoints (map::LoadCheckpoint) with the default config: any bytes give a map or
// an error. The header's checksum refuses nearly every mutation at once, so the input's
// first byte, when odd, asks for the checksum to be fixed up after the mutation: that lets
// the fuzzer reach the payload's parser.
#include <cstring>

#include "cairn/map/checkpoint.hpp"
#include "fuzz_input.hpp"

namespace {

std::uint64_t Fnv1a(const std::uint8_t* p, std::size_t n) {
  std::uint64_t h = 14695981039346656037ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  std::string bytes(reinterpret_cast<const char*>(data + 1), size - 1);
  constexpr std::size_t kHeader = 8 + 4 + 4 + 8 + 8;
  if ((data[0] & 1) && bytes.size() >= kHeader) {
    const std::uint64_t payload = bytes.size() - kHeader;
    const std::uint64_t sum =
        Fnv1a(reinterpret_cast<const std::uint8_t*>(bytes.data()) + kHeader, payload);
    std::memcpy(bytes.data() + 16, &payload, 8);
    std::memcpy(bytes.data() + 24, &sum, 8);
  }
  const auto path = cairn::fuzz::WriteInput(reinterpret_cast<const std::uint8_t*>(bytes.data()),
                                            bytes.size(), "map.checkpoint");
  (void)cairn::map::LoadCheckpoint(path, cairn::map::MapConfig{});
  return 0;
}
