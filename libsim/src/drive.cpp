#include "cairn/sim/drive.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "cairn/od/units.hpp"
#include "cairn/sim/random_scene.hpp"

namespace cairn::sim {
namespace {

double WrapAngle(double a) {
  a = std::remainder(a, 2.0 * kPi);  // in [-pi, pi]
  return a <= -kPi ? a + 2.0 * kPi : a;
}

// Standard normal from two uniform draws (Box-Muller): portable, unlike
// std::normal_distribution, so a seed gives the same drive everywhere.
double Gaussian(Random& rng) {
  const double u1 = 1.0 - rng.Uniform(0.0, 1.0);  // (0, 1]
  const double u2 = rng.Uniform(0.0, 1.0);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

Status DriveError(const std::string& field, const std::string& what) {
  return Error{"drive." + field + ": " + what};
}

Status CheckPositive(const std::string& field, double value) {
  if (!std::isfinite(value) || value <= 0.0) {
    return DriveError(field, "must be a finite number > 0, got " + std::to_string(value));
  }
  return {};
}

Status CheckNonNegative(const std::string& field, double value) {
  if (!std::isfinite(value) || value < 0.0) {
    return DriveError(field, "must be a finite number >= 0, got " + std::to_string(value));
  }
  return {};
}

// The checks a drive needs (DriveSpec::Validate, with the file's other rules, belongs to
// the world loader).
Status CheckDrivable(const DriveSpec& spec) {
  if (Status s = CheckPositive("speed_mps", spec.speed_mps); !s) return s;
  if (Status s = CheckPositive("frame_rate_hz", spec.frame_rate_hz); !s) return s;
  if (Status s = CheckPositive("wheelbase_m", spec.wheelbase_m); !s) return s;
  if (Status s = CheckPositive("track_m", spec.track_m); !s) return s;
  if (Status s = CheckNonNegative("odom_sigma_per_m", spec.odom_sigma_per_m); !s) return s;
  if (Status s = CheckNonNegative("odom_yaw_sigma_rad_per_m", spec.odom_yaw_sigma_rad_per_m); !s) {
    return s;
  }
  if (Status s = CheckNonNegative("imu_sigma_rad", spec.imu_sigma_rad); !s) return s;
  if (Status s = CheckNonNegative("turn_radius_m", spec.turn_radius_m); !s) return s;
  if (!std::isfinite(spec.imu_bias_rad)) return DriveError("imu_bias_rad", "must be finite");
  if (!std::isfinite(spec.sensor_pitch_rad)) {
    return DriveError("sensor_pitch_rad", "must be finite");
  }
  if (!spec.T_body_sensor_xyz.allFinite()) {
    return DriveError("T_body_sensor_xyz", "must be finite");
  }
  for (std::size_t i = 0; i < spec.waypoints.size(); ++i) {
    if (!spec.waypoints[i].allFinite()) {
      return DriveError("waypoints[" + std::to_string(i) + "]", "must be finite");
    }
  }
  if (!std::isfinite(spec.speed_wave_mps) || spec.speed_wave_mps < 0.0 ||
      spec.speed_wave_mps >= spec.speed_mps) {
    return DriveError("speed_wave_mps",
                      "must be in [0, speed_mps), got " + std::to_string(spec.speed_wave_mps));
  }
  if (Status s = CheckPositive("speed_wave_period_s", spec.speed_wave_period_s); !s) return s;
  if (!spec.sensor_misalignment_rad.allFinite()) {
    return DriveError("sensor_misalignment_rad", "must be finite");
  }
  return {};
}

// Distance driven at time t [m]: the integral of speed_mps + A sin(2 pi t / T).
double DistanceAt(const DriveSpec& spec, double t) {
  const double w = 2.0 * kPi / spec.speed_wave_period_s;
  return spec.speed_mps * t + spec.speed_wave_mps / w * (1.0 - std::cos(w * t));
}

// The time at which DistanceAt reaches s (monotone: the speed stays > 0).
double TimeAtDistance(const DriveSpec& spec, double s) {
  double lo = 0.0, hi = s / (spec.speed_mps - spec.speed_wave_mps);
  for (int i = 0; i < 100 && hi - lo > 1e-12; ++i) {
    const double mid = 0.5 * (lo + hi);
    (DistanceAt(spec, mid) < s ? lo : hi) = mid;
  }
  return hi;
}

// The waypoint path by arc length: straight segments, each corner rounded by a circular arc
// of radius turn_radius_m (smaller where a neighbouring segment is too short for it: an arc
// takes at most half of each), so that the heading changes continuously and the lateral
// acceleration stays v^2 / r; 0 keeps the corners sharp (a velocity jump at each). Extended
// along its first and last segments, so that the axles of a vehicle at either end still lie
// on a straight line.
class Path {
 public:
  Path(const std::vector<Eigen::Vector2d>& waypoints, double turn_radius_m) {
    std::vector<Eigen::Vector2d> points;
    for (const Eigen::Vector2d& p : waypoints) {
      if (points.empty() || (p - points.back()).norm() > 1e-9) points.push_back(p);
    }
    if (points.size() < 2) return;
    Eigen::Vector2d at = points[0];  // where the next straight piece starts
    for (std::size_t i = 1; i + 1 < points.size(); ++i) {
      const Eigen::Vector2d in = points[i] - points[i - 1], out = points[i + 1] - points[i];
      const Eigen::Vector2d a = in.normalized(), b = out.normalized();
      const double turn = std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));  // left > 0
      const double half = 0.5 * std::abs(turn);
      // A corner too slight to round, or a reversal (no arc turns back on itself), stays.
      if (turn_radius_m <= 0.0 || half < 1e-9 || half > 0.5 * kPi - 1e-6) {
        Line(at, points[i]);
        at = points[i];
        continue;
      }
      const double tangent =
          std::min({turn_radius_m * std::tan(half), 0.5 * in.norm(), 0.5 * out.norm()});
      const double radius = tangent / std::tan(half);
      Line(at, points[i] - tangent * a);
      Piece arc;
      arc.start = points[i] - tangent * a;
      arc.heading = std::atan2(a.y(), a.x());
      arc.curvature = (turn > 0.0 ? 1.0 : -1.0) / radius;
      arc.length = radius * std::abs(turn);
      Add(arc);
      at = points[i] + tangent * b;
    }
    Line(at, points.back());
  }

