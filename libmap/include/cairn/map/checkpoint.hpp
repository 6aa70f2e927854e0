// Checkpoints of a TerrainMap: its whole fused state in one binary file, so that a mapping
// run interrupted (killed, crashed, stopped) can resume where it was, without losing what
// was fused. A map loaded from a checkpoint and fed the remaining frames ends bit for bit
// like the map that was never interrupted: same cells, same octree nodes, same obstacles.
//
// The file (little-endian, this machine's float layout; not an interchange format):
//   header   magic "CAIRNMCK", u32 format version, u32 reserved (0),
//            u64 payload size [bytes], u64 FNV-1a 64 checksum of the payload;
//   payload  the MapConfig the map was made with (u32 count, then that many doubles),
//            counters (next obstacle id, frames integrated, obstacles retired, observed
//            bounds, window position of the last octree pruning, octree flush state),
//            the grid (window cells, extent, buffer size, every slot of the ring buffer),
//            the obstacles (every field), the application's opaque data (u64 size, bytes),
//            the octree (u64 node count, u64 size, then OctoMap's own node stream,
//            OcTreeBaseImpl::writeData with TerrainOcTreeNode::writeData: both log-odds
//            of every node, inner nodes included, and the child bits).
// It is written atomically (temporary file, then rename): an interruption during a save
// leaves the previous checkpoint as it was. Loading checks the magic, the version, the
// sizes and the checksum before it reads anything, so a truncated or corrupted file is
// refused with a message naming the file and what was expected.
//
// Per-frame scratch (reset at each frame) is not saved. The config is saved so that a run
// that resumes with different settings is refused (they would give a map neither run
// describes), naming the first field that differs.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "cairn/map/map_config.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/od/expected.hpp"

namespace cairn::map {

/// File name of a checkpoint inside a directory.
inline constexpr const char* kCheckpointFileName = "map.checkpoint";
/// Format version written by SaveCheckpoint (and the only one LoadCheckpoint reads).
inline constexpr std::uint32_t kCheckpointVersion = 1;

/// `dir_or_file` itself, or dir_or_file / kCheckpointFileName when it is an existing
/// directory.
std::filesystem::path CheckpointPath(const std::filesystem::path& dir_or_file);

/// Writes the whole state of `map` to CheckpointPath(dir_or_file), atomically; the
/// directory must exist. `user_data` is stored as is and returned by LoadCheckpoint (an
/// application's resume state: which input comes next, for instance). Does not modify the
/// map (not even the lazy octree refresh that octree() does). Errors name the file.
Status SaveCheckpoint(const TerrainMap& map, const std::filesystem::path& dir_or_file,
                      std::string_view user_data = {});

/// Rebuilds the map saved in CheckpointPath(dir_or_file). Fails, naming the file, when it is
/// missing, truncated, corrupted, of another format version, or made with a config that
/// differs from `expected_config` (naming the first differing field by its config-file key,
/// with both values). `user_data`, when given, receives what SaveCheckpoint stored.
Expected<TerrainMap> LoadCheckpoint(const std::filesystem::path& dir_or_file,
                                    const MapConfig& expected_config,
                                    std::string* user_data = nullptr);

}  // namespace cairn::map
