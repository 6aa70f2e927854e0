#include "cairn/map/mapper.hpp"

#include <chrono>
#include <cmath>
#include <exception>
#include <future>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <utility>

#include "cairn/map/checkpoint.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"

namespace cairn::map {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

constexpr const char* kStateFormat = "cairn mapper state 1";
constexpr double kMinJumpDt = 0.01;  // [s]: stamps closer than this count as 10 ms apart

Eigen::Vector3d UpIn(const Eigen::Isometry3d& T_world_sensor) {
  return T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
}

json PoseJson(const Eigen::Isometry3d& T) {
  json m = json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) m.push_back(T.matrix()(r, c));
  }
  return m;
}

Eigen::Isometry3d PoseFromJson(const json& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) T.matrix()(r, c) = m.at(4 * r + c).get<double>();
  }
  return T;
}

}  // namespace

const char* FrameSkipName(FrameSkip skip) {
  switch (skip) {
    case FrameSkip::kNone:
      return "none";
    case FrameSkip::kNoValidPoints:
      return "no valid points";
    case FrameSkip::kPoseJump:
      return "pose jump";
  }
  return "?";
}

Status FrameCheckConfig::Validate() const {
  if (min_valid_points < 1) return Error{"frame checks: 'min_valid_points': expected >= 1"};
  if (!(std::isfinite(max_speed_mps) && max_speed_mps > 0.0)) {
    return Error{"frame checks: 'max_speed': expected > 0 m/s"};
  }
  if (!(std::isfinite(max_turn_rate_radps) && max_turn_rate_radps > 0.0)) {
    return Error{"frame checks: 'max_turn_rate': expected > 0 deg/s"};
  }
  return {};
}

Status MapperConfig::Validate() const {
  if (Status s = detector.Validate(); !s) return Error{"detector: " + s.message()};
  if (Status s = rules.Validate(); !s) return Error{"rules: " + s.message()};
  if (Status s = map.Validate(); !s) return s;
  if (Status s = tilt.Validate(); !s) return s;
  if (Status s = frames.Validate(); !s) return s;
  return {};
}

// Named, not anonymous: Mapper::State holds these (GCC warns of a member of anonymous type
// in a unity batch).
namespace internal {

// A frame levelled with its prior and, when it has the valid returns to be fused, detected
// and classified: what Process does before the tilt step.
struct Levelled {
  od::RangeImage image;
  int valid_points = 0;
  std::optional<od::Detection> detection;  // none: too few valid returns, or not asked
  od::Classification classification;
  std::optional<Error> detect_error;  // the detector's or the rules' failure
};

Expected<Levelled> LevelAndDetect(od::RangeImage image, const Eigen::Isometry3d& prior,
                                  const MapperConfig& config, bool detect) {
  Levelled out;
  if (Status st = image.SetUp(UpIn(prior)); !st) return Error{"mapper: " + st.message()};
  // Returns of the vehicle itself are no returns for the map either (detector.min_range).
  if (config.detector.min_range_m > 0.0) image.DropReturnsNearerThan(config.detector.min_range_m);
  out.valid_points = image.valid_count();
  if (detect && out.valid_points >= config.frames.min_valid_points) {
    Expected<od::Detection> detection = od::Detect(image, config.detector);
    Expected<od::Classification> classification =
        detection ? od::Classify(*detection, config.rules) : Expected<od::Classification>(detection.error());
    if (classification) {
      out.detection = std::move(*detection);
      out.classification = std::move(*classification);
    } else {
      out.detect_error = classification.error();
    }
  }
  out.image = std::move(image);
  return out;
}

// A frame told ahead (Mapper::Expect), and its levelling and detection under way.
struct Lookahead {
  od::RangeImage image;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  double stamp_s = 0.0;
  std::future<Expected<Levelled>> result;  // valid once started
};

}  // namespace internal

using internal::LevelAndDetect;
using internal::Levelled;
using internal::Lookahead;