  bool Drivable() const { return !pieces_.empty(); }
  double Length() const { return pieces_.back().s0 + pieces_.back().length; }

  Eigen::Vector2d At(double s) const {
    // The piece holding s; beyond the ends, the end pieces (straight) extend.
    std::size_t i = 0;
    for (std::size_t lo = 0, hi = pieces_.size(); lo < hi;) {  // last piece with s0 <= s
      const std::size_t mid = (lo + hi) / 2;
      if (pieces_[mid].s0 <= s) {
        i = mid;
        lo = mid + 1;
      } else {
        hi = mid;
      }
    }
    const Piece& p = pieces_[i];
    const double u = s - p.s0;
    if (p.curvature == 0.0) return p.start + u / p.length * p.chord;
    const double h0 = p.heading, h = h0 + p.curvature * u;
    return p.start +
           Eigen::Vector2d(std::sin(h) - std::sin(h0), std::cos(h0) - std::cos(h)) / p.curvature;
  }

 private:
  struct Piece {
    double s0 = 0.0;  // arc length at its start
    Eigen::Vector2d start = Eigen::Vector2d::Zero();
    double length = 0.0;
    Eigen::Vector2d chord = Eigen::Vector2d::Zero();  // a line: end - start
    double heading = 0.0, curvature = 0.0;            // an arc: at its start, left > 0
  };
  void Add(Piece p) {
    p.s0 = pieces_.empty() ? 0.0 : pieces_.back().s0 + pieces_.back().length;
    pieces_.push_back(p);
  }
  void Line(const Eigen::Vector2d& from, const Eigen::Vector2d& to) {
    const double length = (to - from).norm();
    if (length <= 1e-9) return;
    Piece line;
    line.start = from;
    line.length = length;
    line.chord = to - from;
    Add(line);
  }
  std::vector<Piece> pieces_;
};

Eigen::Matrix3d Rx(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).matrix(); }
Eigen::Matrix3d Ry(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()).matrix(); }
Eigen::Matrix3d Rz(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix(); }

