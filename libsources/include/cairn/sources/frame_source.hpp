// FrameSource: a recorded sequence handed out one frame at a time, each frame a range image
// placed in the world, for the Mapper (cairn/map/mapper.hpp) or any per-frame loop.
//
//   OpenRawlogFrames       an MRPT rawlog (cairn::sources_mrpt, rawlog_frames.hpp)
//   OpenKittiFrames        a KITTI odometry sequence: velodyne scans placed by poses.txt
//   OpenDepthFolderFrames  a folder of 16-bit depth PNGs with a TUM file of the camera's
//                          poses (optical frame, z-up world): files named by their stamp
//                          (TUM RGB-D's "1305031102.160407.png") are placed at that time,
//                          otherwise the k-th file (by name) takes the k-th pose
//   OpenStereoFolderFrames a folder of stereo pairs (left/ and right/ PNGs of the same
//                          names) with the rig's calibration and a TUM file of the left
//                          camera's poses, each pair matched into depth (od::ComputeStereoDepth)
//
// Nothing is skipped in silence: a frame the source knows of but cannot read as a frame
// comes back with its reason (SourceSkip) and no image, so that the caller names and counts
// it. A KITTI scan missing from velodyne/ (poses.txt, or the scans around it, say it should
// be there) is kMissing; a scan file of no whole point (empty, or a size not a multiple of
// 16 bytes) is kTruncated. Files that are there but corrupt are errors, naming the file.
//
// Each image is levelled with its pose's up vector (world z up); frames, units and
// conventions as frame.hpp and trajectory.hpp state them. Nothing is printed.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/sources/frame.hpp"
#include "cairn/sources/trajectory.hpp"

namespace cairn::sources {

/// Why a source hands out a frame without an image.
enum class SourceSkip {
  kNone,
  kMissing,    ///< the frame's file is not there
  kTruncated,  ///< the frame's file holds no whole record
};

/// "none" | "missing" | "truncated".
const char* SourceSkipName(SourceSkip skip);

/// One frame of a sequence, placed in the world.
struct SequenceFrame {
  int index = 0;  ///< among the source's frames (0-based), skipped ones included
  double stamp_s = 0.0;
  std::string name;  ///< for messages: "FILE: frame 3 ('CAMERA', entry 12)", a file name
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  bool tilt_from_imu = false;  ///< the pose's roll and pitch came from an IMU
  /// IMU attitudes of the recording since the previous frame (rawlogs), by stamp.
  std::vector<ImuAttitude> imu;
  /// Raw IMU samples (accelerometer, gyro) since the previous frame (rawlogs), by stamp, in
  /// the IMU's frame with its T_body_imu.
  std::vector<ImuSample> imu_raw;
  od::RangeImage image;  ///< sensor frame, levelled with T_world_sensor's up; empty if skipped
  SourceSkip skip = SourceSkip::kNone;
  std::string skip_detail;  ///< what was found ("7 bytes, not a whole 16-byte point")

  bool used() const { return skip == SourceSkip::kNone; }
  /// The sensor's pose on the body: T_world_body^-1 T_world_sensor.
  Eigen::Isometry3d T_body_sensor() const { return T_world_body.inverse() * T_world_sensor; }
};

/// What a source reads, for summaries and for telling two runs' inputs apart: "kind",
/// "path", "frames", "poses", and per kind "label" and "imu_samples" (rawlog), "lidar"
/// (KITTI).
using SourceInfo = std::map<std::string, std::variant<std::string, std::int64_t>>;

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// The next frame (skipped ones included), or nullopt at the end.
  virtual Expected<std::optional<SequenceFrame>> Next() = 0;
  /// Passes over the next `n` frames without making their range images (a resumed run).
  virtual Status Skip(int n) = 0;
  /// Frames the source will give, skipped ones included.
  virtual int total() const = 0;
  virtual SourceInfo Describe() const = 0;
  /// Where the frames' poses come from.
  virtual const Trajectory& trajectory() const = 0;
};

/// A KITTI odometry sequence folder (or DIR/sequences/NN when `sequence` is given), its scans
/// `range` ("A:B", see od::io::SelectKittiFrames; empty: all), read as LiDAR preset `lidar`.
/// Fails, naming the file, without poses.txt, on an unknown preset or a bad range.
Expected<std::unique_ptr<FrameSource>> OpenKittiFrames(const std::string& dir,
                                                       const std::string& sequence,
                                                       const std::string& range,
                                                       const std::string& lidar);

/// A folder of depth PNGs with their TUM poses and the camera YAML (default
/// DIR/intrinsics.yaml). Fails, naming the file, on no images, unreadable poses or
/// intrinsics, or unnamed images whose count differs from the poses'.
Expected<std::unique_ptr<FrameSource>> OpenDepthFolderFrames(const std::string& dir,
                                                             const std::string& poses,
                                                             const std::string& intrinsics);

/// True when `dir` holds left/ and right/ folders (a stereo folder, not a depth folder).
bool IsStereoFolder(const std::string& dir);

/// A folder of stereo pairs: DIR/left/*.png and DIR/right/*.png of the same names (named by
/// their stamps, or the k-th pair taking the k-th pose, as depth folders), the TUM poses of
/// the left camera's optical frame in a z-up world, and the rig's calibration in any format
/// od::io::LoadStereoCalibration reads (default DIR/stereo.yaml; raw pairs are rectified).
/// Each pair is matched with `stereo` into the left camera's depth. Fails, naming the file,
/// on no pairs, a left image without its right one, unreadable poses or calibration, or a
/// bad `stereo`.
Expected<std::unique_ptr<FrameSource>> OpenStereoFolderFrames(const std::string& dir,
                                                              const std::string& poses,
                                                              const std::string& calibration,
                                                              const od::StereoConfig& stereo);

/// `source` read one frame ahead: while the caller works on a frame, the next is read (file,
/// decoding, range image) on a thread of its own, so that reading overlaps the Mapper's
/// work. The same frames in the same order, the same skips and errors, each when the
/// caller reaches it; after an error or the end nothing more is read. A frame read ahead
/// and not taken is read for nothing (a run that stops early).
std::unique_ptr<FrameSource> ReadAhead(std::unique_ptr<FrameSource> source);

}  // namespace cairn::sources
