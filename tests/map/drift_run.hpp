// Mapping a gallery world (datasets/worlds) from the poses a robot would believe: libsim's
// drifting 2-D odometry and biased IMU, optionally with the Ceres tilt refiner, and scoring
// the map against the world's truth. Shared by map_drift_test (the claims) and
// cairn_map_report (datasets/maps/REPORT.md).
//
// The believed pose of the body: x, y, yaw from odometry; roll and pitch from the IMU; height
// dead-reckoned from the odometry steps and the IMU pitch (dz = -d tan(pitch), trapezoid),
// starting at the true height (odometry starts at the true pose). The sensor renders from
// the TRUE pose; the range image is levelled with the believed up vector and the frame is
// fused at the believed pose, as on a real robot.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "cairn/map/gravity_cues.hpp"
#include "cairn/map/mapper.hpp"
#include "cairn/map/terrain_map.hpp"
#include "cairn/sim/render.hpp"
#include "sim_frames.hpp"

namespace cairn::test {

constexpr double kDriftDeg = 3.14159265358979323846 / 180.0;

/// One mapping run.
struct DriftRunSpec {
  std::string world;                       ///< file stem in datasets/worlds
  std::vector<Eigen::Vector2d> waypoints;  ///< world xy [m]
  bool true_poses = false;                 ///< fuse at the true poses (no odometry, no IMU)
  double odom_sigma_per_m = 0.0;           ///< libsim DriveSpec::odom_sigma_per_m
  double odom_yaw_sigma_rad_per_m = 0.0;   ///< libsim DriveSpec::odom_yaw_sigma_rad_per_m
  double imu_bias_rad = 0.0;               ///< constant roll and pitch bias
  double imu_sigma_rad = 0.0;              ///< the IMU attitude output's noise
  bool refine_tilt = false;                ///< Ceres tilt refiner on the believed pose
  bool gravity = false;                    ///< the gravity estimator (takes over refine_tilt)
  /// The floor of every tilt mode: roll, pitch and height true, x, y and heading from the
  /// odometry (what is left is the odometry's horizontal drift).
  bool truth_tilt_height = false;
  /// Raw IMU errors (accelerometer and gyro bias and noise, misalignment) and the sensor's
  /// mount misalignment; the raw samples reach the Mapper in every mode.
  sim::ImuSpec imu;
  Eigen::Vector3d sensor_misalignment_rad = Eigen::Vector3d::Zero();  ///< roll, pitch, yaw
  bool measure_cues = false;  ///< score the vertical cues (gravity_cues.hpp) of every frame
  std::uint64_t drive_seed = 1;            ///< draws the drift of the drive
  double rate_hz = 2.0;
  double speed_mps = 2.0;
  int camera_width = 160;  ///< 160 x 120 range camera
  /// Changes the Mapper's settings before it is made (studies); may be empty.
  std::function<void(map::MapperConfig&)> configure;
  /// Called with every frame's record and its true sample (diagnostics); may be empty.
  std::function<void(const map::MapperRecord&, const sim::DriveSample&)> on_frame;
};

/// Odometry that drifts by `fraction` of the distance (sigma of the scale error) and, in
/// proportion, 0.5 deg of heading per 10 m at 1 %.
inline void DriftOdometryBy(DriftRunSpec& spec, double fraction) {
  spec.odom_sigma_per_m = fraction;
  spec.odom_yaw_sigma_rad_per_m = fraction * 0.5 * kDriftDeg / 0.1;
}

/// One seen obstacle (30 pixels or more in some frame) against the map.
struct ObstacleScore {
  std::string name;
  double first_seen_distance_m = 0.0;  ///< distance driven at the first frame seeing it well
  double nearest_lethal_m = 1e9;       ///< from its true cells to the nearest lethal cell [m]
};

/// Believed pose against the truth, per frame.
struct PoseError {
  double distance_m = 0.0;  ///< driven so far
  double position_m = 0.0;  ///< horizontal error of the believed sensor position [m]
  double yaw_rad = 0.0;     ///< |heading error|
  double tilt_rad = 0.0;    ///< angle between the believed and true up vectors
  double z_m = 0.0;         ///< |height error| of the sensor [m]
};

struct DriftRunResult {
  explicit DriftRunResult(map::Mapper m) : mapper(std::move(m)) {}
  map::Mapper mapper;  ///< the run's Mapper, its map fused
  const map::TerrainMap& map() const { return mapper.map(); }
  int frames = 0;
  double distance_m = 0.0;
  int refined_frames = 0;
  // Scores.
  double iou = 0.0;
  int lethal = 0, truth = 0;
  int false_lethal = 0;  ///< lethal cells more than 0.5 m from every true obstacle cell
  std::vector<ObstacleScore> obstacles;
  double max_distance_m = 0.0, mean_distance_m = 0.0;  ///< over `obstacles`
  int found_0_3 = 0;                                   ///< of which within 0.3 m
  double elevation_rms_m = 0.0;
  int elevation_cells = 0;
  /// Every fused frame's terrain returns within map.max_range (every 4th pixel): the height
  /// they were fused at against the true terrain under their true position [m]. Unlike
  /// elevation_rms_m, which compares the grid with the terrain at the same x, y, it leaves
  /// out the odometry's horizontal drift: it is the error the fused pose's tilt and height
  /// put into the map.
  double ground_height_rms_m = 0.0;
  std::vector<PoseError> pose_errors;
  /// measure_cues: each vertical cue's angle from the true vertical (a wall normal's from
  /// the horizontal) [rad].
  std::vector<double> cue_errors_rad;
  /// Gravity mode: frames whose estimate flagged a state as not observable, and the reasons
  /// of the last frame's flags.
  int degenerate_frames = 0;
  std::vector<std::string> last_degeneracies;
  std::set<std::pair<int, int>> truth_cells;  ///< true obstacle cells (for figures)
  std::string error;                          ///< non-empty when the run failed
};

inline double TiltBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  const Eigen::Vector3d up_a = R_a.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_b = R_b.transpose() * Eigen::Vector3d::UnitZ();
  return std::atan2(up_a.cross(up_b).norm(), up_a.dot(up_b));
}

