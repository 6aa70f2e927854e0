#include "cairn/sim/mrpt/sequence.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <future>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sim/mrpt/frame_files.hpp"
#include "cairn/sim/mrpt/rawlog.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "cairn/sources/rawlog_file.hpp"
#include "cairn/sources/trajectory.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/format.hpp"

namespace cairn::sim {
namespace {

namespace fs = std::filesystem;
std::string FrameName(int index) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "%06d", index);
  return buf;
}

// Drive frames draw their noise from a stream of seeds apart from the views'.
std::uint64_t DriveNoiseSeed(std::uint64_t world_seed, int frame) {
  return MixSeed(world_seed ^ 0x6472697665ULL, static_cast<std::uint64_t>(frame));  // "drive"
}

// The body's velocity in its own frame from two odometry poses dt apart: (vx, vy, omega).
Eigen::Vector3d LocalVelocity(const Pose2D& a, const Pose2D& b, double dt) {
  const double c = std::cos(a.yaw_rad), s = std::sin(a.yaw_rad);
  const double dx = b.x_m - a.x_m, dy = b.y_m - a.y_m;
  const double dyaw = std::remainder(b.yaw_rad - a.yaw_rad, 2.0 * 3.141592653589793);
  return Eigen::Vector3d(c * dx + s * dy, -s * dx + c * dy, dyaw) / dt;
}

std::string Vec3(const Eigen::Vector3d& v) {
  return "[" + util::Number(v.x()) + ", " + util::Number(v.y()) + ", " + util::Number(v.z()) + "]";
}

std::string Num(double v) { return util::Number(v); }

std::string SequenceYaml(const World& world, const Drive& drive, const DriveSpec& spec,
                         const SequenceOptions& options, const SequenceSummary& summary) {
  const bool camera = options.sensor == SensorFrame::kCameraOptical;
  const Eigen::Isometry3d& T = drive.T_body_sensor;
  const Eigen::Quaterniond q(T.linear());
  std::string y =
      "# A synthetic drive written by cairn synth --drive (see "
      "libsim/mrpt/include/cairn/sim/mrpt/sequence.hpp).\n";
  y += "world: \"" + world.name + "\"\n";
  y += "rawlog: " + summary.rawlog.filename().string() + "\n";
  y += std::string("sensor: ") + (camera ? "camera" : "lidar") + "\n";
  y += std::string("sensor_label: ") + (camera ? kCameraLabel : kLidarLabel) + "\n";
  y += std::string("sensor_frame: ") +
       (camera ? "optical  # x right, y down, z forward" : "lidar  # x forward, y left, z up") +
       "\n";
  y += "frames: " + std::to_string(summary.frames) + "\n";
  y += "frame_rate_hz: " + Num(spec.frame_rate_hz) + "\n";
  char stamp[64];
  std::snprintf(stamp, sizeof(stamp), "%.6f", options.start_unix_s);
  y += "first_stamp_s: " + std::string(stamp) + "  # Unix seconds of frame 0\n";
  y += "distance_m: " + Num(summary.distance_m) + "\n";
  y += "noise: " + std::string(options.noise ? "true" : "false") + "\n";
  y += "seed: " + std::to_string(world.seed) + "\n";
  y += "T_body_sensor:  # sensor frame on the body (x forward, y left, z up)\n";
  y += "  translation: " + Vec3(T.translation()) + "\n";
  y += "  quaternion_xyzw: [" + Num(q.x()) + ", " + Num(q.y()) + ", " + Num(q.z()) + ", " +
       Num(q.w()) + "]\n";
  y += "  sensor_pitch_deg: " + Num(spec.sensor_pitch_rad * kRadToDeg) + "\n";
  y += "drift:  # drawn once for this drive (drive.hpp)\n";
  y += "  odom_scale_error: " + Num(drive.errors.odom_scale_error) + "\n";
  y += "  odom_yaw_drift_deg_per_m: " + Num(drive.errors.odom_yaw_drift_rad_per_m * kRadToDeg) +
       "\n";
  y += "  imu_roll_bias_deg: " + Num(drive.errors.imu_roll_bias_rad * kRadToDeg) + "\n";
  y += "  imu_pitch_bias_deg: " + Num(drive.errors.imu_pitch_bias_rad * kRadToDeg) + "\n";
  y += "  imu_sigma_deg: " + Num(spec.imu_sigma_rad * kRadToDeg) + "\n";
  y += "files:\n";
  y += "  poses_body: " + summary.poses_body.filename().string() + "\n";
  y += "  poses_sensor: " + summary.poses_sensor.filename().string() + "\n";
  y += "  truth: truth/  # " +
       std::string(camera ? "NNNNNN.png object ids per pixel"
                          : "NNNNNN.label object id and NNNNNN.rowcol ring, column per point") +
       "\n";
  y += "  objects: " + summary.truth_yaml.filename().string() + "\n";
  return y;
}

}  // namespace

