// `cairn bench` on a whole sequence: the Mapper over the frames of a rawlog, a KITTI sequence
// or a depth folder, exactly as `cairn map` runs it (the same source, settings and Mapper)
// but writing nothing, timed stage by stage: each stage's median and 95th percentile per
// frame, the frame rate it sustains against the sensor's, and the peak memory.
#include "bench_sequence.hpp"

#include <algorithm>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include "cairn/map/frame_imu.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/quantile.hpp"
#include "map_run.hpp"
#include "process_memory.hpp"
#include "progress.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

int SequenceFail(const std::string& message) { return CommandFailure("bench", message); }

struct Stage {
  const char* name;
  int indent;  ///< 1: part of the stage above
  std::vector<double> ms;
};

}  // namespace

int RunSequenceBench(const MapOptions& o, double rate_hz) {
  Expected<map::MapperSettings> settings = map::LoadMapperSettings(o.config);
  if (!settings) return SequenceFail(settings.error().message);
  map::MapperConfig& config = settings->mapper;
  if (!o.tilt.empty()) {
    Expected<map::TiltMode> mode = map::ParseTiltMode(o.tilt);
    if (!mode) return SequenceFail("--tilt: " + mode.error().message);
    config.tilt.mode = *mode;
  }
  Expected<map::Mapper> created = map::Mapper::Create(config);
  if (!created) return SequenceFail(created.error().message);
  map::Mapper mapper = std::move(*created);
  const auto open_start = Clock::now();
  Expected<std::unique_ptr<sources::FrameSource>> opened = OpenFrameSource(o, settings->stereo);
  if (!opened) return SequenceFail(opened.error().message);
  sources::FrameSource& source = **opened;
  const double open_s = SecondsSince(open_start);

  std::vector<Stage> stages = {{"read", 0, {}}, {"detect", 0, {}}, {"tilt", 0, {}},
                               {"fuse", 0, {}}, {"octree", 1, {}}, {"classify", 1, {}},
                               {"grid", 1, {}}, {"frame", 0, {}}};
  int read = 0, skipped = 0;
  const int total = o.max_frames > 0 ? std::min(o.max_frames, source.total()) : source.total();
  Progress progress("cairn bench", total, o.progress_every);
  const auto run_start = Clock::now();
  LookaheadFeed feed(source, mapper);  // as cairn map reads and detects
  while (o.max_frames <= 0 || read < o.max_frames) {
    const auto t = Clock::now();
    Expected<std::optional<sources::SequenceFrame>> next =
        feed.Next(o.max_frames > 0 && read + 1 >= o.max_frames);
    if (!next) return SequenceFail(next.error().message);
    if (!*next) break;
    sources::SequenceFrame& frame = **next;
    ++read;
    const double read_s = SecondsSince(t);
    if (!frame.used()) {
      ++skipped;
      progress.Update(read);
      continue;
    }
    if (Status st = mapper.SetSensorMount(frame.T_body_sensor()); !st) {
      return SequenceFail(frame.name + ": " + st.message());
    }
    Expected<map::MapperRecord> r = mapper.Process(std::move(frame.image), frame.T_world_sensor,
                                                   frame.stamp_s, map::ImuSamplesOf(frame));
    if (!r) return SequenceFail(frame.name + ": " + r.error().message);
    if (!r->used()) {
      ++skipped;
      progress.Update(read);
      continue;
    }
    const double frame_s = SecondsSince(t);
    const double values_s[] = {
        read_s,          r->detect_s, r->tilt_s, r->fuse_s, r->fused.octree_s, r->fused.classify_s,
        r->fused.grid_s, frame_s};
    for (std::size_t k = 0; k < stages.size(); ++k) stages[k].ms.push_back(1e3 * values_s[k]);
    ReleaseFreeMemoryEvery(read);
    progress.Update(read);
  }
  progress.Finish();
  const double run_s = SecondsSince(run_start);
  const std::vector<double>& frame_ms = stages.back().ms;
  const std::string input = !o.rawlog.empty() ? o.rawlog : !o.kitti.empty() ? o.kitti : o.frames;
  if (frame_ms.empty()) return SequenceFail(input + ": no frame was fused");

  const double budget_ms = 1e3 / rate_hz;
  const double median_ms = util::Quantile(frame_ms, 0.5);
  std::cout << "cairn bench: " << frame_ms.size() << " frames fused of " << read << " read ("
            << skipped << " skipped) from " << input << ", tilt "
            << map::TiltModeName(config.tilt.mode) << "\n"
            << "  per frame [ms]        median     95th pct   of the " << util::Fixed(budget_ms, 0)
            << " ms a frame has at " << util::Fixed(rate_hz, 1) << " Hz\n";
  for (const Stage& s : stages) {
    const double median = util::Quantile(s.ms, 0.5);
    std::cout << "  " << std::string(2 * s.indent, ' ') << std::left << std::setw(20 - 2 * s.indent)
              << s.name << std::right << std::setw(9) << util::Fixed(median, 1) << std::setw(13)
              << util::Fixed(util::Quantile(s.ms, 0.95), 1) << std::setw(12)
              << util::Fixed(median / budget_ms, 2) << "\n";
  }
  std::cout << "  sustained: " << util::Fixed(1e3 / median_ms, 2)
            << " frames/s (one over the median frame); " << util::Fixed(read / run_s, 2)
            << " frames/s over the whole loop; opening the source took " << util::Fixed(open_s, 2)
            << " s\n"
            << "  the sensor's " << util::Fixed(rate_hz, 1) << " Hz is "
            << (median_ms <= budget_ms ? "kept" : "not kept") << " ("
            << util::Fixed(median_ms / budget_ms, 2) << " of the budget)\n"
            << "  peak memory: " << util::Fixed(ReadProcessMemory().peak_rss_mb, 0) << " MiB\n";
  return kExitOk;
}

}  // namespace cairn::apps