struct Mapper::State {
  MapperConfig config;
  TerrainMap map;
  std::unique_ptr<TiltStep> tilt;
  std::int64_t processed = 0;
  std::int64_t fused = 0;
  // The previous frame given to Process (the jump check's reference).
  std::optional<std::pair<double, Eigen::Isometry3d>> previous;
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();  // SetSensorMount
  // Expect()'s frame: told (expected), then levelled and detected while the frame before is
  // fused (started), for the Process call of that frame. Declared last: the task that may
  // be under way ends before the rest goes.
  std::optional<Lookahead> expected, started;

  State(const MapperConfig& c, TerrainMap m, std::unique_ptr<TiltStep> t)
      : config(c), map(std::move(m)), tilt(std::move(t)) {}

  /// Empty when the move from the previous frame is plausible, else the figures.
  std::string Jump(double stamp_s, const Eigen::Isometry3d& T) const {
    if (!previous) return {};
    const double dt = std::max(std::abs(stamp_s - previous->first), kMinJumpDt);
    const double moved = (T.translation() - previous->second.translation()).norm();
    const double turned =
        Eigen::AngleAxisd(previous->second.linear().transpose() * T.linear()).angle();
    if (moved > config.frames.max_speed_mps * dt) {
      return "the odometry moved " + util::Fixed(moved, 2) + " m in " + util::Fixed(dt, 3) +
             " s (frames.max_speed " + util::Fixed(config.frames.max_speed_mps, 1) + " m/s)";
    }
    if (turned > config.frames.max_turn_rate_radps * dt) {
      return "the odometry turned " + util::Fixed(turned * kRadToDeg, 1) + " deg in " +
             util::Fixed(dt, 3) + " s (frames.max_turn_rate " +
             util::Fixed(config.frames.max_turn_rate_radps * kRadToDeg, 0) + " deg/s)";
    }
    return {};
  }
};

Mapper::Mapper(std::unique_ptr<State> state) : state_(std::move(state)) {}
Mapper::Mapper(Mapper&&) noexcept = default;
Mapper& Mapper::operator=(Mapper&&) noexcept = default;
Mapper::~Mapper() = default;

Expected<Mapper> Mapper::Create(const MapperConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  Expected<std::unique_ptr<TiltStep>> tilt = MakeTiltStep(config.tilt);
  if (!tilt) return tilt.error();
  return Create(config, std::move(*tilt));
}

Expected<Mapper> Mapper::Create(const MapperConfig& config, std::unique_ptr<TiltStep> tilt) {
  if (tilt == nullptr) return Error{"mapper: no tilt step"};
  if (Status s = config.Validate(); !s) return s.error();
  Expected<TerrainMap> map = TerrainMap::Create(config.map);
  if (!map) return map.error();
  return Mapper(std::make_unique<State>(config, std::move(*map), std::move(tilt)));
}

