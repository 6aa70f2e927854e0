// kGravity: the Mapper's tilt step over map::GravityEstimator (tilt_step.hpp).
#include "gravity_tilt.hpp"

#include <cmath>
#include <deque>
#include <exception>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "gravity_terms.hpp"
#include "ground_rise.hpp"
#include "json_numbers.hpp"

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

// A fixed-size matrix's entries, in storage order.
template <int R, int C>
json Entries(const Eigen::Matrix<double, R, C>& m) {
  return internal::Array(m.data(), R * C);
}
template <int R, int C>
Eigen::Matrix<double, R, C> EntriesFrom(const json& a, const char* what) {
  Eigen::Matrix<double, R, C> m;
  internal::ArrayFrom(a, m.data(), R * C, what);
  return m;
}

constexpr const char* kNoGround = "no ground overlap";

class GravityTilt final : public TiltStep {
 public:
  explicit GravityTilt(const TiltConfig& config) : config_(config) {}

  TiltMode mode() const override { return TiltMode::kGravity; }
  bool UsesGroundPoints() const override { return true; }

  // The odometry pose with the correction of the last estimate applied to the body: its roll
  // and pitch (offsets to the IMU's attitude output, as its bias is: a correction about world
  // axes, carried through a turn, would tilt the next prior by up to twice the bias) and its
  // height, with the mount's tilt as estimated. Turning the body, not the sensor, moves the
  // sensor where the fused pose has it: a sensor 1.5 m above the body moves 8 cm sideways
  // with 3 deg of tilt, which on a slope the ground height would otherwise take for a height
  // error.
  Eigen::Isometry3d Prior(const Eigen::Isometry3d& T_world_sensor_odometry) const override {
    if (!estimator_) return T_world_sensor_odometry;
    Eigen::Isometry3d body = T_world_sensor_odometry * T_body_sensor_.inverse();
    const Attitude odom = AttitudeOf(body.linear());
    const double rpy[3] = {odom.roll + correction_rad_.x(), odom.pitch + correction_rad_.y(),
                           odom.yaw};
    body.linear() = gravity::WorldFromBody(rpy);
    body.translation().z() += dz_m_;
    return body * T_body_sensor_estimated_;
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
      if (config_.smooth) {
        Expected<GravitySmoother> smoother = GravitySmoother::Create(
            config_.gravity, Eigen::Matrix3d::Identity(), frame.T_body_sensor.linear());
        if (!smoother) return smoother.error();
        smoother_.emplace(std::move(*smoother));
      }
      T_body_sensor_ = frame.T_body_sensor;
      T_body_sensor_estimated_ = frame.T_body_sensor;
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
    // so far, the prior's tilt held (RefineHeight), give the body's
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
    // The ground against the ground of the frame rise_frames_back before, where both saw it.
    const int back = config_.gravity_rise_frames_back;
    std::vector<Eigen::Vector3f> ground;
    if (back > 0) ground = internal::ThinGroundPoints(frame.ground_points_sensor, RiseFitConfig());
    // The body on which the prior places this frame, and its height (the estimator's).
    const Eigen::Isometry3d body_prior =
        frame.T_world_sensor_prior * T_body_sensor_estimated_.inverse();
    const double h_prior = body_prior.translation().z() - z0_m_;
    // From the frame after the one that fills the estimator's window: begun at the first
    // frames, with the mount at its wide prior and the body's up from a few accelerometer
    // spans, the first rises moved those frames' tilt more than they told (libmap/README.md).
    if (back > 0 && static_cast<int>(earlier_.size()) >= back &&
        estimator_->frames_added() >= config_.gravity.window_frames) {
      const EarlierGround& e = earlier_[earlier_.size() - back];
      if (std::optional<internal::GroundRiseFit> fit = internal::FitGroundRise(
              ground, frame.T_world_sensor_prior, e.surface, RiseFitConfig())) {
        GroundRise rise;
        rise.earlier_stamp_s = e.stamp_s;
        rise.rise_m = fit->dz_m + h_prior - e.h_m;
        rise.R_world_sensor = frame.T_world_sensor_prior.linear();
        rise.R_world_sensor_earlier = e.surface.T_world_sensor().linear();
        rise.R_world_body = body_prior.linear();
        rise.R_world_body_earlier = e.R_world_body;
        rise.sensor_on_body_m = T_body_sensor_.translation();
        rise.offset_m = fit->offset_m;
        rise.offset_earlier_m = fit->offset_earlier_m;
        rise.odometry_step_m = g.odometry_xy_yaw.head<2>() - e.odometry_xy;
        rise.gradient = fit->gradient;
        rise.sigma_m = config_.gravity_rise_sigma_m;
        g.ground_rises.push_back(rise);
      }
    }
    Expected<GravityEstimate> estimate = estimator_->AddFrame(g);
    if (!estimate) return estimate.error();
    if (smoother_) {
      // The frame-to-map ground height was measured against the map fused at the window's
      // estimates, whose errors the smoother is there to undo: it is given with a sigma of its
      // own (TiltConfig::smooth_ground_sigma_m; 0: left out).
      // Its solve starts from the window's estimate.
      GravityFrame kept = g;
      kept.ground_height_sigma_m = config_.smooth_ground_sigma_m;
      if (config_.smooth_ground_sigma_m == 0.0) kept.ground_height_m.reset();
      const GravityEstimate* start = estimate->IsSolutionUsable() ? &*estimate : nullptr;
      if (Status s = smoother_->Add(kept, start); !s) return s.error();
    }
    verticals_seen_ += static_cast<int>(g.verticals.size());

    TiltOutcome outcome;
    outcome.estimated = true;
    outcome.T_world_sensor = frame.T_world_sensor_prior;
    if (estimate->IsSolutionUsable()) {
      const Eigen::Isometry3d mount = MountOf(*estimate);
      const Eigen::Isometry3d body = BodyOf(*estimate, g.odometry_xy_yaw);
      outcome.T_world_sensor = body * mount;
      const Eigen::Isometry3d body_odometry =
          frame.T_world_sensor_odometry * T_body_sensor_.inverse();
      correction_rad_ =
          Eigen::Vector2d(estimate->roll_rad - odom.roll, estimate->pitch_rad - odom.pitch);
      dz_m_ = body.translation().z() - body_odometry.translation().z();
      T_body_sensor_estimated_ = mount;
      outcome.applied = true;
    }
    const Attitude fused =
        AttitudeOf(outcome.T_world_sensor.linear() * T_body_sensor_.linear().transpose());
    outcome.roll_rad = fused.roll - odom.roll;
    outcome.pitch_rad = fused.pitch - odom.pitch;
    outcome.dz_m = outcome.T_world_sensor.translation().z() -
                   frame.T_world_sensor_odometry.translation().z();
    if (back > 0) {
      // The body this frame is fused on (the mount as now estimated).
      const Eigen::Isometry3d body_fused =
          outcome.T_world_sensor * T_body_sensor_estimated_.inverse();
      earlier_.push_back(
          EarlierGround{frame.stamp_s, body_fused.translation().z() - z0_m_, body_fused.linear(),
                        g.odometry_xy_yaw.head<2>(), ground,
                        internal::GroundSurface(ground, outcome.T_world_sensor, RiseFitConfig())});
      while (static_cast<int>(earlier_.size()) > back) earlier_.pop_front();
    }
    outcome.gravity = std::move(*estimate);
    return outcome;
  }

