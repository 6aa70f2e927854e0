// MRPT rawlogs: every entry read (RawlogReader) and every range observation decoded as
// `cairn detect --rawlog` does (DecodeRangeObservation), at most 8 entries per input.
#include "cairn/sources/decode.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto reader = cairn::sources::RawlogReader::Open(
      cairn::fuzz::WriteInput(data, size, "log.rawlog"));
  if (!reader) return 0;
  for (int i = 0; i < 8; ++i) {
    auto next = reader->Next();
    if (!next || !*next) break;
    (void)cairn::sources::DecodeRangeObservation(**next);
  }
  return 0;
}