Expected<MapperRecord> Mapper::Process(od::RangeImage image,
                                       const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                       const std::vector<ImuSample>& imu) {
  State& s = *state_;
  if (!T_world_sensor.matrix().allFinite() || !std::isfinite(stamp_s)) {
    return Error{"mapper: non-finite pose or stamp"};
  }
  MapperRecord r;
  r.index = s.fused;
  r.stamp_s = stamp_s;
  r.T_world_sensor_odometry = T_world_sensor;
  r.T_world_sensor = T_world_sensor;

  // --- check ---
  r.skip_detail = s.Jump(stamp_s, T_world_sensor);
  if (!r.skip_detail.empty()) r.skip = FrameSkip::kPoseJump;

  Clock::time_point t = Clock::now();
  // --- level: the detector measures heights along the prior's up vector; detect ---
  // The look-ahead's result when it is this frame (Expect): the prior it was levelled with
  // is this one (the tilt step has estimated nothing since; SetSensorMount does not enter
  // it: the step keeps the mount of its first frame, and its own estimate of the tilt).
  const Eigen::Isometry3d prior = s.tilt->Prior(T_world_sensor);
  std::optional<Lookahead> ahead = std::move(s.started);
  s.started.reset();
  Expected<Levelled> levelled =
      ahead && ahead->result.valid() && ahead->stamp_s == stamp_s &&
              ahead->T_world_sensor.matrix() == T_world_sensor.matrix()
          ? ahead->result.get()
          : LevelAndDetect(std::move(image), prior, s.config, r.used());
  if (!levelled) return levelled.error();
  r.valid_points = levelled->valid_points;
  if (r.used() && r.valid_points < s.config.frames.min_valid_points) {
    r.skip = FrameSkip::kNoValidPoints;
    r.skip_detail = std::to_string(r.valid_points) + " valid returns (frames.min_valid_points " +
                    std::to_string(s.config.frames.min_valid_points) + ")";
  }
  if (!r.used()) {
    s.previous.emplace(stamp_s, T_world_sensor);
    ++s.processed;
    return r;
  }
  if (levelled->detect_error) return *levelled->detect_error;
  const od::RangeImage& levelled_image = levelled->image;
  const od::Detection* detection = &*levelled->detection;
  const od::Classification* classification = &levelled->classification;
  r.detect_s = util::SecondsSince(t);
  r.segments = static_cast<int>(detection->segments.size());
  r.kept = classification->kept;
  r.rejected = r.segments - r.kept;

  // --- tilt ---
  t = Clock::now();
  std::vector<Eigen::Vector3f> ground;
  if (s.tilt->UsesGroundPoints()) {
    ground.reserve(levelled_image.size());
    for (int i = 0; i < levelled_image.size(); ++i) {
      if (!levelled_image.valid(i)) continue;
      const int label = detection->labels[i];
      if (label > 0 && classification->verdicts[label - 1].cls == od::SegmentClass::kKept) continue;
      ground.push_back(levelled_image.point(i).cast<float>());
    }
  }
  const TiltFrame frame{s.fused, stamp_s, T_world_sensor, prior, s.T_body_sensor, imu,
                        levelled_image,       *detection,      *classification, ground};
  Expected<TiltOutcome> tilt = s.tilt->Estimate(frame, s.map);
  if (!tilt) return Error{"tilt: " + tilt.error().message};
  r.tilt = std::move(*tilt);
  r.T_world_sensor = r.tilt.T_world_sensor;
  r.tilt_s = util::SecondsSince(t);

  // --- look ahead: the next frame levelled and detected while this one is fused ---
  if (s.expected) {
    s.started = std::move(s.expected);
    s.expected.reset();
    s.started->result = std::async(
        std::launch::async,
        [image = std::move(s.started->image), prior = s.tilt->Prior(s.started->T_world_sensor),
         config = s.config]() mutable {
          return LevelAndDetect(std::move(image), prior, config, true);
        });
  }

  // --- fuse ---
  t = Clock::now();
  Expected<FrameSummary> fused =
      s.map.Integrate(levelled_image, *detection, *classification, r.T_world_sensor, stamp_s, s.fused);
  if (!fused) return fused.error();
  r.fuse_s = util::SecondsSince(t);
  r.fused = *fused;
  s.previous.emplace(stamp_s, T_world_sensor);
  ++s.processed;
  ++s.fused;
  return r;
}

Expected<MapperRecord> Mapper::Process(const std::vector<Eigen::Vector3f>& points,
                                       const od::SphericalModel& model,
                                       const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                       const std::vector<ImuSample>& imu,
                                       const std::vector<std::int32_t>& rows,
                                       const std::vector<std::int32_t>& cols) {
  if (!T_world_sensor.matrix().allFinite()) return Error{"mapper: non-finite pose"};
  Expected<od::RangeImage> image =
      od::RangeImage::FromPoints(points, model, UpIn(state_->tilt->Prior(T_world_sensor)), rows, cols);
  if (!image) return image.error();
  return Process(std::move(*image), T_world_sensor, stamp_s, imu);
}

Status Mapper::SaveCheckpoint(const std::filesystem::path& dir_or_file,
                              std::string_view app_data) const {
  const State& s = *state_;
  json previous = nullptr;
  if (s.previous) previous = {{"stamp_s", s.previous->first}, {"pose", PoseJson(s.previous->second)}};
  const json state = {{"format", kStateFormat},
                      {"tilt_mode", TiltModeName(s.tilt->mode())},
                      {"tilt_state", s.tilt->SaveState()},
                      {"processed", s.processed},
                      {"fused", s.fused},
                      {"previous", previous},
                      {"app", std::string(app_data)}};
  return map::SaveCheckpoint(s.map, dir_or_file, state.dump());
}

