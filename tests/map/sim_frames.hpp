// Synthetic frames for the map tests: a scene seen from a pose by libsim's range camera or
// LiDAR, run through the cone detector and the rules of config/default.yaml, with the
// rendered ground truth beside it.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "cairn/map/mapper_config_file.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::test {

inline std::filesystem::path SourceDir() { return CAIRN_SOURCE_DIR; }

/// config/default.yaml's detector and rules (one worker thread: tests run side by side).
inline Expected<od::io::DetectSettings> DefaultDetectSettings() {
  Expected<od::io::DetectSettings> settings = od::io::LoadDetectSettings(
      SourceDir() / "config" / "default.yaml", map::MapperSettingsSections());
  if (settings) settings->detector.threads = 1;
  return settings;
}

/// One frame ready for TerrainMap::Integrate, with its truth.
struct SimFrame {
  od::RangeImage image;
  od::Detection detection;
  od::Classification classification;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
  std::int64_t id = 0;
  std::vector<std::int32_t> object_id;  ///< per pixel: kTerrainId, an object id or kNoHitId

  Expected<map::FrameSummary> IntegrateInto(map::TerrainMap& m) const {
    return m.Integrate(image, detection, classification, T_world_sensor, stamp_s, id);
  }
};

inline Expected<SimFrame> Detected(od::RangeImage image, std::vector<std::int32_t> object_id,
                                   const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                   std::int64_t id, const od::io::DetectSettings& settings) {
  SimFrame f;
  f.image = std::move(image);
  f.object_id = std::move(object_id);
  f.T_world_sensor = T_world_sensor;
  f.stamp_s = stamp_s;
  f.id = id;
  Expected<od::Detection> detection = od::Detect(f.image, settings.detector);
  if (!detection) return detection.error();
  f.detection = std::move(*detection);
  Expected<od::Classification> classes = od::Classify(f.detection, settings.rules);
  if (!classes) return classes.error();
  f.classification = std::move(*classes);
  return f;
}

/// The range camera of `spec` at T_world_sensor (optical frame).
inline Expected<SimFrame> CameraFrame(const sim::Scene& scene, const sim::RangeCameraSpec& spec,
                                      const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                      std::int64_t id, const od::io::DetectSettings& settings,
                                      std::uint64_t seed = 1) {
  sim::Camera camera;
  camera.model = spec.model;
  camera.T_world_camera = T_world_sensor;
  Expected<sim::DepthFrame> frame = sim::RenderRangeCamera(scene, spec, camera, seed);
  if (!frame) return frame.error();
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(frame->depth_m, frame->model, frame->up_optical);
  if (!image) return image.error();
  return Detected(std::move(*image), frame->object_id, T_world_sensor, stamp_s, id, settings);
}

/// A spinning LiDAR at T_world_sensor (x forward, y left, z up).
inline Expected<SimFrame> LidarFrame(const sim::Scene& scene, const sim::LidarSpec& lidar,
                                     const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                     std::int64_t id, const od::io::DetectSettings& settings,
                                     std::uint64_t seed = 1) {
  Expected<sim::LidarScan> scan = sim::RenderLidar(scene, lidar, T_world_sensor, seed);
  if (!scan) return scan.error();
  od::SphericalModel model;
  model.width = lidar.azimuth_steps;
  model.ring_elevation_rad = lidar.elevations_rad;
  model.azimuth_start_rad = lidar.AzimuthRad(0);
  const Eigen::Vector3d up = T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
  Expected<od::RangeImage> image =
      od::RangeImage::FromPoints(scan->points, model, up, scan->ring, scan->column);
  if (!image) return image.error();
  std::vector<std::int32_t> ids(image->size(), sim::kNoHitId);
  for (std::size_t k = 0; k < scan->points.size(); ++k) {
    const std::int32_t cell = image->cell_of_point()[k];
    if (cell >= 0) ids[cell] = scan->object_id[k];
  }
  return Detected(std::move(*image), std::move(ids), T_world_sensor, stamp_s, id, settings);
}

/// A noiseless drive along `waypoints` over `terrain` (true poses; odometry unused).
inline Expected<sim::Drive> TrueDrive(const sim::Terrain& terrain,
                                      std::vector<Eigen::Vector2d> waypoints, double speed_mps,
                                      double rate_hz, double sensor_pitch_rad,
                                      sim::SensorFrame sensor = sim::SensorFrame::kCameraOptical) {
  sim::DriveSpec spec;
  spec.waypoints = std::move(waypoints);
  spec.speed_mps = speed_mps;
  spec.frame_rate_hz = rate_hz;
  spec.sensor_pitch_rad = sensor_pitch_rad;
  spec.odom_sigma_per_m = spec.odom_yaw_sigma_rad_per_m = 0.0;
  spec.imu_sigma_rad = spec.imu_bias_rad = 0.0;
  return sim::SimulateDrive(terrain, spec, sensor, 1);
}

}  // namespace cairn::test
