// `cairn map`: per-frame records, the run's resume state, progress (map_run.hpp).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include "cairn/sources/rawlog_frames.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/format.hpp"
#include "map_run.hpp"
#include "process_memory.hpp"

namespace cairn::apps {
namespace {

using nlohmann::json;

json IsometryJson(const Eigen::Isometry3d& T) {
  json m = json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m.push_back(T.matrix()(r, c));
  }
  return m;
}

Eigen::Isometry3d IsometryFromJson(const json& m) {
  if (!m.is_array() || m.size() != 12) throw std::runtime_error("a pose is not 12 numbers");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) T.matrix()(r, c) = m.at(4 * r + c).get<double>();
  }
  return T;
}

constexpr const char* kFormat = "cairn map resume state 4";

}  // namespace

Expected<std::optional<sources::SequenceFrame>> LookaheadFeed::Next(bool last) {
  Expected<std::optional<sources::SequenceFrame>> next =
      ahead_ ? std::move(*ahead_) : source_.Next();
  ahead_.reset();
  if (!last && next && *next && (*next)->used()) {
    ahead_ = source_.Next();
    if (*ahead_ && **ahead_ && (**ahead_)->used()) {
      const sources::SequenceFrame& following = ***ahead_;
      mapper_.Expect(following.image, following.T_world_sensor, following.stamp_s);
    }
  }
  return next;
}

Expected<std::unique_ptr<sources::FrameSource>> OpenFrameSource(const MapOptions& o,
                                                                const od::StereoConfig& stereo) {
  Expected<std::unique_ptr<sources::FrameSource>> opened =
      !o.rawlog.empty()  ? sources::OpenRawlogFrames(o.rawlog, o.label, stereo)
      : !o.kitti.empty() ? sources::OpenKittiFrames(o.kitti, o.sequence, o.range, o.lidar)
      : sources::IsStereoFolder(o.frames)
          ? sources::OpenStereoFolderFrames(o.frames, o.poses, o.stereo_calib, stereo)
          : sources::OpenDepthFolderFrames(o.frames, o.poses, o.intrinsics);
  if (!opened) return opened.error();
  return sources::ReadAhead(std::move(*opened));  // the next frame is read while this one maps
}

// The fields of FrameRecord and FrameSummary that the outputs use, by name. json keeps
// doubles exactly (shortest round-trip form), so a resumed run writes the same figures.
#define CAIRN_RECORD_FIELDS(X)                                                              \
  X(index) X(stamp_s) X(valid_points) X(segments) X(kept) X(tilt_from_imu) X(refined)       \
  X(d_roll_rad) X(d_pitch_rad) X(dz_m) X(rms_before_m) X(rms_after_m) X(refine_points)      \
  X(read_s) X(detect_s) X(refine_s) X(fuse_s) X(rss_mb) X(heap_mb)
#define CAIRN_SUMMARY_FIELDS(X)                                                             \
  X(frame_id) X(stamp_s) X(valid_points) X(points_in_range) X(obstacle_points)              \
  X(ground_points) X(kept_segments) X(obstacles_created) X(obstacles_updated)               \
  X(obstacles_merged) X(obstacles_retired) X(voxels_occupied) X(voxels_free) X(cells_hit)   \
  X(cells_missed) X(lethal_cells) X(window_moved) X(classify_s) X(octree_s) X(grid_s)       \
  X(obstacles_s)
#define CAIRN_TIME_FIELDS(X) X(read_s) X(detect_s) X(refine_s) X(fuse_s) X(write_s) X(checkpoint_s)