Expected<Mapper> Mapper::FromCheckpoint(const std::filesystem::path& dir_or_file,
                                        const MapperConfig& config, std::string* app_data,
                                        std::unique_ptr<TiltStep> tilt) {
  if (Status s = config.Validate(); !s) return s.error();
  const std::string file = CheckpointPath(dir_or_file).string();
  if (tilt == nullptr) {
    Expected<std::unique_ptr<TiltStep>> made = MakeTiltStep(config.tilt);
    if (!made) return made.error();
    tilt = std::move(*made);
  }
  std::string user_data;
  Expected<TerrainMap> map = LoadCheckpoint(dir_or_file, config.map, &user_data);
  if (!map) return map.error();
  auto state = std::make_unique<State>(config, std::move(*map), std::move(tilt));
  try {
    const json j = json::parse(user_data);
    if (j.at("format") != kStateFormat) {
      return Error{"checkpoint " + file + ": not a Mapper's (its state is of another format)"};
    }
    const std::string mode = j.at("tilt_mode").get<std::string>();
    if (mode != TiltModeName(state->tilt->mode())) {
      return Error{"checkpoint " + file + ": made with tilt mode '" + mode + "', not '" +
                   TiltModeName(state->tilt->mode()) + "' (tilt.refine)"};
    }
    if (Status s = state->tilt->RestoreState(j.at("tilt_state").get<std::string>()); !s) {
      return Error{"checkpoint " + file + ": " + s.message()};
    }
    state->processed = j.at("processed").get<std::int64_t>();
    state->fused = j.at("fused").get<std::int64_t>();
    const json& previous = j.at("previous");
    if (!previous.is_null()) {
      state->previous.emplace(previous.at("stamp_s").get<double>(), PoseFromJson(previous.at("pose")));
    }
    if (app_data != nullptr) *app_data = j.at("app").get<std::string>();
  } catch (const std::exception& e) {
    return Error{"checkpoint " + file + ": the Mapper's state is unreadable (" + e.what() + ")"};
  }
  return Mapper(std::move(state));
}

void Mapper::Expect(od::RangeImage image, const Eigen::Isometry3d& T_world_sensor,
                    double stamp_s) {
  State& s = *state_;
  s.expected.emplace();
  s.expected->image = std::move(image);
  s.expected->T_world_sensor = T_world_sensor;
  s.expected->stamp_s = stamp_s;
}

Status Mapper::SetSensorMount(const Eigen::Isometry3d& T_body_sensor) {
  const Eigen::Matrix3d R = T_body_sensor.linear();
  if (!T_body_sensor.matrix().allFinite() ||
      !(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || R.determinant() < 0.0) {
    return Error{"mapper: the sensor mount T_body_sensor must be finite and rigid"};
  }
  state_->T_body_sensor = T_body_sensor;
  return {};
}

const Eigen::Isometry3d& Mapper::sensor_mount() const { return state_->T_body_sensor; }

const TerrainMap& Mapper::map() const { return state_->map; }
const MapperConfig& Mapper::config() const { return state_->config; }
const TiltStep& Mapper::tilt() const { return *state_->tilt; }
Expected<std::vector<SmoothedFrame>> Mapper::SmoothTilt() { return state_->tilt->Smooth(); }

MapperConfig SmoothedPassConfig(const MapperConfig& first) {
  MapperConfig c = first;
  c.tilt.mode = TiltMode::kPrior;
  c.tilt.smooth = false;
  c.frames.max_speed_mps = std::numeric_limits<double>::max();
  c.frames.max_turn_rate_radps = std::numeric_limits<double>::max();
  return c;
}
std::int64_t Mapper::frames_processed() const { return state_->processed; }
std::int64_t Mapper::frames_fused() const { return state_->fused; }

}  // namespace cairn::map
