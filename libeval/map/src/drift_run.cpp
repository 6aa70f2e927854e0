#include "cairn/eval/drift_run.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <utility>

#include "cairn/map/gravity_cues.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::eval {
namespace {

// DriftRunSpec::truth_tilt_height: fuses the odometry's x, y and heading with the true roll, pitch
// and height of `*truth` (set before each frame; shared, so that the step never outlives it).
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
  Expected<map::TiltOutcome> Estimate(const map::TiltFrame& frame,
                                      const map::TerrainMap&) override {
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

}  // namespace

void DriftOdometryBy(DriftRunSpec& spec, double fraction) {
  spec.odom_sigma_per_m = fraction;
  spec.odom_yaw_sigma_rad_per_m = fraction * 0.5 * kDegToRad / 0.1;
}

double TiltBetween(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  const Eigen::Vector3d up_a = R_a.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_b = R_b.transpose() * Eigen::Vector3d::UnitZ();
  return std::atan2(up_a.cross(up_b).norm(), up_a.dot(up_b));
}

// d^T P^+ d, d the up vector of R_fused less that of R_true (their sensor frames), P^+ the
// pseudo-inverse of P (rank 2: across the up vector).
double UpNees(const Eigen::Matrix3d& R_fused, const Eigen::Matrix3d& R_true,
              const Eigen::Matrix3d& P) {
  const Eigen::Vector3d d = R_fused.transpose() * Eigen::Vector3d::UnitZ() -
                            R_true.transpose() * Eigen::Vector3d::UnitZ();
  if (!P.allFinite()) return NAN;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(P);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues().maxCoeff() > 0.0)) return NAN;
  const double floor = 1e-9 * eig.eigenvalues().maxCoeff();
  double nees = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double l = eig.eigenvalues()(i);
    if (l > floor) nees += std::pow(eig.eigenvectors().col(i).dot(d), 2) / l;
  }
  return nees;
}

std::vector<map::ImuSample> BodyImuUpTo(const sim::Drive& drive, double up_to_s,
                                        std::size_t* next) {
  std::vector<map::ImuSample> out;
  for (; *next < drive.imu.size() && drive.imu[*next].stamp_s <= up_to_s; ++*next) {
    const sim::ImuReading& reading = drive.imu[*next];
    map::ImuSample sample;
    sample.stamp_s = reading.stamp_s;
    sample.specific_force_mps2 = drive.R_body_imu * reading.specific_force_mps2;
    sample.angular_rate_radps = drive.R_body_imu * reading.angular_rate_radps;
    sample.has_raw = true;
    out.push_back(sample);
  }
  return out;
}

