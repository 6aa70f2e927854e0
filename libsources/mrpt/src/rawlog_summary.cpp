#include "cairn/sources/rawlog_summary.hpp"

#include <mrpt/obs/CAction.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CSensoryFrame.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <tuple>

#include "cairn/sources/decode.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "mrpt_errors.hpp"

namespace cairn::sources {
namespace {

using ::mrpt::obs::CObservation;

struct SensorTally {
  SensorSummary summary;
  std::int64_t points_sum = 0;
  int point_scans = 0;
};

void MinMaxStamp(double stamp_s, double& first, double& last) {
  if (!std::isfinite(stamp_s)) return;
  if (!std::isfinite(first) || stamp_s < first) first = stamp_s;
  if (!std::isfinite(last) || stamp_s > last) last = stamp_s;
}

void AddPoints(SensorTally& tally, std::int64_t points) {
  SensorSummary& s = tally.summary;
  s.points_min = tally.point_scans == 0 ? points : std::min(s.points_min, points);
  s.points_max = tally.point_scans == 0 ? points : std::max(s.points_max, points);
  tally.points_sum += points;
  ++tally.point_scans;
}

// Sizes of what the observation holds; range data is decoded (and its failure recorded).
void Measure(const CObservation& o, SensorTally& tally) {
  SensorSummary& s = tally.summary;
  if (IsRangeObservation(o)) {
    if (WhyNoRangeData(o)) return;
    Expected<Frame> frame = DecodeRangeObservation(o);
    if (!frame) {
      if (s.problems++ == 0) s.problem = frame.error().message;
      return;
    }
    if (const DepthImage* depth = frame->depth()) {
      s.width = depth->model.width;
      s.height = depth->model.height;
    } else if (const PointScan* scan = frame->points()) {
      AddPoints(tally, static_cast<std::int64_t>(scan->points.size()));
      s.rings = scan->model.height();
    } else if (const StereoPair* pair = frame->stereo()) {
      s.width = pair->left.width;
      s.height = pair->left.height;
    }
    return;
  }
  if (const auto* scan2d = dynamic_cast<const ::mrpt::obs::CObservation2DRangeScan*>(&o)) {
    AddPoints(tally, static_cast<std::int64_t>(scan2d->getScanSize()));
  } else if (const auto* image = dynamic_cast<const ::mrpt::obs::CObservationImage*>(&o)) {
    try {
      s.width = static_cast<int>(image->image.getWidth());
      s.height = static_cast<int>(image->image.getHeight());
    } catch (const std::exception& e) {
      if (s.problems++ == 0) s.problem = "cannot load its image: " + detail::Describe(e);
    }
  }
}

bool IsGzip(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char magic[2] = {0, 0};
  in.read(reinterpret_cast<char*>(magic), 2);
  return in.gcount() == 2 && magic[0] == 0x1f && magic[1] == 0x8b;
}

}  // namespace

const char* FormatName(RawlogFormat format) {
  switch (format) {
    case RawlogFormat::kEmpty: return "empty";
    case RawlogFormat::kObservations: return "observations";
    case RawlogFormat::kSensoryFrames: return "sensory frames (actions and observations)";
    case RawlogFormat::kMixed: return "mixed (observations, sensory frames and actions)";
  }
  return "unknown";
}

Expected<RawlogSummary> SummarizeRawlog(const std::filesystem::path& path) {
  SourceOptions options;
  options.decode_frames = false;
  Expected<RawlogSource> source = RawlogSource::Open(path, options);
  if (!source) return source.error();
  RawlogSummary summary;
  summary.path = path;
  std::error_code ec;
  summary.file_bytes = std::filesystem::file_size(path, ec);
  summary.gzip = IsGzip(path);
  bool observations = false, frames = false;
  std::map<std::tuple<std::string, std::string>, SensorTally> sensors;
  while (true) {
    Expected<std::optional<SourceEntry>> entry = source->NextEntry();
    if (!entry) return entry.error();
    if (!*entry) break;
    const auto& object = (*entry)->raw.object;
    ++summary.entries;
    ++summary.class_counts[ShortClassName(object->GetRuntimeClass()->className)];
    if (std::dynamic_pointer_cast<CObservation>(object)) {
      observations = true;
    } else {
      frames = true;
    }
    if (auto actions = std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>(object)) {
      for (const auto& action : *actions) {
        if (!action) continue;
        ++summary.class_counts[ShortClassName(action->GetRuntimeClass()->className)];
        MinMaxStamp(FromMrptTime(action->timestamp), summary.first_stamp_s, summary.last_stamp_s);
      }
    }
    const bool nested = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>(object) != nullptr;
    for (const CObservation::Ptr& o : (*entry)->observations) {
      const std::string cls = ShortClassName(o->GetRuntimeClass()->className);
      if (nested) ++summary.class_counts[cls];
      SensorTally& tally = sensors[{o->sensorLabel, cls}];
      SensorSummary& s = tally.summary;
      s.label = o->sensorLabel;
      s.mrpt_class = cls;
      ++s.count;
      const double stamp_s = FromMrptTime(o->timestamp);
      MinMaxStamp(stamp_s, s.first_stamp_s, s.last_stamp_s);
      MinMaxStamp(stamp_s, summary.first_stamp_s, summary.last_stamp_s);
      Measure(*o, tally);
    }
  }
  summary.format = summary.entries == 0 ? RawlogFormat::kEmpty
                   : observations && frames ? RawlogFormat::kMixed
                   : observations           ? RawlogFormat::kObservations
                                            : RawlogFormat::kSensoryFrames;
  for (auto& [key, tally] : sensors) {
    SensorSummary& s = tally.summary;
    if (tally.point_scans > 0) s.points_mean = static_cast<double>(tally.points_sum) / tally.point_scans;
    if (s.count >= 2 && s.last_stamp_s > s.first_stamp_s) {
      s.rate_hz = (s.count - 1) / (s.last_stamp_s - s.first_stamp_s);
    }
    summary.sensors.push_back(s);
  }
  const std::vector<OdometrySample>& odometry = source->odometry();
  summary.odometry_poses = static_cast<int>(odometry.size());
  for (std::size_t k = 1; k < odometry.size(); ++k) {
    if (odometry[k].source != odometry[k - 1].source) continue;
    summary.odometry_path_m +=
        (odometry[k].T_odom_body.translation() - odometry[k - 1].T_odom_body.translation()).norm();
  }
  return summary;
}

}  // namespace cairn::sources