Expected<DepthFrame> RenderDriveCamera(const World& world, const Eigen::Isometry3d& T_world_camera,
                                       int frame, bool noise) {
  Camera camera;
  camera.model = world.camera.model;
  camera.T_world_camera = T_world_camera;
  if (noise) {
    return RenderRangeCamera(world.scene, world.camera, camera, DriveNoiseSeed(world.seed, frame));
  }
  RangeCameraSpec exact = world.camera;
  exact.noise = StereoNoise{};
  return RenderRangeCamera(world.scene, exact, camera, 0);
}

Expected<SequenceSummary> WriteDriveSequence(const World& world, const fs::path& dir,
                                             const SequenceOptions& options,
                                             const SequenceProgress& progress) {
  const std::string who = world.name.empty() ? std::string("world") : "world " + world.name;
  if (!world.drive) return Error{who + ": drive: missing (the world has no drive section)"};
  const bool camera = options.sensor == SensorFrame::kCameraOptical;
  if (!camera && !world.lidar) {
    return Error{who + ": lidar: missing (a LiDAR sequence needs the world's lidar section)"};
  }
  const DriveSpec& spec = *world.drive;
  Expected<Drive> simulated =
      SimulateDrive(world.scene.terrain(), spec, options.sensor, world.seed, options.max_frames,
                    options.imu);
  if (!simulated) return Error{who + ": " + simulated.error().message};
  const Drive& drive = *simulated;
  const int total = static_cast<int>(drive.samples.size());

  std::error_code ec;
  fs::create_directories(dir / "truth", ec);
  if (ec) return Error{(dir / "truth").string() + ": cannot create the directory: " + ec.message()};

  SequenceSummary summary;
  summary.rawlog = dir / "sequence.rawlog";
  summary.poses_body = dir / "poses_body.tum";
  summary.poses_sensor = dir / "poses_sensor.tum";
  summary.truth_yaml = dir / "truth.yaml";
  summary.sequence_yaml = dir / "sequence.yaml";
  Expected<sources::RawlogWriter> writer = sources::RawlogWriter::Create(summary.rawlog, options.gzip_level);
  if (!writer) return writer.error();

  // Frames render on other threads, a few ahead and in order of need, while this thread
  // encodes and writes them in sequence order. Renders only read the world.
  std::optional<LidarSpec> lidar = world.lidar;
  if (lidar && !options.noise) lidar->range_sigma_m = 0.0;
  struct Rendered {
    Expected<DepthFrame> depth = Error{"not rendered"};
    Expected<LidarScan> scan = Error{"not rendered"};
  };
  auto render = [&](int k) {
    Rendered out;
    const DriveSample& sample = drive.samples[k];
    if (camera) {
      out.depth = RenderDriveCamera(world, sample.T_world_sensor, k, options.noise);
    } else {
      out.scan =
          RenderLidar(world.scene, *lidar, sample.T_world_sensor, DriveNoiseSeed(world.seed, k));
    }
    return out;
  };
  const int in_flight_max = std::max(1, options.frames_in_flight);
  std::deque<std::future<Rendered>> in_flight;
  int launched = 0;

  std::vector<sources::StampedPose> body_poses, sensor_poses;
  std::size_t next_imu = 0;
  const double dt = 1.0 / spec.frame_rate_hz;
  for (int k = 0; k < total; ++k) {
    while (launched < total && static_cast<int>(in_flight.size()) < in_flight_max) {
      in_flight.push_back(std::async(std::launch::async, render, launched++));
    }
    Rendered rendered = in_flight.front().get();
    in_flight.pop_front();
    const DriveSample& sample = drive.samples[k];
    const double stamp_s = options.start_unix_s + sample.stamp_s;
    const ::mrpt::Clock::time_point stamp = sources::ToMrptTime(stamp_s);
    const std::string frame_name = FrameName(k);

    // Odometry and IMU, then the sensor's observation with its truth file.
    const Pose2D& from = drive.samples[k == 0 ? 0 : k - 1].odometry;
    const Pose2D& to = drive.samples[k == 0 ? std::min(1, total - 1) : k].odometry;
    const Eigen::Vector3d velocity =
        total > 1 ? LocalVelocity(from, to, dt) : Eigen::Vector3d::Zero();
    Status status;
    // Raw IMU samples up to this frame's time, before its observations.
    while (options.raw_imu && status && next_imu < drive.imu.size() &&
           drive.imu[next_imu].stamp_s <= sample.stamp_s) {
      const ImuReading& reading = drive.imu[next_imu++];
      status = writer->Write(*MakeRawImu(reading, drive.R_body_imu,
                                         sources::ToMrptTime(options.start_unix_s + reading.stamp_s)));
    }
    if (status) status = writer->Write(*MakeOdometry(sample.odometry, velocity, stamp));
    if (status) status = writer->Write(*MakeImu(sample.imu, stamp));
    if (!status) return status.error();
    if (camera) {
      if (!rendered.depth) {
        return Error{who + ": frame " + std::to_string(k) + ": " + rendered.depth.error().message};
      }
      const DepthFrame& frame = *rendered.depth;
      od::Grid<std::int32_t> ids;
      ids.width = frame.width();
      ids.height = frame.height();
      ids.data = frame.object_id;
      if (Status s = WriteObjectIdPng(dir / "truth" / (frame_name + ".png"), ids); !s) {
        return s.error();
      }
      float max_depth = 0.0f;
      for (float d : frame.depth_m) {
        if (std::isfinite(d) && d > max_depth) max_depth = d;
      }
      Expected<::mrpt::obs::CObservation3DRangeScan::Ptr> scan = MakeRangeScan(
          frame, drive.T_body_sensor, DepthScaleFor(max_depth), world.camera.max_range_m, stamp);
      if (!scan) return Error{who + ": frame " + std::to_string(k) + ": " + scan.error().message};
      if (Status s = writer->Write(**scan); !s) return s.error();
    } else {
      if (!rendered.scan) {
        return Error{who + ": frame " + std::to_string(k) + ": " + rendered.scan.error().message};
      }
      const LidarScan& scan = *rendered.scan;
      if (Status s = WriteLidarLabels(dir / "truth" / (frame_name + ".label"), scan); !s) {
        return s.error();
      }
      if (Status s = WriteLidarRowCol(dir / "truth" / (frame_name + ".rowcol"), scan); !s) {
        return s.error();
      }
      if (Status s = writer->Write(*MakePointCloud(scan, drive.T_body_sensor, stamp)); !s) {
        return s.error();
      }
    }
    body_poses.push_back({stamp_s, sample.T_world_body});
    sensor_poses.push_back({stamp_s, sample.T_world_sensor});
    summary.frames = k + 1;
    summary.distance_m = sample.distance_m;
    summary.duration_s = sample.stamp_s;
    if (progress) progress(k + 1, total);
  }

  const std::string about = "world " + world.name + ", " + std::to_string(summary.frames) +
                            " frames; stamps as in " + summary.rawlog.filename().string();
  if (Status s = sources::WriteTumPoses(summary.poses_body, body_poses,
                                        "T_world_body (x forward, y left, z up) of " + about);
      !s) {
    return s.error();
  }
  const std::string sensor_frame = camera ? "camera optical frame: x right, y down, z forward"
                                          : "LiDAR frame: x forward, y left, z up";
  if (Status s = sources::WriteTumPoses(summary.poses_sensor, sensor_poses,
                                        "T_world_sensor (" + sensor_frame + ") of " + about);
      !s) {
    return s.error();
  }
  if (Status s = WriteTruthYaml(summary.truth_yaml, world.scene); !s) return s.error();
  if (Status s = util::WriteFileAtomic(summary.sequence_yaml,
                                         SequenceYaml(world, drive, spec, options, summary));
      !s) {
    return s.error();
  }
  if (Status s = writer->Commit(); !s) return s.error();
  return summary;
}

}  // namespace cairn::sim
