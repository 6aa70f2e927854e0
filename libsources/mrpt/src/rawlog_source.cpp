#include "cairn/sources/rawlog_source.hpp"

#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CSensoryFrame.h>

#include <cmath>

#include "cairn/sources/mrpt_convert.hpp"

namespace cairn::sources {
namespace {

using ::mrpt::obs::CObservation;

Eigen::Isometry3d FromPose2D(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() << x, y, 0.0;
  return T;
}

}  // namespace

Expected<RawlogSource> RawlogSource::Open(const std::filesystem::path& path,
                                          const SourceOptions& options) {
  Expected<RawlogReader> reader = RawlogReader::Open(path);
  if (!reader) return reader.error();
  return RawlogSource(std::move(*reader), options);
}

void RawlogSource::NoteStamp(double stamp_s) {
  if (std::isfinite(stamp_s)) last_stamp_s_ = stamp_s;
}

void RawlogSource::FlushPendingAction(double stamp_s) {
  if (!pending_action_) return;
  pending_action_->stamp_s = stamp_s;
  odometry_.push_back(*pending_action_);
  last_odometry_ = *pending_action_;
  pending_action_.reset();
}

void RawlogSource::Observe(const CObservation& observation) {
  NoteStamp(FromMrptTime(observation.timestamp));
  if (const auto* odometry = dynamic_cast<const ::mrpt::obs::CObservationOdometry*>(&observation)) {
    last_odometry_ = DecodeOdometry(*odometry);
    odometry_.push_back(*last_odometry_);
  } else if (const auto* imu = dynamic_cast<const ::mrpt::obs::CObservationIMU*>(&observation)) {
    if (std::optional<ImuAttitude> attitude = DecodeImu(*imu)) last_imu_ = attitude;
    if (std::optional<ImuSample> sample = DecodeImuSample(*imu)) {
      imu_samples_.push_back(std::move(*sample));
    }
  }
}

void RawlogSource::Act(const ::mrpt::obs::CActionCollection& actions) {
  std::optional<Eigen::Isometry3d> increment;
  std::string source;
  double stamp_s = kNoStamp;
  if (auto move3d = actions.getActionByClass<::mrpt::obs::CActionRobotMovement3D>()) {
    increment = FromCPose3D(move3d->poseChange.mean);
    source = "CActionRobotMovement3D";
    stamp_s = FromMrptTime(move3d->timestamp);
  } else if (auto move2d = actions.getActionByClass<::mrpt::obs::CActionRobotMovement2D>()) {
    if (move2d->poseChange) {
      const ::mrpt::poses::CPose2D mean = move2d->poseChange->getMeanVal();
      increment = FromPose2D(mean.x(), mean.y(), mean.phi());
      source = "CActionRobotMovement2D";
      stamp_s = FromMrptTime(move2d->timestamp);
    }
  }
  if (!increment) return;
  // An action that follows another one without a frame between keeps the first's time.
  FlushPendingAction(last_stamp_s_);
  if (!actions_started_) {
    actions_started_ = true;
    OdometrySample start;
    start.stamp_s = last_frame_stamp_s_;
    start.source = source;
    odometry_.push_back(start);
    last_odometry_ = start;
  }
  T_odom_body_actions_ = T_odom_body_actions_ * *increment;
  OdometrySample sample;
  sample.T_odom_body = T_odom_body_actions_;
  sample.source = source;
  pending_action_ = sample;
  if (std::isfinite(stamp_s)) {
    NoteStamp(stamp_s);
    FlushPendingAction(stamp_s);
  }
}

Expected<std::optional<SourceEntry>> RawlogSource::NextEntry() {
  Expected<std::optional<RawlogEntry>> raw = reader_.NextEntry();
  if (!raw) return raw.error();
  if (!*raw) {
    FlushPendingAction(last_stamp_s_);
    return std::optional<SourceEntry>();
  }
  SourceEntry entry;
  entry.raw = std::move(**raw);
  const auto& object = entry.raw.object;
  if (auto observation = std::dynamic_pointer_cast<CObservation>(object)) {
    entry.observations.push_back(std::move(observation));
  } else if (auto sf = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>(object)) {
    double stamp_s = kNoStamp;
    for (const CObservation::Ptr& o : *sf) {
      if (!o) continue;
      entry.observations.push_back(o);
      if (!std::isfinite(stamp_s)) stamp_s = FromMrptTime(o->timestamp);
    }
    if (std::isfinite(stamp_s)) {
      last_frame_stamp_s_ = stamp_s;
      FlushPendingAction(stamp_s);
    }
  } else if (auto actions = std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>(object)) {
    Act(*actions);
  } else {
    return Error{EntryName(reader_.path(), entry.raw.index) + ": a " +
                 ShortClassName(object->GetRuntimeClass()->className) +
                 ", not an observation, sensory frame or action collection"};
  }
  for (std::size_t k = 0; k < entry.observations.size(); ++k) {
    const CObservation& o = *entry.observations[k];
    Observe(o);
    if (!options_.decode_frames || !IsRangeObservation(o)) continue;
    if (!options_.label.empty() && o.sensorLabel != options_.label) continue;
    if (std::optional<std::string> why = WhyNoRangeData(o)) {
      skipped_.push_back({entry.raw.index, o.sensorLabel,
                          ShortClassName(o.GetRuntimeClass()->className), *why});
      continue;
    }
    Expected<Frame> frame = DecodeRangeObservation(o, options_.decode);
    if (!frame) return Error{EntryName(reader_.path(), entry.raw.index) + ": " + frame.error().message};
    frame->entry = entry.raw.index;
    frame->index = frames_++;
    frame->odometry = last_odometry_;
    frame->imu = last_imu_;
    frame->imu_samples = std::move(imu_samples_);
    imu_samples_.clear();
    entry.frames.push_back(std::move(*frame));
    entry.frame_observation.push_back(static_cast<int>(k));
  }
  return std::optional<SourceEntry>(std::move(entry));
}

Expected<std::optional<Frame>> RawlogSource::NextFrame() {
  while (pending_frames_.empty()) {
    Expected<std::optional<SourceEntry>> entry = NextEntry();
    if (!entry) return entry.error();
    if (!*entry) return std::optional<Frame>();
    for (Frame& frame : (*entry)->frames) pending_frames_.push_back(std::move(frame));
  }
  Frame frame = std::move(pending_frames_.front());
  pending_frames_.pop_front();
  return std::optional<Frame>(std::move(frame));
}

}  // namespace cairn::sources
