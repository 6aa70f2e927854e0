// kGravity: the Mapper's tilt step over map::GravityEstimator (tilt_step.hpp).
#include "gravity_tilt.hpp"

#include <cmath>
#include <exception>
#include <nlohmann/json.hpp>
#include <optional>
#include <utility>
#include <vector>

#include "gravity_terms.hpp"

namespace cairn::map {
namespace {

using nlohmann::json;

struct Attitude {
  double roll = 0.0, pitch = 0.0, yaw = 0.0;
};

// R = Rz(yaw) Ry(pitch) Rx(roll): pitch > 0 nose down, roll > 0 left side up.
Attitude AttitudeOf(const Eigen::Matrix3d& R) {
  Attitude a;
  a.pitch = std::atan2(-R(2, 0), std::hypot(R(0, 0), R(1, 0)));
  a.roll = std::atan2(R(2, 1), R(2, 2));
  a.yaw = std::atan2(R(1, 0), R(0, 0));
  return a;
}

json Vec(const Eigen::VectorXd& v) {
  json a = json::array();
  for (int i = 0; i < v.size(); ++i) a.push_back(v(i));
  return a;
}
template <int N>
Eigen::Matrix<double, N, 1> VecFrom(const json& a) {
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v(i) = a.at(i).get<double>();
  return v;
}

json FrameJson(const GravityFrame& f) {
  json imu = json::array();
  for (const GravityImuSample& s : f.imu) {
    imu.push_back({s.stamp_s, Vec(s.specific_force_mps2), Vec(s.angular_rate_radps)});
  }
  json verticals = json::array();
  for (const VerticalCue& v : f.verticals) verticals.push_back({Vec(v.direction_sensor), v.wall_normal});
  json j = {{"stamp", f.stamp_s}, {"imu", imu}, {"odom", Vec(f.odometry_xy_yaw)},
            {"verticals", verticals}};
  if (f.attitude_prior_rad) j["attitude"] = Vec(*f.attitude_prior_rad);
  if (f.velocity_world_mps) j["velocity"] = Vec(*f.velocity_world_mps);
  if (f.ground_height_m) j["ground"] = {*f.ground_height_m, f.ground_height_sigma_m};
  return j;
}

GravityFrame FrameFrom(const json& j) {
  GravityFrame f;
  f.stamp_s = j.at("stamp").get<double>();
  for (const json& s : j.at("imu")) {
    f.imu.push_back({s.at(0).get<double>(), VecFrom<3>(s.at(1)), VecFrom<3>(s.at(2))});
  }
  f.odometry_xy_yaw = VecFrom<3>(j.at("odom"));
  for (const json& v : j.at("verticals")) f.verticals.push_back({VecFrom<3>(v.at(0)), v.at(1).get<bool>()});
  if (j.contains("attitude")) f.attitude_prior_rad = VecFrom<2>(j.at("attitude"));
  if (j.contains("velocity")) f.velocity_world_mps = VecFrom<3>(j.at("velocity"));
  if (j.contains("ground")) {
    f.ground_height_m = j.at("ground").at(0).get<double>();
    f.ground_height_sigma_m = j.at("ground").at(1).get<double>();
  }
  return f;
}

constexpr const char* kNoGround = "no ground overlap";

class GravityTilt final : public TiltStep {
 public:
  explicit GravityTilt(const TiltConfig& config) : config_(config) {}

  TiltMode mode() const override { return TiltMode::kGravity; }
  bool UsesGroundPoints() const override { return true; }

  // The odometry pose with the correction of the last estimate: its tilt (a rotation about
  // world axes, the heading kept) and its height.
  Eigen::Isometry3d Prior(const Eigen::Isometry3d& T_world_sensor_odometry) const override {
    Eigen::Isometry3d T = T_world_sensor_odometry;
    T.linear() = R_correction_ * T.linear();
    T.translation().z() += dz_m_;
    return T;
  }