namespace {

json RecordJson(const FrameRecord& r) {
  json j, fused;
#define CAIRN_PUT(f) j[#f] = r.f;
  CAIRN_RECORD_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
#define CAIRN_PUT(f) fused[#f] = r.fused.f;
  CAIRN_SUMMARY_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
  j["fused"] = fused;
  j["not_observable"] = r.not_observable;
  j["verticals"] = r.verticals;
  if (std::isfinite(r.tilt_sigma_rad)) j["tilt_sigma_rad"] = r.tilt_sigma_rad;
  j["T_world_body"] = IsometryJson(r.T_world_body);
  j["T_world_sensor"] = IsometryJson(r.T_world_sensor);
  return j;
}

// Throws (json's exceptions, std::runtime_error) on a record that is not whole.
FrameRecord RecordFromJson(const json& rj) {
  FrameRecord r;
#define CAIRN_GET(f) rj.at(#f).get_to(r.f);
  CAIRN_RECORD_FIELDS(CAIRN_GET)
#undef CAIRN_GET
  const json& fused = rj.at("fused");
#define CAIRN_GET(f) fused.at(#f).get_to(r.fused.f);
  CAIRN_SUMMARY_FIELDS(CAIRN_GET)
#undef CAIRN_GET
  r.not_observable = rj.at("not_observable").get<std::string>();
  r.verticals = rj.at("verticals").get<int>();
  if (rj.contains("tilt_sigma_rad")) r.tilt_sigma_rad = rj.at("tilt_sigma_rad").get<double>();
  r.T_world_body = IsometryFromJson(rj.at("T_world_body"));
  r.T_world_sensor = IsometryFromJson(rj.at("T_world_sensor"));
  return r;
}

}  // namespace

std::string ResumeStateJson(const RunState& state) {
  json skipped = json::array();
  for (const SkippedFrame& s : state.skipped) {
    skipped.push_back({{"name", s.name}, {"reason", s.reason}, {"detail", s.detail}});
  }
  json times;
#define CAIRN_PUT(f) times[#f] = state.times.f;
  CAIRN_TIME_FIELDS(CAIRN_PUT)
#undef CAIRN_PUT
  const json j = {{"format", kFormat},
                  {"input", state.input},
                  {"config_text", state.config_text},
                  {"options", state.options},
                  {"wall_s", state.wall_s},
                  {"frames_read", state.frames_read},
                  {"refined_frames", state.refined_frames},
                  {"times", times},
                  {"records", {{"count", state.records_saved}, {"bytes", state.records_bytes}}},
                  {"skipped", skipped}};
  return j.dump();
}

Expected<RunState> ResumeStateFromJson(const std::string& text, const std::string& path) {
  try {
    const json j = json::parse(text);
    if (j.at("format") != kFormat) {
      return Error{path +
                   ": not a cairn map checkpoint of this version (its resume state is of "
                   "another format)"};
    }
    RunState state;
    state.input = j.at("input");
    state.config_text = j.at("config_text").get<std::string>();
    state.options = j.at("options");
    state.wall_s = j.at("wall_s").get<double>();
    state.frames_read = j.at("frames_read").get<int>();
    state.refined_frames = j.at("refined_frames").get<int>();
    const json& times = j.at("times");
#define CAIRN_GET(f) times.at(#f).get_to(state.times.f);
    CAIRN_TIME_FIELDS(CAIRN_GET)
#undef CAIRN_GET
    state.records_saved = j.at("records").at("count").get<std::size_t>();
    state.records_bytes = j.at("records").at("bytes").get<std::uint64_t>();
    for (const json& s : j.at("skipped")) {
      state.skipped.push_back({s.at("name").get<std::string>(), s.at("reason").get<std::string>(),
                               s.at("detail").get<std::string>()});
    }
    return state;
  } catch (const std::exception& e) {
    return Error{path + ": the run's resume state is unreadable (" + e.what() + ")"};
  }
}

Status SaveRecords(RunState& state, const std::filesystem::path& file) {
  std::string lines;
  for (std::size_t i = state.records_saved; i < state.records.size(); ++i) {
    lines += RecordJson(state.records[i]).dump();
    lines += '\n';
  }
  if (Status s = util::WriteFileAt(file, state.records_bytes, lines); !s) return s;
  state.records_saved = state.records.size();
  state.records_bytes += lines.size();
  return Status::Ok();
}

Status LoadRecords(RunState& state, const std::filesystem::path& file) {
  const std::string name = file.string();
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    return Error{name + ": cannot open the records the checkpoint counts (" +
                 std::to_string(state.records_saved) + ")"};
  }
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec || size < state.records_bytes || state.records_saved > state.records_bytes) {
    return Error{name + ": holds " + (ec ? std::string("no readable") : std::to_string(size)) +
                 " bytes, the checkpoint counts " + std::to_string(state.records_bytes) + " (" +
                 std::to_string(state.records_saved) + " records)"};
  }
  std::string bytes(state.records_bytes, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<std::uint64_t>(in.gcount()) != state.records_bytes) {
    return Error{name + ": holds " + std::to_string(in.gcount()) +
                 " bytes, the checkpoint counts " + std::to_string(state.records_bytes)};
  }
  state.records.clear();
  state.records.reserve(state.records_saved);
  std::size_t at = 0;
  while (at < bytes.size()) {
    const std::size_t end = bytes.find('\n', at);
    if (end == std::string::npos) break;
    try {
      state.records.push_back(RecordFromJson(json::parse(bytes.begin() + at, bytes.begin() + end)));
    } catch (const std::exception& e) {
      return Error{name + ": record " + std::to_string(state.records.size() + 1) +
                   " is unreadable (" + e.what() + ")"};
    }
    at = end + 1;
  }
  if (at != bytes.size() || state.records.size() != state.records_saved) {
    return Error{name + ": " + std::to_string(state.records.size()) +
                 " whole records in the bytes the checkpoint counts, expected " +
                 std::to_string(state.records_saved)};
  }
  return Status::Ok();
}

