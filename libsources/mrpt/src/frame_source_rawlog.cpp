// OpenRawlogFrames (rawlog_frames.hpp): an MRPT rawlog read twice, poses first.
#include <mrpt/obs/CObservationIMU.h>

#include <algorithm>

#include "cairn/sources/decode.hpp"
#include "cairn/sources/rawlog_frames.hpp"
#include "cairn/sources/rawlog_source.hpp"

namespace cairn::sources {
namespace {

std::string FrameName(const Frame& f) {
  std::string name = "frame " + std::to_string(f.index) + " (";
  if (!f.label.empty()) name += "'" + f.label + "', ";
  return name + "entry " + std::to_string(f.entry) + ")";
}

Eigen::Vector3d UpIn(const Eigen::Isometry3d& T_world_sensor) {
  return T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
}

class RawlogFrames final : public FrameSource {
 public:
  RawlogFrames(std::string path, std::string label, const od::StereoConfig& stereo,
               Trajectory trajectory, std::vector<ImuAttitude> imu, std::vector<ImuSample> imu_raw,
               int total, RawlogSource source)
      : path_(std::move(path)),
        label_(std::move(label)),
        stereo_(stereo),
        trajectory_(std::move(trajectory)),
        imu_(std::move(imu)),
        imu_raw_(std::move(imu_raw)),
        total_(total),
        source_(std::move(source)) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    Expected<std::optional<Frame>> frame = source_.NextFrame();
    if (!frame) return frame.error();
    if (!*frame) return std::optional<SequenceFrame>();
    const Frame& f = **frame;
    SequenceFrame out;
    out.index = f.index;
    out.stamp_s = f.stamp_s;
    out.name = path_ + ": " + FrameName(f);
    // The IMU attitudes since the previous frame.
    while (next_imu_ < imu_.size() && !(imu_[next_imu_].stamp_s > f.stamp_s)) {
      out.imu.push_back(imu_[next_imu_++]);
    }
    while (next_raw_ < imu_raw_.size() && !(imu_raw_[next_raw_].stamp_s > f.stamp_s)) {
      out.imu_raw.push_back(imu_raw_[next_raw_++]);
    }
    Expected<BodyPose> body = trajectory_.PoseAt(f.stamp_s);
    if (!body) return Error{out.name + ": " + body.error().message};
    out.T_world_body = body->T_world_body;
    out.T_world_sensor = body->T_world_body * f.T_body_sensor;
    out.tilt_from_imu = body->tilt_from_imu;
    const Eigen::Vector3d up = UpIn(out.T_world_sensor);
    Expected<FrameImage> image = ToRangeImage(f, up, stereo_);
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(image->image);
    return std::optional<SequenceFrame>(std::move(out));
  }

  Status Skip(int n) override {
    for (int k = 0; k < n; ++k) {
      Expected<std::optional<Frame>> frame = source_.NextFrame();
      if (!frame) return frame.error();
      if (!*frame) return Error{path_ + ": holds fewer frames than the checkpoint fused"};
      while (next_imu_ < imu_.size() && !(imu_[next_imu_].stamp_s > (*frame)->stamp_s)) {
        ++next_imu_;
      }
      while (next_raw_ < imu_raw_.size() && !(imu_raw_[next_raw_].stamp_s > (*frame)->stamp_s)) {
        ++next_raw_;
      }
    }
    return {};
  }

  int total() const override { return total_; }
  SourceInfo Describe() const override {
    return {{"kind", std::string("rawlog")},
            {"path", path_},
            {"label", label_},
            {"frames", std::int64_t{total_}},
            {"poses", trajectory_.source()},
            {"imu_samples", static_cast<std::int64_t>(imu_.size())},
            {"imu_raw_samples", static_cast<std::int64_t>(imu_raw_.size())}};
  }
  const Trajectory& trajectory() const override { return trajectory_; }

 private:
  std::string path_, label_;
  od::StereoConfig stereo_;
  Trajectory trajectory_;
  std::vector<ImuAttitude> imu_;  // in file order
  std::size_t next_imu_ = 0;
  std::vector<ImuSample> imu_raw_;  // in file order
  std::size_t next_raw_ = 0;
  int total_ = 0;
  RawlogSource source_;
};

}  // namespace

Expected<std::unique_ptr<FrameSource>> OpenRawlogFrames(const std::string& path,
                                                        const std::string& label,
                                                        const od::StereoConfig& stereo) {
  SourceOptions scan;
  scan.label = label;
  scan.decode_frames = false;
  Expected<RawlogSource> first = RawlogSource::Open(path, scan);
  if (!first) return first.error();
  std::vector<ImuAttitude> imu;
  std::vector<ImuSample> imu_raw;
  std::vector<std::string> labels;
  int total = 0;
  while (true) {
    Expected<std::optional<SourceEntry>> entry = first->NextEntry();
    if (!entry) return entry.error();
    if (!*entry) break;
    for (const auto& o : (*entry)->observations) {
      if (const auto* m = dynamic_cast<const ::mrpt::obs::CObservationIMU*>(o.get())) {
        if (std::optional<ImuAttitude> a = DecodeImu(*m)) imu.push_back(*a);
        if (std::optional<ImuSample> r = DecodeImuSample(*m)) imu_raw.push_back(*r);
      }
      if (!IsRangeObservation(*o) || WhyNoRangeData(*o)) continue;
      if (std::find(labels.begin(), labels.end(), o->sensorLabel) == labels.end()) {
        labels.push_back(o->sensorLabel);
      }
      if (label.empty() || o->sensorLabel == label) ++total;
    }
  }
  if (total == 0) {
    std::string found = labels.empty() ? "none" : "";
    for (const std::string& l : labels) found += (found.empty() ? "'" : ", '") + l + "'";
    return Error{path + ": no range frames" +
                 (label.empty() ? std::string() : " with label '" + label + "'") +
                 " (range sensors in the file: " + found + ")"};
  }
  if (first->odometry().empty()) {
    return Error{path +
                 ": no odometry (CObservationOdometry or robot movement actions), so "
                 "the frames cannot be placed"};
  }
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(first->odometry(), imu);
  if (!trajectory) return Error{path + ": " + trajectory.error().message};
  SourceOptions read;
  read.label = label;
  Expected<RawlogSource> second = RawlogSource::Open(path, read);
  if (!second) return second.error();
  return std::unique_ptr<FrameSource>(
      std::make_unique<RawlogFrames>(path, label, stereo, std::move(*trajectory), std::move(imu),
                                     std::move(imu_raw), total, std::move(*second)));
}

}  // namespace cairn::sources