// x, y, yaw composed with an increment given in the pose's own frame.
Pose2D Compose(const Pose2D& a, double dx, double dy, double dyaw) {
  const double c = std::cos(a.yaw_rad), s = std::sin(a.yaw_rad);
  return {a.x_m + c * dx - s * dy, a.y_m + s * dx + c * dy, WrapAngle(a.yaw_rad + dyaw)};
}

}  // namespace

Status ImuSpec::Validate() const {
  if (!std::isfinite(rate_hz) || rate_hz <= 0.0) {
    return Error{"imu.rate_hz: must be a finite number > 0, got " + std::to_string(rate_hz)};
  }
  if (!accel_bias_mps2.allFinite()) return Error{"imu.accel_bias_mps2: must be finite"};
  if (!gyro_bias_radps.allFinite()) return Error{"imu.gyro_bias_radps: must be finite"};
  if (!misalignment_rad.allFinite()) return Error{"imu.misalignment_rad: must be finite"};
  if (!std::isfinite(accel_sigma_mps2) || accel_sigma_mps2 < 0.0) {
    return Error{"imu.accel_sigma_mps2: must be a finite number >= 0"};
  }
  if (!std::isfinite(gyro_sigma_radps) || gyro_sigma_radps < 0.0) {
    return Error{"imu.gyro_sigma_radps: must be a finite number >= 0"};
  }
  return {};
}

Eigen::Matrix3d RotationFromRollPitchYaw(const Eigen::Vector3d& rpy) {
  return Rz(rpy.z()) * Ry(rpy.y()) * Rx(rpy.x());
}

Eigen::Matrix3d RotationOpticalFromFlu() {
  Eigen::Matrix3d R;
  R << 0.0, -1.0, 0.0,  // x right = -y left
      0.0, 0.0, -1.0,   // y down = -z up
      1.0, 0.0, 0.0;    // z forward = x forward
  return R;
}

Eigen::Matrix3d RotationFromAttitude(const Attitude& attitude) {
  return Rz(attitude.yaw_rad) * Ry(attitude.pitch_rad) * Rx(attitude.roll_rad);
}

Attitude AttitudeFromRotation(const Eigen::Matrix3d& R) {
  Attitude a;
  a.pitch_rad = std::atan2(-R(2, 0), std::hypot(R(0, 0), R(1, 0)));
  a.yaw_rad = std::atan2(R(1, 0), R(0, 0));
  a.roll_rad = std::atan2(R(2, 1), R(2, 2));
  return a;
}

Eigen::Isometry3d BodyToSensor(const DriveSpec& spec, SensorFrame sensor) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = spec.T_body_sensor_xyz;
  // Pitching down turns x (forward) towards -z: a positive rotation about the body's y.
  T.linear() = Ry(spec.sensor_pitch_rad);
  if (sensor == SensorFrame::kCameraOptical) {
    T.linear() = T.linear() * RotationOpticalFromFlu().transpose();
  }
  return T;
}

std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t index) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

int DriveFrameCount(const DriveSpec& spec) {
  if (!CheckDrivable(spec)) return 0;
  const Path path(spec.waypoints, spec.turn_radius_m);
  if (!path.Drivable()) return 0;
  const double duration_s = spec.speed_wave_mps > 0.0 ? TimeAtDistance(spec, path.Length())
                                                      : path.Length() / spec.speed_mps;
  const double frames = duration_s * spec.frame_rate_hz;
  return static_cast<int>(std::floor(frames + 1e-9)) + 1;
}