  Expected<std::vector<SmoothedFrame>> Smooth() override {
    if (!smoother_ || smoother_->frames() == 0) return TiltStep::Smooth();
    Expected<std::vector<GravityEstimate>> solved = smoother_->Solve();
    if (!solved) return solved.error();
    std::vector<SmoothedFrame> out;
    out.reserve(solved->size());
    for (std::size_t i = 0; i < solved->size(); ++i) {
      GravityEstimate& e = (*solved)[i];
      SmoothedFrame f;
      f.stamp_s = e.stamp_s;
      const GravityFrame& in = smoother_->frame(static_cast<int>(i));
      f.T_world_sensor = BodyOf(e, in.odometry_xy_yaw) * MountOf(e);
      // As Estimate() has them: the fused pose's body through the nominal mount against the
      // odometry's attitude (the IMU's, the frame's prior).
      const Attitude fused =
          AttitudeOf(f.T_world_sensor.linear() * T_body_sensor_.linear().transpose());
      const Eigen::Vector2d odometry = in.attitude_prior_rad.value_or(Eigen::Vector2d::Zero());
      f.roll_rad = fused.roll - odometry.x();
      f.pitch_rad = fused.pitch - odometry.y();
      f.estimate = std::move(e);
      out.push_back(std::move(f));
    }
    return out;
  }

  // The body an estimate puts at the odometry's x, y and heading.
  Eigen::Isometry3d BodyOf(const GravityEstimate& e, const Eigen::Vector3d& odometry_xy_yaw) const {
    const double rpy[3] = {e.roll_rad, e.pitch_rad, odometry_xy_yaw.z()};
    Eigen::Isometry3d body = Eigen::Isometry3d::Identity();
    body.linear() = gravity::WorldFromBody(rpy);
    body.translation() =
        Eigen::Vector3d(odometry_xy_yaw.x(), odometry_xy_yaw.y(), z0_m_ + e.height_m);
    return body;
  }
  // The sensor's pose on the body with the mount's tilt as estimated.
  Eigen::Isometry3d MountOf(const GravityEstimate& e) const {
    Eigen::Isometry3d mount = T_body_sensor_;
    mount.linear() =
        gravity::RotY(e.mount_rad.y()) * gravity::RotX(e.mount_rad.x()) * T_body_sensor_.linear();
    return mount;
  }