Expected<DriftRunResult> RunDrift(const DriftRunSpec& spec) {
  Expected<sim::World> world = sim::LoadWorld(spec.world);
  if (!world) return world.error();
  map::MapperConfig config;
  config.detector = spec.settings.detector;
  config.rules = spec.settings.rules;
  config.tilt.mode = spec.true_poses    ? map::TiltMode::kPrior
                     : spec.gravity     ? map::TiltMode::kGravity
                     : spec.refine_tilt ? map::TiltMode::kRefineToMap
                                        : map::TiltMode::kPrior;
  if (spec.smooth && config.tilt.mode != map::TiltMode::kGravity) {
    return Error{spec.world + ": smooth needs the gravity estimator (gravity, not true_poses)"};
  }
  config.tilt.smooth = spec.smooth;
  // The gravity estimator is told the odometry's random walk and, where it is wider than the
  // default prior, its scale error, as a user states them from the odometry's drift per
  // metre (tilt.gravity.odometry_walk_sigma, odometry_scale_sigma; libsim draws both with
  // odom_sigma_per_m).
  config.tilt.gravity.odometry_walk_sigma = spec.odom_sigma_per_m;
  config.tilt.gravity.odometry_scale_sigma =
      std::max(config.tilt.gravity.odometry_scale_sigma, spec.odom_sigma_per_m);
  if (spec.configure) spec.configure(config);
  // truth_tilt_height: the true pose of the frame being fused.
  const auto truth_now = std::make_shared<Eigen::Isometry3d>(Eigen::Isometry3d::Identity());
  Expected<map::Mapper> mapper =
      spec.truth_tilt_height
          ? map::Mapper::Create(config, std::make_unique<TruthTiltStep>(truth_now))
          : map::Mapper::Create(config);
  if (!mapper) return mapper.error();

  sim::DriveSpec drive_spec;
  drive_spec.waypoints = spec.waypoints;
  drive_spec.turn_radius_m = spec.turn_radius_m;
  drive_spec.speed_mps = spec.speed_mps;
  drive_spec.frame_rate_hz = spec.rate_hz;
  drive_spec.sensor_pitch_rad = 8.0 * kDegToRad;
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
  const sim::RangeCameraSpec camera_spec = world->camera.Scaled(spec.camera_width);
  // An obstacle is seen well where it fills as much of the view as 30 pixels of a 160 x 120
  // image (120 of the worlds' 320 x 240).
  const int seen_well_pixels =
      std::max(1, static_cast<int>(std::lround(kSeenWellPixels160 * camera_spec.model.width *
                                               camera_spec.model.height / (160.0 * 120.0))));

  std::map<int, int> pixels_seen;
  std::map<int, double> first_seen_m;
  std::vector<PoseError> pose_errors;
  std::vector<double> cue_errors_rad;
  int degenerate_frames = 0, accel_bias_flagged_frames = 0;
  double last_height_sigma = NAN;
  std::vector<map::GravityDegeneracy> last_degeneracies;
  int refined_frames = 0;
  double distance_m = 0.0;
  double ground_sum2 = 0.0;  // ground_height_rms_m
  long ground_n = 0;
  // One pass over the drive through `m`: at the believed poses, or at `given` (the smoothed
  // ones, one per frame); `final` when its map is the run's.
  const auto pass = [&](map::Mapper& m, const std::vector<map::SmoothedFrame>* given,
                        bool final) -> Status {
    double z_body = 0.0;  // dead reckoning
    ground_sum2 = 0.0;
    ground_n = 0;
    pose_errors.clear();
    const sim::DriveSample* previous = nullptr;
    std::size_t next_imu = 0;
    for (const sim::DriveSample& s : drive->samples) {
      // The raw IMU samples since the previous frame, rotated into the body frame.
      std::vector<map::ImuSample> imu = BodyImuUpTo(*drive, s.stamp_s, &next_imu);
      // The believed pose.
      Eigen::Isometry3d T_world_sensor = s.T_world_sensor;
      if (given != nullptr) {
        const std::size_t k = static_cast<std::size_t>(s.index);
        if (k >= given->size() || (*given)[k].stamp_s != s.stamp_s) {
          return Error{spec.world + ": the smoother gave no pose for frame " +
                       std::to_string(s.index)};
        }
        T_world_sensor = (*given)[k].T_world_sensor;
      } else if (!spec.true_poses) {
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
      // The sensor's noise differs from drive to drive (drive_seed) as the drift does.
      const std::uint64_t seed = sim::MixSeed(sim::MixSeed(world->seed, spec.drive_seed),
                                              static_cast<std::uint64_t>(s.index));
      Expected<sim::DepthFrame> rendered =
          sim::RenderRangeCamera(world->scene, camera_spec, camera, seed);
      if (!rendered) return rendered.error();
      const Eigen::Vector3d up = T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
      Expected<od::RangeImage> image =
          od::RangeImage::FromDepth(rendered->depth_m, rendered->model, up);
      if (!image) return image.error();
      if (spec.measure_cues &&
          given == nullptr) {  // the vertical cues the gravity step would see, against the truth
        Expected<od::Detection> detection = od::Detect(*image, config.detector);
        if (!detection) return detection.error();
        Expected<od::Classification> classes = od::Classify(*detection, config.rules);
        if (!classes) return classes.error();
        const Eigen::Vector3d up_true =
            s.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
        for (const map::VerticalCue& c : map::FindVerticalCues(
                 *image, *detection, *classes, image->up(), config.tilt.verticals)) {
          const double a = std::acos(std::min(1.0, std::abs(c.direction_sensor.dot(up_true))));
          cue_errors_rad.push_back(c.wall_normal ? std::abs(0.5 * kPi - a) : a);
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
          m.Process(std::move(*image), T_world_sensor, s.stamp_s, imu);
      if (!record) return record.error();
      if (!record->used()) {
        return Error{spec.world + ": frame " + std::to_string(s.index) + " skipped: " +
                     map::FrameSkipName(record->skip) + " (" + record->skip_detail + ")"};
      }
      if (spec.on_frame && final) spec.on_frame(*record, s);
      refined_frames += record->tilt.applied ? 1 : 0;
      if (record->tilt.gravity) {
        degenerate_frames += record->tilt.gravity->degeneracies.empty() ? 0 : 1;
        accel_bias_flagged_frames +=
            record->tilt.gravity->Degenerate(map::GravityDegeneracy::State::kAccelBias) ? 1 : 0;
        last_degeneracies = record->tilt.gravity->degeneracies;
        last_height_sigma = std::sqrt(record->tilt.gravity->height_variance);
      }
      std::map<int, int> pixels;
      for (const std::int32_t object : rendered->object_id) {
        if (object > 0) ++pixels[object];
      }
      for (const auto& [object, n] : pixels) {
        pixels_seen[object] = std::max(pixels_seen[object], n);
        if (n >= seen_well_pixels && first_seen_m.count(object) == 0) {
          first_seen_m[object] = s.distance_m;
        }
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
      e.yaw_rad = spec.true_poses
                      ? 0.0
                      : std::abs(std::remainder(s.odometry.yaw_rad - yaw_true, 2.0 * kPi));
      e.tilt_rad = TiltBetween(fused.linear(), s.T_world_sensor.linear());
      if (record->tilt.gravity && record->tilt.applied &&
          record->tilt.gravity->up_sensor_covariance.allFinite()) {
        e.tilt_nees = UpNees(fused.linear(), s.T_world_sensor.linear(),
                             record->tilt.gravity->up_sensor_covariance);
        e.tilt_sigma_rad = std::sqrt(record->tilt.gravity->up_sensor_covariance.trace());
      }
      e.z_m = std::abs(fused.translation().z() - s.T_world_sensor.translation().z());
      pose_errors.push_back(e);
      distance_m = s.distance_m;
    }
    return {};
  };
  if (Status st = pass(*mapper, nullptr, !spec.smooth); !st) return st.error();
  if (spec.smooth) {
    Expected<std::vector<map::SmoothedFrame>> smoothed = (*mapper).SmoothTilt();
    if (!smoothed) return Error{spec.world + ": " + smoothed.error().message};
    // The second pass fuses every frame at its smoothed pose, as given.
    Expected<map::Mapper> again = map::Mapper::Create(map::SmoothedPassConfig(config));
    if (!again) return again.error();
    const int refined = refined_frames;
    if (Status st = pass(*again, &*smoothed, true); !st) return st.error();
    refined_frames = refined;
    *mapper = std::move(*again);
  }
  DriftRunResult r(std::move(*mapper));
  r.frames = static_cast<int>(r.mapper.frames_fused());
  r.distance_m = distance_m;
  r.refined_frames = refined_frames;
  r.ground_height_rms_m = std::sqrt(ground_sum2 / std::max(1L, ground_n));
  r.pose_errors = std::move(pose_errors);
  r.cue_errors_rad = std::move(cue_errors_rad);
  r.degenerate_frames = degenerate_frames;
  r.accel_bias_flagged_frames = accel_bias_flagged_frames;
  r.final_height_sigma_m = last_height_sigma;
  r.last_degeneracies = std::move(last_degeneracies);
  Expected<MapScore> score = ScoreMap(world->scene, r.map());
  if (!score) return Error{spec.world + ": " + score.error().message};
  r.score = std::move(*score);
  // The obstacles seen well, against the map.
  double sum = 0.0;
  for (const MapObjectScore& o : r.score.objects) {
    const auto seen = pixels_seen.find(o.id);
    if (!o.scored() || seen == pixels_seen.end() || seen->second < seen_well_pixels) continue;
    r.obstacles.push_back({o.name, first_seen_m.at(o.id), o.nearest_lethal_m});
    r.max_distance_m = std::max(r.max_distance_m, o.nearest_lethal_m);
    sum += o.nearest_lethal_m;
    r.found_0_3 += o.found ? 1 : 0;
  }
  r.mean_distance_m = r.obstacles.empty() ? 0.0 : sum / r.obstacles.size();
  return r;
}

}  // namespace cairn::eval