namespace detail {


inline double CellDistance(const std::pair<int, int>& a, const std::pair<int, int>& b, double s) {
  return std::hypot(a.first - b.first, a.second - b.second) * s;
}

// truth_tilt_height: fuses the odometry's x, y and heading with the true roll, pitch and
// height of `*truth` (set before each frame; shared, so that the step never outlives it).
class TruthTiltStep final : public map::TiltStep {
 public:
  explicit TruthTiltStep(std::shared_ptr<const Eigen::Isometry3d> truth)
      : truth_(std::move(truth)) {}
  map::TiltMode mode() const override { return map::TiltMode::kPrior; }
  bool UsesGroundPoints() const override { return false; }
  Eigen::Isometry3d Prior(const Eigen::Isometry3d& odometry) const override {
    const auto heading = [](const Eigen::Matrix3d& R) {
      // The heading of the sensor's viewing direction (optical z) on the level plane.
      return std::atan2(R(1, 2), R(0, 2));
    };
    Eigen::Isometry3d T = *truth_;
    T.linear() = Eigen::AngleAxisd(heading(odometry.linear()) - heading(truth_->linear()),
                                   Eigen::Vector3d::UnitZ()) *
                 truth_->linear();
    T.translation().head<2>() = odometry.translation().head<2>();
    return T;
  }
  Expected<map::TiltOutcome> Estimate(const map::TiltFrame& frame, const map::TerrainMap&) override {
    map::TiltOutcome out;
    out.T_world_sensor = Prior(frame.T_world_sensor_odometry);
    out.applied = true;
    return out;
  }
  std::string SaveState() const override { return {}; }
  Status RestoreState(const std::string&) override { return {}; }