#undef CAIRN_RECORD_FIELDS
#undef CAIRN_SUMMARY_FIELDS
#undef CAIRN_TIME_FIELDS

json SourceJson(const sources::SourceInfo& info) {
  json j = json::object();
  for (const auto& [key, value] : info) {
    if (const auto* s = std::get_if<std::string>(&value)) {
      j[key] = *s;
    } else {
      j[key] = std::get<std::int64_t>(value);
    }
  }
  return j;
}

json RunOptions(const MapOptions& o, map::TiltMode tilt, double window_size_m, bool smooth) {
  return {{"--range", o.range},
          {"--intrinsics", o.intrinsics},
          {"--tilt", map::TiltModeName(tilt)},
          {"--window", window_size_m},
          {"--smooth", smooth}};
}

FrameRecord RecordOf(const sources::SequenceFrame& frame, const map::MapperRecord& m,
                     double read_s) {
  FrameRecord r;
  r.index = static_cast<int>(m.index);
  r.stamp_s = m.stamp_s;
  r.T_world_body = frame.T_world_body;
  r.T_world_sensor = m.T_world_sensor;
  r.valid_points = m.valid_points;
  r.segments = m.segments;
  r.kept = m.kept;
  r.fused = m.fused;
  r.tilt_from_imu = frame.tilt_from_imu;
  if (m.tilt.estimated) {
    r.refined = m.tilt.applied;
    r.d_roll_rad = m.tilt.roll_rad;
    r.d_pitch_rad = m.tilt.pitch_rad;
    r.dz_m = m.tilt.dz_m;
    r.rms_before_m = m.tilt.estimate.rms_before_m;
    r.rms_after_m = m.tilt.estimate.rms_after_m;
    r.refine_points = m.tilt.estimate.points_used;
    r.refine_s = m.tilt_s;
    if (m.tilt.gravity) {
      for (const map::GravityDegeneracy& d : m.tilt.gravity->degeneracies) {
        r.not_observable +=
            (r.not_observable.empty() ? "" : "; ") + std::string(map::StateName(d.state));
      }
      r.verticals = m.tilt.gravity->cues.frame_verticals;
      // The pose fused is the estimate's only when it was applied.
      if (m.tilt.applied) {
        r.tilt_sigma_rad = std::sqrt(m.tilt.gravity->up_sensor_covariance.trace());
      }
    }
  }
  r.read_s = read_s;
  r.detect_s = m.detect_s;
  r.fuse_s = m.fuse_s;
  const ProcessMemory memory = ReadProcessMemory();
  r.rss_mb = memory.rss_mb;
  r.heap_mb = memory.heap_mb;
  return r;
}

Status SameRun(const RunState& saved, const RunState& now, const std::string& checkpoint,
               const std::string& config) {
  if (saved.input != now.input) {
    return Error{checkpoint + ": made from another input (" + saved.input.dump() + "), not " +
                 now.input.dump() + " (--resume needs the same input)"};
  }
  for (const auto& [key, value] : saved.options.items()) {
    if (!now.options.contains(key) || now.options.at(key) != value) {
      return Error{checkpoint + ": made with " + key + " " + value.dump() + ", not " +
                   (now.options.contains(key) ? now.options.at(key).dump() : "none") +
                   " (--resume needs the same options)"};
    }
  }
  if (saved.config_text != now.config_text) {
    return Error{checkpoint + ": made with other settings than " +
                 (config.empty() ? std::string("the defaults") : config) +
                 " (--resume needs the same --config)"};
  }
  return {};
}


}  // namespace cairn::apps