Expected<Drive> SimulateDrive(const Terrain& terrain, const DriveSpec& spec, SensorFrame sensor,
                              std::uint64_t seed, int max_frames, const ImuSpec& imu) {
  if (Status s = CheckDrivable(spec); !s) return s.error();
  if (Status s = imu.Validate(); !s) return s.error();
  const Path path(spec.waypoints, spec.turn_radius_m);
  if (!path.Drivable()) {
    return Error{"drive.waypoints: need at least two distinct points, got " +
                 std::to_string(spec.waypoints.size())};
  }
  int frames = DriveFrameCount(spec);
  if (max_frames > 0) frames = std::min(frames, max_frames);

  Drive drive;
  drive.sensor = sensor;
  drive.T_body_sensor = BodyToSensor(spec, sensor);
  drive.T_body_sensor_true = drive.T_body_sensor;
  drive.T_body_sensor_true.linear() =
      drive.T_body_sensor.linear() * RotationFromRollPitchYaw(spec.sensor_misalignment_rad);
  drive.R_body_imu = RotationFromRollPitchYaw(imu.misalignment_rad);
  drive.path_length_m = path.Length();
  drive.errors.accel_bias_mps2 = imu.accel_bias_mps2;
  drive.errors.gyro_bias_radps = imu.gyro_bias_radps;

  // Drawn in a fixed order, once per drive, then per frame.
  Random rng(MixSeed(seed, 0x647269766555ULL));  // "driveU"
  drive.errors.odom_scale_error = spec.odom_sigma_per_m * Gaussian(rng);
  drive.errors.odom_yaw_drift_rad_per_m = spec.odom_yaw_sigma_rad_per_m * Gaussian(rng);
  drive.errors.imu_roll_bias_rad = spec.imu_bias_rad;
  drive.errors.imu_pitch_bias_rad = spec.imu_bias_rad;

  const double half_base = 0.5 * spec.wheelbase_m, half_track = 0.5 * spec.track_m;
  // The body's true pose after s metres: axles on the path, the plane through the four
  // wheel contacts. Sets attitude.
  auto body_pose = [&](double s, Attitude& attitude) {
    const Eigen::Vector2d xy = path.At(s);
    const Eigen::Vector2d chord = path.At(s + half_base) - path.At(s - half_base);
    const double yaw = std::atan2(chord.y(), chord.x());
    const Eigen::Vector2d forward(std::cos(yaw), std::sin(yaw)), left(-forward.y(), forward.x());
    const double h_fl = terrain.Height(xy + half_base * forward + half_track * left);
    const double h_fr = terrain.Height(xy + half_base * forward - half_track * left);
    const double h_rl = terrain.Height(xy - half_base * forward + half_track * left);
    const double h_rr = terrain.Height(xy - half_base * forward - half_track * left);
    // Slopes along the heading and to the left (exact for a plane, whose heights are linear);
    // with R = Rz Ry Rx the body's x and y axes lie in the plane when tan(pitch) = -slope_x
    // and tan(roll) = cos(pitch) slope_y.
    const double slope_x = 0.5 * ((h_fl + h_fr) - (h_rl + h_rr)) / spec.wheelbase_m;
    const double slope_y = 0.5 * ((h_fl + h_rl) - (h_fr + h_rr)) / spec.track_m;
    attitude.yaw_rad = yaw;
    attitude.pitch_rad = -std::atan(slope_x);
    attitude.roll_rad = std::atan(std::cos(attitude.pitch_rad) * slope_y);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = RotationFromAttitude(attitude);
    T.translation() << xy, 0.25 * (h_fl + h_fr + h_rl + h_rr);
    return T;
  };
  // Unclamped: the path extends beyond its ends (the IMU's differences look past them).
  auto distance_at = [&](double t) {
    return spec.speed_wave_mps > 0.0 ? DistanceAt(spec, t) : spec.speed_mps * t;
  };

  drive.samples.reserve(frames);
  for (int k = 0; k < frames; ++k) {
    DriveSample sample;
    sample.index = k;
    sample.stamp_s = k / spec.frame_rate_hz;
    sample.distance_m = std::min(distance_at(sample.stamp_s), path.Length());
    const double s = sample.distance_m;

    sample.T_world_body = body_pose(s, sample.attitude);
    const Eigen::Vector2d xy = sample.T_world_body.translation().head<2>();
    const double yaw = sample.attitude.yaw_rad;
    sample.T_world_sensor = sample.T_world_body * drive.T_body_sensor_true;
    sample.true_planar = {xy.x(), xy.y(), yaw};

    // Odometry: the true planar increment in the previous body frame, with errors.
    if (k == 0) {
      sample.odometry = sample.true_planar;
    } else {
      const DriveSample& prev = drive.samples.back();
      const Pose2D& a = prev.true_planar;
      const Eigen::Vector2d delta = xy - Eigen::Vector2d(a.x_m, a.y_m);
      const double c = std::cos(a.yaw_rad), sn = std::sin(a.yaw_rad);
      const double d = delta.norm();
      const double walk = spec.odom_sigma_per_m * std::sqrt(d);
      const double yaw_walk = spec.odom_yaw_sigma_rad_per_m * std::sqrt(d);
      const double scale = 1.0 + drive.errors.odom_scale_error;
      const double dx = scale * (c * delta.x() + sn * delta.y()) + walk * Gaussian(rng);
      const double dy = scale * (-sn * delta.x() + c * delta.y()) + walk * Gaussian(rng);
      const double dyaw = WrapAngle(yaw - a.yaw_rad) + drive.errors.odom_yaw_drift_rad_per_m * d +
                          yaw_walk * Gaussian(rng);
      sample.odometry = Compose(prev.odometry, dx, dy, dyaw);
    }

    // IMU attitude: the IMU frame's (the body's when the IMU is aligned).
    const Attitude imu_frame = imu.misalignment_rad.isZero()
                                   ? sample.attitude
                                   : AttitudeFromRotation(sample.T_world_body.linear() *
                                                          drive.R_body_imu);
    const double n_roll = Gaussian(rng), n_pitch = Gaussian(rng), n_yaw = Gaussian(rng);
    sample.imu.roll_rad =
        imu_frame.roll_rad + drive.errors.imu_roll_bias_rad + spec.imu_sigma_rad * n_roll;
    sample.imu.pitch_rad =
        imu_frame.pitch_rad + drive.errors.imu_pitch_bias_rad + spec.imu_sigma_rad * n_pitch;
    sample.imu.yaw_rad = WrapAngle(imu_frame.yaw_rad + spec.imu_sigma_rad * n_yaw);
    drive.samples.push_back(sample);
  }

  // Raw IMU, from the same pose function, with its own noise stream.
  Random imu_rng(MixSeed(seed, 0x696d75526177ULL));  // "imuRaw"
  const double dt = 1.0 / imu.rate_hz;
  const double end_s = drive.samples.back().stamp_s;
  auto T_world_imu = [&](double t) {
    Attitude unused;
    Eigen::Isometry3d T = body_pose(distance_at(t), unused);
    T.linear() = T.linear() * drive.R_body_imu;
    return T;
  };
  const int n_imu = static_cast<int>(std::floor(end_s * imu.rate_hz + 1e-9));
  drive.imu.reserve(static_cast<std::size_t>(std::max(0, n_imu)));
  for (int j = 0; j < n_imu; ++j) {
    ImuReading reading = IdealImuReading(T_world_imu, (j + 0.5) * dt, dt);
    for (int axis = 0; axis < 3; ++axis) {
      reading.specific_force_mps2[axis] +=
          imu.accel_bias_mps2[axis] + imu.accel_sigma_mps2 * Gaussian(imu_rng);
    }
    for (int axis = 0; axis < 3; ++axis) {
      reading.angular_rate_radps[axis] +=
          imu.gyro_bias_radps[axis] + imu.gyro_sigma_radps * Gaussian(imu_rng);
    }
    drive.imu.push_back(reading);
  }
  return drive;
}

}  // namespace cairn::sim
