#include "cairn/map/tilt_step.hpp"

#include <cmath>
#include <exception>
#include <nlohmann/json.hpp>

#include "gravity_tilt.hpp"

namespace cairn::map {
namespace {

using nlohmann::json;

/// kPrior: the odometry pose is fused as it is.
class PriorTilt final : public TiltStep {
 public:
  TiltMode mode() const override { return TiltMode::kPrior; }
  bool UsesGroundPoints() const override { return false; }
  Eigen::Isometry3d Prior(const Eigen::Isometry3d& T_world_sensor_odometry) const override {
    return T_world_sensor_odometry;
  }
  Expected<TiltOutcome> Estimate(const TiltFrame& frame, const TerrainMap&) override {
    TiltOutcome outcome;
    outcome.T_world_sensor = frame.T_world_sensor_prior;
    return outcome;
  }
  std::string SaveState() const override { return "{}"; }
  Status RestoreState(const std::string&) override { return {}; }
};

/// kRefineToMap: RefineTilt on the ground points against the fused elevation around the
/// prior; the correction of the last estimate used carries to the next frame's prior.
class RefineToMapTilt final : public TiltStep {
 public:
  explicit RefineToMapTilt(const TiltRefinerConfig& config) : config_(config) {}

  TiltMode mode() const override { return TiltMode::kRefineToMap; }
  bool UsesGroundPoints() const override { return true; }
  Eigen::Isometry3d Prior(const Eigen::Isometry3d& T_world_sensor_odometry) const override {
    return ApplyTiltCorrection(T_world_sensor_odometry, roll_rad_, pitch_rad_, dz_m_);
  }

  Expected<TiltOutcome> Estimate(const TiltFrame& frame, const TerrainMap& map) override {
    const ElevationPatch patch = ElevationPatchAround(
        map, frame.T_world_sensor_prior.translation().head<2>(), config_.max_range_m);
    Expected<TiltEstimate> estimate =
        RefineTilt(frame.ground_points_sensor, frame.T_world_sensor_prior, patch, config_);
    if (!estimate) return estimate.error();
    TiltOutcome outcome;
    outcome.estimated = true;
    outcome.T_world_sensor = frame.T_world_sensor_prior;
    // A correction that does not lower the ground residuals is not trusted.
    if (estimate->usable && estimate->rms_after_m <= estimate->rms_before_m) {
      roll_rad_ += estimate->roll_rad;
      pitch_rad_ += estimate->pitch_rad;
      dz_m_ += estimate->dz_m;
      outcome.T_world_sensor = estimate->T_world_sensor;
      outcome.applied = true;
    }
    outcome.estimate = std::move(*estimate);
    outcome.roll_rad = roll_rad_;
    outcome.pitch_rad = pitch_rad_;
    outcome.dz_m = dz_m_;
    return outcome;
  }

  // json writes doubles in their shortest round-trip form: a restored step carries exactly.
  std::string SaveState() const override {
    return json{{"carry", {roll_rad_, pitch_rad_, dz_m_}}}.dump();
  }
  Status RestoreState(const std::string& state) override {
    try {
      const json j = json::parse(state);
      roll_rad_ = j.at("carry").at(0).get<double>();
      pitch_rad_ = j.at("carry").at(1).get<double>();
      dz_m_ = j.at("carry").at(2).get<double>();
    } catch (const std::exception& e) {
      return Error{std::string("tilt state (refine_to_map) unreadable: ") + e.what()};
    }
    return {};
  }

 private:
  TiltRefinerConfig config_;
  double roll_rad_ = 0.0, pitch_rad_ = 0.0, dz_m_ = 0.0;  // carried correction
};

}  // namespace

const char* TiltModeName(TiltMode mode) {
  switch (mode) {
    case TiltMode::kPrior:
      return "prior";
    case TiltMode::kRefineToMap:
      return "refine_to_map";
    case TiltMode::kGravity:
      return "gravity";
  }
  return "?";
}

Expected<TiltMode> ParseTiltMode(const std::string& name) {
  for (TiltMode m : {TiltMode::kPrior, TiltMode::kRefineToMap, TiltMode::kGravity}) {
    if (name == TiltModeName(m)) return m;
  }
  return Error{"expected prior, refine_to_map or gravity, got '" + name + "'"};
}

Expected<std::vector<SmoothedFrame>> TiltStep::Smooth() {
  return Error{std::string("tilt step (") + TiltModeName(mode()) +
               "): keeps no record to smooth (tilt.mode gravity with tilt.smooth)"};
}

Status TiltConfig::Validate() const {
  if (mode != TiltMode::kPrior && mode != TiltMode::kRefineToMap && mode != TiltMode::kGravity) {
    return Error{"tilt config: 'mode': unknown"};
  }
  if (!(smooth_ground_sigma_m >= 0.0 && std::isfinite(smooth_ground_sigma_m))) {
    return Error{"tilt config: 'smooth_ground_sigma_m': must be >= 0 m (0: left out)"};
  }
  if (smooth && mode != TiltMode::kGravity) {
    return Error{"tilt config: 'smooth': smooths the gravity mode's run (mode gravity)"};
  }
  if (Status s = refiner.Validate(); !s) return Error{"tilt config: " + s.message()};
  if (Status s = gravity.Validate(); !s) return Error{"tilt config: " + s.message()};
  if (Status s = verticals.Validate(); !s) return Error{"tilt config: " + s.message()};
  if (!(gravity_ground_sigma_m > 0.0 && std::isfinite(gravity_ground_sigma_m))) {
    return Error{"tilt config: 'gravity_ground_sigma': must be > 0 m"};
  }
  if (gravity_ground_min_verticals < 0) {
    return Error{"tilt config: 'gravity_ground_min_verticals': must be >= 0"};
  }
  if (gravity_rise_frames_back < 0 || gravity_rise_frames_back >= gravity.window_frames) {
    return Error{
        "tilt config: 'gravity_rise_frames_back': must be >= 0 and under "
        "gravity.window_frames (" +
        std::to_string(gravity.window_frames) + ")"};
  }
  if (!(gravity_rise_sigma_m > 0.0 && std::isfinite(gravity_rise_sigma_m))) {
    return Error{"tilt config: 'gravity_rise_sigma_m': must be > 0 m"};
  }
  return {};
}

Expected<std::unique_ptr<TiltStep>> MakeTiltStep(const TiltConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  if (config.mode == TiltMode::kRefineToMap) {
    return std::unique_ptr<TiltStep>(std::make_unique<RefineToMapTilt>(config.refiner));
  }
  if (config.mode == TiltMode::kGravity) return MakeGravityTilt(config);
  return std::unique_ptr<TiltStep>(std::make_unique<PriorTilt>());
}

}  // namespace cairn::map