 private:
  std::shared_ptr<const Eigen::Isometry3d> truth_;
};

// Scores the map of `r` against the world (same measures as terrain_map_sim_test).
inline void Score(const sim::World& world, const std::map<int, int>& pixels_seen,
                  const std::map<int, double>& first_seen_m, DriftRunResult& r) {
  const map::TerrainGrid& grid = r.map().grid();
  const double s = grid.cell_size();
  const std::optional<map::CellBox> box = r.map().ObservedBounds();
  if (!box) {
    r.error = "nothing observed";
    return;
  }
  const TrueCells true_cells = TrueCellsOf(world.scene, grid, *box);
  const std::map<int, CellSet>& objects = true_cells.obstacles;
  const CellSet& near_object = true_cells.near_object;
  r.truth_cells = true_cells.all;
  CellSet lethal;
  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      if (grid.At({i, j}).lethal) lethal.insert({i, j});
    }
  }
  int both = 0;
  for (const auto& c : lethal) both += static_cast<int>(r.truth_cells.count(c));
  r.lethal = static_cast<int>(lethal.size());
  r.truth = static_cast<int>(r.truth_cells.size());
  const int union_cells = r.lethal + r.truth - both;
  r.iou = union_cells > 0 ? both / static_cast<double>(union_cells) : 0.0;
  for (const auto& c : lethal) {
    double nearest = 1e9;
    for (const auto& t : r.truth_cells) nearest = std::min(nearest, CellDistance(c, t, s));
    r.false_lethal += nearest > 0.5;
  }
  double sum = 0.0;
  for (const auto& [id, cells] : objects) {
    const sim::Object* object = world.scene.Find(id);
    const auto seen = pixels_seen.find(id);
    if (seen == pixels_seen.end() || seen->second < 30) continue;
    ObstacleScore o;
    o.name = object->name;
    o.first_seen_distance_m = first_seen_m.at(id);
    for (const auto& c : cells) {
      for (const auto& l : lethal)
        o.nearest_lethal_m = std::min(o.nearest_lethal_m, CellDistance(c, l, s));
    }
    r.max_distance_m = std::max(r.max_distance_m, o.nearest_lethal_m);
    sum += o.nearest_lethal_m;
    r.found_0_3 += o.nearest_lethal_m <= 0.3;
    r.obstacles.push_back(o);
  }
  r.mean_distance_m = r.obstacles.empty() ? 0.0 : sum / r.obstacles.size();
  // Elevation against the terrain, away from every object.
  double sum2 = 0.0;
  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      const map::Cell& cell = grid.At({i, j});
      if (!cell.has_elevation() || near_object.count({i, j}) != 0) continue;
      const Eigen::Vector2d c = grid.CentreOf({i, j});
      const double e = cell.elevation_mean_m - world.scene.terrain().Height(c.x(), c.y());
      sum2 += e * e;
      ++r.elevation_cells;
    }
  }
  r.elevation_rms_m = std::sqrt(sum2 / std::max(1, r.elevation_cells));
}

}  // namespace detail

/// A gallery world by its stem, or any world file by its path (ending in .yaml, relative to
/// the source tree).
inline Expected<sim::World> LoadGalleryWorld(const std::string& name) {
  if (name.size() > 5 && name.compare(name.size() - 5, 5, ".yaml") == 0) {
    return sim::LoadWorld((SourceDir() / name).string());
  }
  return sim::LoadWorld((SourceDir() / "datasets" / "worlds" / (name + ".yaml")).string());
}

