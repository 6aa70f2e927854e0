// `cairn bench` on a sequence (bench_sequence.cpp): built with the Mapper and the frame
// sources (CAIRN_HAVE_MAP).
#pragma once

#include "map_run.hpp"

namespace cairn::apps {

/// The Mapper over the sequence `o` names (its inputs, --config, --tilt, --max-frames), per
/// stage, against a sensor at `rate_hz`; prints the table and returns the exit code.
int RunSequenceBench(const MapOptions& o, double rate_hz);

}  // namespace cairn::apps
