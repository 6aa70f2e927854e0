// A rawlog as a source of frames: every range observation of the selected sensor decoded
// (decode.hpp), with the odometry pose and IMU attitude known when it was taken.
//
// Odometry comes from CObservationOdometry (observations format) and from the robot
// movement actions of sensory-frame files. Actions are increments between sensory frames:
// in "SF0, A0, SF1, A1, SF2, ..." A_k moves the robot from where it observed SF_k to where
// it observed SF_k+1. Their poses are composed from the identity at SF0 (the mean of each
// CActionRobotMovement3D, else CActionRobotMovement2D, of a collection) into one stream
// T_odom_body, each stamped with its action's timestamp, or, when the action has none (as in
// MRPT's sample files), with the time of the sensory frame that follows it; a trailing
// action with no frame after it takes the last time seen in the file.
//
// Errors name the file and the entry (0-based position of the top-level object).
#pragma once

#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CObservation.h>

#include <deque>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sources/decode.hpp"
#include "cairn/sources/frame.hpp"
#include "cairn/sources/rawlog_file.hpp"

namespace cairn::sources {

struct SourceOptions {
  std::string label;  ///< decode range observations of this sensor label only; empty: all
  DecodeOptions decode;
  /// false: entries carry their observations but no frames (nothing is decoded, nothing
  /// skipped), for tools that look at the objects themselves.
  bool decode_frames = true;
};

/// A range observation that holds no range data (see WhyNoRangeData).
struct SkippedObservation {
  int entry = -1;
  std::string label, mrpt_class, reason;
};

/// One top-level object, its observations and the frames decoded from them.
struct SourceEntry {
  RawlogEntry raw;
  /// The object itself when it is an observation, a sensory frame's observations, or none
  /// (action collections).
  std::vector<::mrpt::obs::CObservation::Ptr> observations;
  std::vector<Frame> frames;
  std::vector<int> frame_observation;  ///< for each frame, its index in `observations`
};

class RawlogSource {
 public:
  static Expected<RawlogSource> Open(const std::filesystem::path& path,
                                     const SourceOptions& options = {});

  /// The next top-level object, decoded; nullopt at the end. Fails on a corrupt or
  /// truncated file, an object that is no observation, sensory frame or action collection,
  /// or a range observation that cannot be decoded.
  Expected<std::optional<SourceEntry>> NextEntry();

  /// The next range frame of the selected sensor; nullopt at the end. Fails like NextEntry.
  Expected<std::optional<Frame>> NextFrame();

  /// Odometry poses read so far, in file order (observations and integrated actions).
  const std::vector<OdometrySample>& odometry() const { return odometry_; }
  /// Range observations of the selected sensor skipped for holding no range data.
  const std::vector<SkippedObservation>& skipped() const { return skipped_; }
  int entries_read() const { return reader_.entries_read(); }
  int frames_read() const { return frames_; }
  const std::filesystem::path& path() const { return reader_.path(); }

 private:
  RawlogSource(RawlogReader reader, SourceOptions options)
      : reader_(std::move(reader)), options_(std::move(options)) {}
  void NoteStamp(double stamp_s);
  void Observe(const ::mrpt::obs::CObservation& observation);
  void Act(const ::mrpt::obs::CActionCollection& actions);
  void FlushPendingAction(double stamp_s);

  RawlogReader reader_;
  SourceOptions options_;
  std::vector<OdometrySample> odometry_;
  std::vector<SkippedObservation> skipped_;
  std::optional<OdometrySample> last_odometry_;
  std::optional<ImuAttitude> last_imu_;
  std::vector<ImuSample> imu_samples_;  ///< raw samples since the last frame
  // Actions: the composed pose, and the last one while it waits for its frame's stamp.
  Eigen::Isometry3d T_odom_body_actions_ = Eigen::Isometry3d::Identity();
  bool actions_started_ = false;
  std::optional<OdometrySample> pending_action_;
  double last_frame_stamp_s_ = kNoStamp;  ///< of the last sensory frame
  double last_stamp_s_ = kNoStamp;        ///< of anything
  std::deque<Frame> pending_frames_;
  int frames_ = 0;
};

}  // namespace cairn::sources