  internal::GroundRiseFitConfig RiseFitConfig() const {
    internal::GroundRiseFitConfig c;
    c.max_range_m = config_.refiner.max_range_m;
    c.max_points = config_.refiner.max_points;
    c.huber_m = config_.refiner.huber_m;
    return c;
  }

  // The body height [m] at which the frame's ground points fit the fused terrain (tilt as
  // the prior has it), or Error{kNoGround} when too few overlap it.
  Expected<double> GroundHeight(const TiltFrame& frame, const TerrainMap& map) const {
    if (frame.index == 0) return Error{kNoGround};
    // The tilt is the estimator's business: held at the prior's.
    const ElevationPatch patch = ElevationPatchAround(
        map, frame.T_world_sensor_prior.translation().head<2>(), config_.refiner.max_range_m);
    Expected<TiltEstimate> fit = RefineHeight(frame.ground_points_sensor,
                                              frame.T_world_sensor_prior, patch, config_.refiner);
    if (!fit) return fit.error();
    if (!fit->usable) return Error{kNoGround};
    // The prior's body: its sensor sits on it by the mount as estimated (Prior()).
    const Eigen::Isometry3d body = frame.T_world_sensor_prior * T_body_sensor_estimated_.inverse();
    return body.translation().z() + fit->dz_m;
  }

