// A world's drive written as a sequence that every later command reads like real data:
//
//   DIR/sequence.rawlog    MRPT rawlog, observations format (see rawlog.hpp); per frame, in
//                          this order: ODOMETRY, IMU, then CAMERA or LIDAR, one timestamp
//   DIR/poses_body.tum     true T_world_body per frame (TUM: stamp tx ty tz qx qy qz qw),
//                          stamps equal to the rawlog's (Unix seconds)
//   DIR/poses_sensor.tum   true T_world_sensor: the camera's optical frame (x right, y down,
//                          z forward) or the LiDAR frame (x forward, y left, z up)
//   DIR/truth/NNNNNN.png   camera: object id per pixel (truth.png convention, frame_files.hpp)
//   DIR/truth/NNNNNN.label LiDAR: uint32 object id per point, in the cloud's order, and
//   DIR/truth/NNNNNN.rowcol  uint16 ring and column per point
//   DIR/truth.yaml         the objects: id, name, is_obstacle, height_m
//   DIR/sequence.yaml      what was written: world, sensor, frames, rate, first stamp, the
//                          mount T_body_sensor, the drifts drawn, the noise settings
//
// The world frame is the one of the world file; the odometry frame equals it at frame 0.
// Every file is written to a temporary name and renamed; the rawlog is renamed last, so a
// directory with a sequence.rawlog holds a whole sequence.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "cairn/od/expected.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {

struct SequenceOptions {
  SensorFrame sensor = SensorFrame::kCameraOptical;  ///< kLidar needs world.lidar
  int max_frames = 0;                                ///< 0 = the whole drive
  double start_unix_s = 1704067200.0;  ///< stamp of frame 0 [s] (2024-01-01T00:00:00Z)
  int gzip_level = 1;                  ///< 0 = plain rawlog, 1 (fast) .. 9 (small)
  bool noise = true;                   ///< the world's sensor noise; false: exact ranges
  /// Frames rendered at once, ahead of the writer (each render is parallel inside already);
  /// the output does not depend on it.
  int frames_in_flight = 2;
  /// Also write the raw IMU samples (MakeRawImu, label "IMU"), each before the frame that
  /// follows it in time; `imu` sets their rate and errors. Off: the rawlog holds three
  /// observations per frame, as before.
  bool raw_imu = false;
  ImuSpec imu;
};

struct SequenceSummary {
  std::filesystem::path rawlog;
  std::filesystem::path poses_body;
  std::filesystem::path poses_sensor;
  std::filesystem::path truth_yaml;
  std::filesystem::path sequence_yaml;
  int frames = 0;
  double distance_m = 0.0;  ///< driven, planar [m]
  double duration_s = 0.0;  ///< first to last stamp [s]
};

/// Called after each frame is written with (frames done, frames in all).
using SequenceProgress = std::function<void(int done, int total)>;

/// Simulates the world's drive (SimulateDrive, seeded by world.seed) and writes it into `dir`
/// (created when missing). Fails, naming the field or the file, when the world has no
/// drive, kLidar is asked of a world without a LiDAR, a frame cannot be rendered or a file
/// cannot be written; a failed run leaves no sequence.rawlog behind.
Expected<SequenceSummary> WriteDriveSequence(const World& world, const std::filesystem::path& dir,
                                             const SequenceOptions& options = {},
                                             const SequenceProgress& progress = {});

/// The depth frame the drive's camera sees from T_world_camera (RenderRangeCamera): with the
/// world's camera noise, seeded by world.seed and `frame` (a stream apart from the views'),
/// or exact.
Expected<DepthFrame> RenderDriveCamera(const World& world, const Eigen::Isometry3d& T_world_camera,
                                       int frame, bool noise);

}  // namespace cairn::sim