  Expected<TiltOutcome> Estimate(const TiltFrame& frame, const TerrainMap& map) override {
    const Eigen::Isometry3d T_world_body =
        frame.T_world_sensor_odometry * frame.T_body_sensor.inverse();
    const Attitude odom = AttitudeOf(T_world_body.linear());
    if (!estimator_) {
      Expected<GravityEstimator> made = GravityEstimator::Create(
          config_.gravity, Eigen::Matrix3d::Identity(), frame.T_body_sensor.linear());
      if (!made) return made.error();
      estimator_.emplace(std::move(*made));
      T_body_sensor_ = frame.T_body_sensor;
      z0_m_ = T_world_body.translation().z();
    }
    GravityFrame g;
    g.stamp_s = frame.stamp_s;
    for (const ImuSample& s : frame.imu) {
      if (s.has_raw) g.imu.push_back({s.stamp_s, s.specific_force_mps2, s.angular_rate_radps});
    }
    g.odometry_xy_yaw = Eigen::Vector3d(T_world_body.translation().x(),
                                        T_world_body.translation().y(), odom.yaw);
    // The odometry pose's roll and pitch are the IMU's attitude output.
    g.attitude_prior_rad = Eigen::Vector2d(odom.roll, odom.pitch);
    g.verticals = FindVerticalCues(frame.image, frame.detection, frame.classification,
                                   frame.image.up(), config_.verticals);
    // The frame-to-map ground height: the frame's ground points against the terrain fused
    // so far, the prior's tilt held (RefineTilt with a tight tilt prior), give the body's
    // height; it keeps the height consistent with the map, as refine_to_map does, while
    // the tilt comes from gravity. Only once vertical structure anchors the tilt: without
    // it the map, built at the earlier frames' tilts, would pull the tilt back to theirs
    // through the height steps (on an open field it turned a 2.5 deg mount error into 7).
    if (verticals_seen_ < config_.gravity_ground_min_verticals) {
      // not yet anchored
    } else if (Expected<double> h = GroundHeight(frame, map); h) {
      g.ground_height_m = *h - z0_m_;
      g.ground_height_sigma_m = config_.gravity_ground_sigma_m;
    } else if (h.error().message != kNoGround) {
      return h.error();
    }
    Expected<GravityEstimate> estimate = estimator_->AddFrame(g);
    if (!estimate) return estimate.error();
    verticals_seen_ += static_cast<int>(g.verticals.size());
    frames_.push_back(FrameJson(g));

    TiltOutcome outcome;
    outcome.estimated = true;
    outcome.T_world_sensor = frame.T_world_sensor_prior;
    if (estimate->IsSolutionUsable()) {
      const double rpy[3] = {estimate->roll_rad, estimate->pitch_rad, odom.yaw};
      Eigen::Isometry3d body = Eigen::Isometry3d::Identity();
      body.linear() = gravity::WorldFromBody(rpy);
      body.translation() = Eigen::Vector3d(T_world_body.translation().x(),
                                           T_world_body.translation().y(),
                                           z0_m_ + estimate->height_m);
      Eigen::Isometry3d mount = T_body_sensor_;
      mount.linear() = gravity::RotY(estimate->mount_rad.y()) *
                       gravity::RotX(estimate->mount_rad.x()) * T_body_sensor_.linear();
      outcome.T_world_sensor = body * mount;
      R_correction_ = outcome.T_world_sensor.linear() *
                      frame.T_world_sensor_odometry.linear().transpose();
      dz_m_ = outcome.T_world_sensor.translation().z() -
              frame.T_world_sensor_odometry.translation().z();
      outcome.applied = true;
    }
    const Attitude fused =
        AttitudeOf(outcome.T_world_sensor.linear() * T_body_sensor_.linear().transpose());
    outcome.roll_rad = fused.roll - odom.roll;
    outcome.pitch_rad = fused.pitch - odom.pitch;
    outcome.dz_m = outcome.T_world_sensor.translation().z() -
                   frame.T_world_sensor_odometry.translation().z();
    outcome.gravity = std::move(*estimate);
    return outcome;
  }

