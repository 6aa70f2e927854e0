// World YAML (sim::LoadWorld), as `cairn synth --world` reads it.
#include "cairn/sim/world.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)cairn::sim::LoadWorld(cairn::fuzz::WriteInput(data, size, "world.yaml").string());
  return 0;
}