/// Drives, maps and scores one run through the Mapper (prior tilt, or the tilt refiner).
/// Fails on a world that does not load or a frame that does not render or fuse.
inline Expected<DriftRunResult> RunDrift(const DriftRunSpec& spec) {
  Expected<sim::World> world = LoadGalleryWorld(spec.world);
  if (!world) return world.error();
  const Expected<od::io::DetectSettings> settings = DefaultDetectSettings();
  if (!settings) return settings.error();
  map::MapperConfig config;
  config.detector = settings->detector;
  config.rules = settings->rules;
  config.tilt.mode = spec.true_poses   ? map::TiltMode::kPrior
                     : spec.gravity     ? map::TiltMode::kGravity
                     : spec.refine_tilt ? map::TiltMode::kRefineToMap
                                        : map::TiltMode::kPrior;
  if (spec.configure) spec.configure(config);
  // truth_tilt_height: the true pose of the frame being fused.
  const auto truth_now = std::make_shared<Eigen::Isometry3d>(Eigen::Isometry3d::Identity());
  Expected<map::Mapper> mapper =
      spec.truth_tilt_height
          ? map::Mapper::Create(config, std::make_unique<detail::TruthTiltStep>(truth_now))
          : map::Mapper::Create(config);
  if (!mapper) return mapper.error();

  sim::DriveSpec drive_spec;
  drive_spec.waypoints = spec.waypoints;
  drive_spec.speed_mps = spec.speed_mps;
  drive_spec.frame_rate_hz = spec.rate_hz;
  drive_spec.sensor_pitch_rad = 8.0 * kDriftDeg;
  drive_spec.odom_sigma_per_m = spec.odom_sigma_per_m;
  drive_spec.odom_yaw_sigma_rad_per_m = spec.odom_yaw_sigma_rad_per_m;
  drive_spec.imu_sigma_rad = spec.imu_sigma_rad;
  drive_spec.imu_bias_rad = spec.imu_bias_rad;
  drive_spec.sensor_misalignment_rad = spec.sensor_misalignment_rad;
  const Expected<sim::Drive> drive =
      sim::SimulateDrive(world->scene.terrain(), drive_spec, sim::SensorFrame::kCameraOptical,
                         spec.drive_seed, 0, spec.imu);
  if (!drive) return drive.error();
  if (Status st = (*mapper).SetSensorMount(drive->T_body_sensor); !st) return st.error();
  const sim::RangeCameraSpec camera_spec = SmallCamera(world->camera, spec.camera_width);

  std::map<int, int> pixels_seen;
  std::map<int, double> first_seen_m;
  std::vector<PoseError> pose_errors;
  std::vector<double> cue_errors_rad;
  int degenerate_frames = 0;
  std::vector<std::string> last_degeneracies;
  int refined_frames = 0;
  double distance_m = 0.0;
  double z_body = 0.0;  // dead reckoning
  double ground_sum2 = 0.0;  // ground_height_rms_m
  long ground_n = 0;
  const sim::DriveSample* previous = nullptr;
  std::size_t next_imu = 0;
  for (const sim::DriveSample& s : drive->samples) {
    // The raw IMU samples since the previous frame, rotated into the body frame.
    std::vector<map::ImuSample> imu = BodyImuUpTo(*drive, s.stamp_s, &next_imu);
    // The believed pose.
    Eigen::Isometry3d T_world_sensor = s.T_world_sensor;
    if (!spec.true_poses) {
      if (previous == nullptr) {
        z_body = s.T_world_body.translation().z();
      } else {
        const double d = std::hypot(s.odometry.x_m - previous->odometry.x_m,
                                    s.odometry.y_m - previous->odometry.y_m);
        z_body -= d * std::tan(0.5 * (s.imu.pitch_rad + previous->imu.pitch_rad));
      }
      Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
      T_world_body.linear() =
          sim::RotationFromAttitude({s.imu.roll_rad, s.imu.pitch_rad, s.odometry.yaw_rad});
      T_world_body.translation() = Eigen::Vector3d(s.odometry.x_m, s.odometry.y_m, z_body);
      T_world_sensor = T_world_body * drive->T_body_sensor;
    }
    previous = &s;
    // Render from the true pose; the Mapper levels with the believed up vector (and the
    // correction the refiner carries).
    sim::Camera camera;
    camera.model = camera_spec.model;
    camera.T_world_camera = s.T_world_sensor;
    const std::uint64_t seed = sim::MixSeed(world->seed, static_cast<std::uint64_t>(s.index));
    Expected<sim::DepthFrame> rendered =
        sim::RenderRangeCamera(world->scene, camera_spec, camera, seed);
    if (!rendered) return rendered.error();
    const Eigen::Vector3d up = T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    Expected<od::RangeImage> image =
        od::RangeImage::FromDepth(rendered->depth_m, rendered->model, up);
    if (!image) return image.error();
    if (spec.measure_cues) {  // the vertical cues the gravity step would see, against the truth
      Expected<od::Detection> detection = od::Detect(*image, config.detector);
      if (!detection) return detection.error();
      Expected<od::Classification> classes = od::Classify(*detection, config.rules);
      if (!classes) return classes.error();
      const Eigen::Vector3d up_true =
          s.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
      for (const map::VerticalCue& c : map::FindVerticalCues(*image, *detection, *classes,
                                                             image->up(), config.tilt.verticals)) {
        const double a = std::acos(std::min(1.0, std::abs(c.direction_sensor.dot(up_true))));
        cue_errors_rad.push_back(c.wall_normal ? std::abs(0.5 * M_PI - a) : a);
      }
    }
    // The terrain returns (sensor frame) for ground_height_rms_m.
    std::vector<Eigen::Vector3d> terrain_returns;
    for (int i = 0; i < image->size(); i += 4) {
      if (image->valid(i) && rendered->object_id[i] == sim::kTerrainId &&
          image->point(i).norm() <= config.map.max_range_m) {
        terrain_returns.push_back(image->point(i));
      }
    }
    *truth_now = s.T_world_sensor;
    Expected<map::MapperRecord> record =
        (*mapper).Process(std::move(*image), T_world_sensor, s.stamp_s, imu);
    if (!record) return record.error();
    if (!record->used()) {
      return Error{spec.world + ": frame " + std::to_string(s.index) + " skipped: " +
                   map::FrameSkipName(record->skip) + " (" + record->skip_detail + ")"};
    }
    if (spec.on_frame) spec.on_frame(*record, s);
    refined_frames += record->tilt.applied ? 1 : 0;
    if (record->tilt.gravity) {
      degenerate_frames += record->tilt.gravity->degeneracies.empty() ? 0 : 1;
      last_degeneracies.clear();
      for (const map::GravityDegeneracy& d : record->tilt.gravity->degeneracies) {
        last_degeneracies.push_back(d.reason);
      }
    }
    std::map<int, int> pixels;
    for (const std::int32_t object : rendered->object_id) {
      if (object > 0) ++pixels[object];
    }
    for (const auto& [object, n] : pixels) {
      pixels_seen[object] = std::max(pixels_seen[object], n);
      if (n >= 30 && first_seen_m.count(object) == 0) first_seen_m[object] = s.distance_m;
    }
    const Eigen::Isometry3d& fused = record->T_world_sensor;
    for (const Eigen::Vector3d& p : terrain_returns) {
      const Eigen::Vector3d at = s.T_world_sensor * p;
      const double e = (fused * p).z() - world->scene.terrain().Height(at.x(), at.y());
      ground_sum2 += e * e;
      ++ground_n;
    }
    PoseError e;
    e.distance_m = s.distance_m;
    e.position_m = (fused.translation() - s.T_world_sensor.translation()).head<2>().norm();
    const Eigen::Vector3d fwd_true = s.T_world_body.linear().col(0);
    const double yaw_true = std::atan2(fwd_true.y(), fwd_true.x());
    e.yaw_rad =
        spec.true_poses ? 0.0 : std::abs(std::remainder(s.odometry.yaw_rad - yaw_true, 2.0 * M_PI));
    e.tilt_rad = TiltBetween(fused.linear(), s.T_world_sensor.linear());
    e.z_m = std::abs(fused.translation().z() - s.T_world_sensor.translation().z());
    pose_errors.push_back(e);
    distance_m = s.distance_m;
  }
  DriftRunResult r(std::move(*mapper));
  r.frames = static_cast<int>(r.mapper.frames_fused());
  r.distance_m = distance_m;
  r.refined_frames = refined_frames;
  r.ground_height_rms_m = std::sqrt(ground_sum2 / std::max(1L, ground_n));
  r.pose_errors = std::move(pose_errors);
  r.cue_errors_rad = std::move(cue_errors_rad);
  r.degenerate_frames = degenerate_frames;
  r.last_degeneracies = std::move(last_degeneracies);
  detail::Score(*world, pixels_seen, first_seen_m, r);
  if (!r.error.empty()) return Error{spec.world + ": " + r.error};
  return r;
}

}  // namespace cairn::test