  // The body height [m] at which the frame's ground points fit the fused terrain (tilt as
  // the prior has it), or Error{kNoGround} when too few overlap it.
  Expected<double> GroundHeight(const TiltFrame& frame, const TerrainMap& map) const {
    if (frame.index == 0) return Error{kNoGround};
    TiltRefinerConfig c = config_.refiner;
    c.prior_sigma_rad = 1e-5;  // the tilt is the estimator's business
    const ElevationPatch patch = ElevationPatchAround(
        map, frame.T_world_sensor_prior.translation().head<2>(), c.max_range_m);
    Expected<TiltEstimate> fit = RefineTilt(frame.ground_points_sensor, frame.T_world_sensor_prior, patch, c);
    if (!fit) return fit.error();
    if (!fit->usable) return Error{kNoGround};
    const Eigen::Isometry3d body = frame.T_world_sensor_prior * frame.T_body_sensor.inverse();
    return body.translation().z() + fit->dz_m;
  }

  // The estimator's window and marginalised prior are a function of every frame it was
  // given: the state is those frames, replayed on restore (the solve is deterministic).
  std::string SaveState() const override {
    json j = {{"frames", frames_},
              {"correction", Vec(Eigen::Map<const Eigen::Matrix<double, 9, 1>>(R_correction_.data()))},
              {"dz", dz_m_},
              {"z0", z0_m_},
              {"mount", Vec(Eigen::Map<const Eigen::Matrix<double, 16, 1>>(T_body_sensor_.matrix().data()))}};
    return j.dump();
  }
  Status RestoreState(const std::string& state) override {
    try {
      const json j = json::parse(state);
      estimator_.reset();
      frames_ = json::array();
      verticals_seen_ = 0;
      const Eigen::Matrix<double, 16, 1> mount = VecFrom<16>(j.at("mount"));
      T_body_sensor_.matrix() = Eigen::Map<const Eigen::Matrix4d>(mount.data());
      for (const json& f : j.at("frames")) {
        if (!estimator_) {
          Expected<GravityEstimator> made = GravityEstimator::Create(
              config_.gravity, Eigen::Matrix3d::Identity(), T_body_sensor_.linear());
          if (!made) return made.error();
          estimator_.emplace(std::move(*made));
        }
        const GravityFrame frame = FrameFrom(f);
        Expected<GravityEstimate> e = estimator_->AddFrame(frame);
        if (!e) return Error{"tilt state (gravity): " + e.error().message};
        verticals_seen_ += static_cast<int>(frame.verticals.size());
        frames_.push_back(f);
      }
      const Eigen::Matrix<double, 9, 1> c = VecFrom<9>(j.at("correction"));
      R_correction_ = Eigen::Map<const Eigen::Matrix3d>(c.data());
      dz_m_ = j.at("dz").get<double>();
      z0_m_ = j.at("z0").get<double>();
    } catch (const std::exception& e) {
      return Error{std::string("tilt state (gravity) unreadable: ") + e.what()};
    }
    return {};
  }

 private:
  TiltConfig config_;
  std::optional<GravityEstimator> estimator_;  // made at the first frame (it needs the mount)
  Eigen::Isometry3d T_body_sensor_ = Eigen::Isometry3d::Identity();
  double z0_m_ = 0.0;  // the body's odometry height at the first frame [m]
  int verticals_seen_ = 0;  // vertical cues given so far
  json frames_ = json::array();
  Eigen::Matrix3d R_correction_ = Eigen::Matrix3d::Identity();  // carried to the next prior
  double dz_m_ = 0.0;
};

}  // namespace

std::unique_ptr<TiltStep> MakeGravityTilt(const TiltConfig& config) {
  return std::make_unique<GravityTilt>(config);
}

}  // namespace cairn::map
