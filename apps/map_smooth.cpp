// cairn map --smooth: the second pass over the input, at the smoother's poses (map_run.hpp).
#include <Eigen/Geometry>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "cairn/map/frame_imu.hpp"
#include "map_run.hpp"
#include "progress.hpp"

namespace cairn::apps {

Expected<SmoothedRun> SmoothedPass(const MapOptions& options, const map::MapperSettings& settings,
                                   map::Mapper& first, RunState& state,
                                   const std::function<bool()>& interrupted) {
  const Clock::time_point solve_start = Clock::now();
  Expected<std::vector<map::SmoothedFrame>> poses = first.SmoothTilt();
  if (!poses) return Error{"smoothing: " + poses.error().message};
  const double solve_s = SecondsSince(solve_start);
  if (poses->size() != state.records.size()) {
    return Error{"smoothing: " + std::to_string(poses->size()) + " poses for " +
                 std::to_string(state.records.size()) + " fused frames"};
  }
  const Clock::time_point pass_start = Clock::now();
  Expected<map::Mapper> again = map::Mapper::Create(map::SmoothedPassConfig(first.config()));
  if (!again) return again.error();
  Expected<std::unique_ptr<sources::FrameSource>> opened =
      OpenFrameSource(options, settings.stereo);
  if (!opened) return opened.error();
  sources::FrameSource& source = **opened;
  const int n = static_cast<int>(poses->size());
  Progress progress("cairn map, smoothed pass", n, options.progress_every, 0);
  int k = 0;
  for (int read = 0; k < n && read < state.frames_read; ++read) {
    if (interrupted()) {
      progress.Finish();
      return Error{"interrupted"};
    }
    Expected<std::optional<sources::SequenceFrame>> next = source.Next();
    if (!next) return next.error();
    if (!*next) break;
    sources::SequenceFrame& frame = **next;
    const map::SmoothedFrame& pose = (*poses)[static_cast<std::size_t>(k)];
    if (!frame.used() || frame.stamp_s != pose.stamp_s) continue;  // not fused the first time
    if (state.records[static_cast<std::size_t>(k)].stamp_s != pose.stamp_s) {
      return Error{"smoothing: the first pass's record " + std::to_string(k) + " is of " +
                   std::to_string(state.records[static_cast<std::size_t>(k)].stamp_s) +
                   " s, its smoothed pose of " + std::to_string(pose.stamp_s) + " s"};
    }
    if (Status st = again->SetSensorMount(frame.T_body_sensor()); !st) {
      return Error{frame.name + ": " + st.message()};
    }
    const Eigen::Isometry3d odometry = frame.T_world_sensor;
    Expected<map::MapperRecord> r = again->Process(std::move(frame.image), pose.T_world_sensor,
                                                   frame.stamp_s, map::ImuSamplesOf(frame));
    if (!r) return Error{frame.name + ": " + r.error().message};
    if (!r->used()) {
      return Error{frame.name + ": not fused at its smoothed pose: " + map::FrameSkipName(r->skip) +
                   " (" + r->skip_detail + ")"};
    }
    FrameRecord& record = state.records[static_cast<std::size_t>(k)];
    record.T_world_sensor = r->T_world_sensor;
    record.fused = r->fused;
    record.d_roll_rad = pose.roll_rad;
    record.d_pitch_rad = pose.pitch_rad;
    record.dz_m = r->T_world_sensor.translation().z() - odometry.translation().z();
    // The window's tilt sigma does not describe the smoothed pose (the smoother states none).
    record.tilt_sigma_rad = std::numeric_limits<double>::quiet_NaN();
    ++k;
    progress.Update(k);
  }
  progress.Finish();
  if (k != n) {
    return Error{"smoothing: the input gave " + std::to_string(k) + " of the " + std::to_string(n) +
                 " frames the first pass fused"};
  }
  return SmoothedRun{std::move(*again), solve_s, SecondsSince(pass_start)};
}

}  // namespace cairn::apps