  // The estimator's own state (bounded by its window) and what this step carries.
  std::string SaveState() const override {
    json j = {{"attitude_correction", Entries(correction_rad_)},
              {"dz", dz_m_},
              {"mount_estimated", Entries(T_body_sensor_estimated_.matrix())},
              {"z0", z0_m_},
              {"verticals_seen", verticals_seen_},
              {"mount", Entries(T_body_sensor_.matrix())}};
    json earlier = json::array();
    for (const EarlierGround& e : earlier_) {
      std::vector<double> points;
      points.reserve(3 * e.points_sensor.size());
      for (const Eigen::Vector3f& p : e.points_sensor)
        points.insert(points.end(), {p.x(), p.y(), p.z()});
      earlier.push_back({{"stamp", e.stamp_s},
                         {"h", e.h_m},
                         {"body", Entries(e.R_world_body)},
                         {"odometry_xy", {e.odometry_xy.x(), e.odometry_xy.y()}},
                         {"pose", Entries(e.surface.T_world_sensor().matrix())},
                         {"points", points}});
    }
    j["earlier_ground"] = earlier;
    if (estimator_) j["estimator"] = json::parse(estimator_->SaveState());
    if (smoother_) j["smoother"] = json::parse(smoother_->SaveState());
    return j.dump();
  }
  Status RestoreState(const std::string& state) override {
    try {
      const json j = json::parse(state);
      if (j.contains("frames")) {
        return Error{
            "tilt state (gravity): written by an earlier cairn, which replayed every "
            "frame; start the run afresh"};
      }
      if (!j.contains("mount_estimated") || !j.contains("attitude_correction")) {
        return Error{
            "tilt state (gravity): written by an earlier cairn, whose prior turned the sensor "
            "rather than the body, or corrected the body's tilt about world axes; start the run "
            "afresh"};
      }
      // Read whole before anything changes: a state that fails leaves the step as it was.
      Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();
      mount.matrix() = EntriesFrom<4, 4>(j.at("mount"), "mount");
      std::optional<GravityEstimator> estimator;
      if (j.contains("estimator")) {
        Expected<GravityEstimator> made =
            GravityEstimator::Create(config_.gravity, Eigen::Matrix3d::Identity(), mount.linear());
        if (!made) return made.error();
        if (Status s = made->RestoreState(j.at("estimator").dump()); !s) {
          return Error{"tilt state (gravity): " + s.message()};
        }
        estimator.emplace(std::move(*made));
      }
      std::optional<GravitySmoother> smoother;
      if (config_.smooth && j.contains("smoother")) {
        Expected<GravitySmoother> made =
            GravitySmoother::Create(config_.gravity, Eigen::Matrix3d::Identity(), mount.linear());
        if (!made) return made.error();
        if (Status s = made->RestoreState(j.at("smoother").dump()); !s) {
          return Error{"tilt state (gravity) smoother: " + s.message()};
        }
        smoother.emplace(std::move(*made));
      } else if (config_.smooth && estimator) {
        return Error{
            "tilt state (gravity): saved without tilt.smooth, which keeps every frame for the "
            "smoother; start the run afresh to smooth it"};
      }
      const int verticals_seen = j.at("verticals_seen").get<int>();
      const Eigen::Vector2d correction =
          EntriesFrom<2, 1>(j.at("attitude_correction"), "attitude_correction");
      if (!correction.allFinite()) throw std::runtime_error("attitude_correction: not finite");
      Eigen::Isometry3d mount_estimated = Eigen::Isometry3d::Identity();
      mount_estimated.matrix() = EntriesFrom<4, 4>(j.at("mount_estimated"), "mount_estimated");
      const double dz = j.at("dz").get<double>(), z0 = j.at("z0").get<double>();
      std::deque<EarlierGround> earlier;
      // (absent from a state of a cairn before the ground rises: they start afresh)
      for (const json& e : j.value("earlier_ground", json::array())) {
        Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
        pose.matrix() = EntriesFrom<4, 4>(e.at("pose"), "earlier_ground.pose");
        const Eigen::Matrix3d body = EntriesFrom<3, 3>(e.at("body"), "earlier_ground.body");
        Eigen::Vector2d odometry_xy;
        internal::ArrayFrom(e.at("odometry_xy"), odometry_xy.data(), 2,
                            "earlier_ground.odometry_xy");
        const double stamp = e.at("stamp").get<double>(), h = e.at("h").get<double>();
        if (!(pose.matrix().allFinite() && body.allFinite() && odometry_xy.allFinite() &&
              std::isfinite(stamp) && std::isfinite(h))) {
          throw std::runtime_error(
              "earlier_ground: a pose, rotation, position or height not finite");
        }
        const std::vector<double> flat = e.at("points").get<std::vector<double>>();
        if (flat.size() % 3 != 0) {
          throw std::runtime_error("earlier_ground.points: not x, y, z triples");
        }
        std::vector<Eigen::Vector3f> points;
        for (std::size_t i = 0; i < flat.size(); i += 3) {
          for (std::size_t k = i; k < i + 3; ++k) {
            if (!(std::abs(flat[k]) < 1e6)) {
              throw std::runtime_error(
                  "earlier_ground.points: a coordinate not finite or beyond 1e6 m");
            }
          }
          points.emplace_back(static_cast<float>(flat[i]), static_cast<float>(flat[i + 1]),
                              static_cast<float>(flat[i + 2]));
        }
        internal::GroundSurface surface(points, pose, RiseFitConfig());
        earlier.push_back(
            EarlierGround{stamp, h, body, odometry_xy, std::move(points), std::move(surface)});
      }
      T_body_sensor_ = mount;
      estimator_ = std::move(estimator);
      smoother_ = std::move(smoother);
      verticals_seen_ = verticals_seen;
      correction_rad_ = correction;
      dz_m_ = dz;
      T_body_sensor_estimated_ = mount_estimated;
      z0_m_ = z0;
      earlier_ = std::move(earlier);
    } catch (const std::exception& e) {
      return Error{std::string("tilt state (gravity) unreadable: ") + e.what()};
    }
    return {};
  }

 private:
  TiltConfig config_;
  std::optional<GravityEstimator> estimator_;  // made at the first frame (it needs the mount)
  std::optional<GravitySmoother> smoother_;    // and with it, with TiltConfig::smooth
  Eigen::Isometry3d T_body_sensor_ = Eigen::Isometry3d::Identity();
  double z0_m_ = 0.0;  // the body's odometry height at the first frame [m]
  int verticals_seen_ = 0;                                      // vertical cues given so far
  // Carried to the next prior: the body's roll and pitch and height correction, the mount as
  // estimated.
  Eigen::Vector2d correction_rad_ = Eigen::Vector2d::Zero();
  double dz_m_ = 0.0;
  Eigen::Isometry3d T_body_sensor_estimated_ = Eigen::Isometry3d::Identity();
  // The last rise_frames_back frames' ground, as fused, for the ground rises.
  struct EarlierGround {
    double stamp_s = 0.0;
    double h_m = 0.0;  // the body height (the estimator's) it was fused at [m]
    Eigen::Matrix3d R_world_body = Eigen::Matrix3d::Identity();  // and its rotation
    Eigen::Vector2d odometry_xy = Eigen::Vector2d::Zero();       // the odometry's body x, y [m]
    std::vector<Eigen::Vector3f> points_sensor;
    internal::GroundSurface surface;
  };
  std::deque<EarlierGround> earlier_;
};

}  // namespace

std::unique_ptr<TiltStep> MakeGravityTilt(const TiltConfig& config) {
  return std::make_unique<GravityTilt>(config);
}

}  // namespace cairn::map
