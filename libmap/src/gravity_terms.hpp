// The error terms of GravityEstimator, as Ceres functors (automatic derivatives), each
// whitened by its stated noise. Internal to libmap; the test of the derivatives includes it.
//
// States (parameter blocks), world z up, radians, metres:
//   rpy[3]    a frame's body attitude, Z-Y-X: R_world_body = Rz(yaw) Ry(pitch) Rx(roll)
//             (pitch > 0 nose down, roll > 0 left side up, as sim::RotationFromAttitude).
//             R_level_body = Ry(pitch) Rx(roll) is the attitude without heading.
//   h[1]      a frame's body height [m] (relative to the first frame's anchor).
//   ba[3]     accelerometer bias, IMU frame [m/s^2]: f_measured = f_true + ba.
//   bg[3]     gyro bias, IMU frame [rad/s]: omega_measured = omega_true + bg.
//   prior_bias[2]  the IMU attitude output's roll and pitch bias [rad].
//   mount[2]  the sensor mount's tilt correction (roll, pitch about the body's x and y)
//             [rad]: R_body_sensor = Ry(mount[1]) Rx(mount[0]) R_body_sensor_nominal.
//   scale[1]  the wheel odometry's distance scale error s: odometry distance = (1 + s) x
//             true distance (a wheel radius off by s).
// The IMU frame is placed on the body by a known rotation R_body_imu (the body frame is
// defined by the IMU; a misalignment between the IMU and the sensor is the mount's).
#pragma once

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Core>
#include <cmath>
#include <utility>
#include <vector>

namespace cairn::map::gravity {

template <typename T>
Eigen::Matrix<T, 3, 3> RotX(const T& a) {
  Eigen::Matrix<T, 3, 3> R;
  const T c = cos(a), s = sin(a), o(0.0), l(1.0);
  R << l, o, o, o, c, -s, o, s, c;
  return R;
}
template <typename T>
Eigen::Matrix<T, 3, 3> RotY(const T& a) {
  Eigen::Matrix<T, 3, 3> R;
  const T c = cos(a), s = sin(a), o(0.0), l(1.0);
  R << c, o, s, o, l, o, -s, o, c;
  return R;
}
template <typename T>
Eigen::Matrix<T, 3, 3> RotZ(const T& a) {
  Eigen::Matrix<T, 3, 3> R;
  const T c = cos(a), s = sin(a), o(0.0), l(1.0);
  R << c, -s, o, s, c, o, o, o, l;
  return R;
}

/// R_world_body from rpy = (roll, pitch, yaw).
template <typename T>
Eigen::Matrix<T, 3, 3> WorldFromBody(const T* rpy) {
  return RotZ(rpy[2]) * RotY(rpy[1]) * RotX(rpy[0]);
}
/// R_level_body: the attitude without its heading.
template <typename T>
Eigen::Matrix<T, 3, 3> LevelFromBody(const T* rpy) {
  return RotY(rpy[1]) * RotX(rpy[0]);
}

/// The rise of a step (dx, dy) on the plane that a ground vehicle's wheels stand on, given
/// in the level frame of the vehicle's own heading (x forward, y left) and its roll and
/// pitch: the plane's normal is R_level_body e_z = (sin p cos r, -sin r, cos p cos r), so
///   dz = -(n_x dx + n_y dy) / n_z = -dx tan(p) + dy tan(r) / cos(p).
/// Along the nose (dy = 0) it is -dx tan(p); a step to the side (a slip, a chord across a
/// corner) rises by the roll.
template <typename T>
T RiseOnWheelPlane(const T* rpy, const T& dx, const T& dy) {
  return -dx * tan(rpy[1]) + dy * tan(rpy[0]) / cos(rpy[1]);
}

template <typename T>
Eigen::Matrix<T, 3, 3> Exp(const Eigen::Matrix<T, 3, 1>& w) {
  Eigen::Matrix<T, 3, 3> R;
  ceres::AngleAxisToRotationMatrix(w.data(), R.data());  // both column-major
  return R;
}

template <typename T>
Eigen::Matrix<T, 3, 1> Log(const Eigen::Matrix<T, 3, 3>& R) {
  Eigen::Matrix<T, 3, 1> w;
  ceres::RotationMatrixToAngleAxis(R.data(), w.data());
  return w;
}

/// One raw IMU sample cut to an integration span: the span runs `before_s` up to the
/// sample's stamp and `after_s` beyond it (both >= 0, clipped to the span's ends). Its
/// specific force is used when the stamp lies inside the span (use_force), with the weight
/// the accelerometer term gives it (its averaging kernel).
struct ImuSegment {
  Eigen::Vector3d omega_imu = Eigen::Vector3d::Zero();  ///< [rad/s], measured
  Eigen::Vector3d force_imu = Eigen::Vector3d::Zero();  ///< [m/s^2], measured
  double before_s = 0.0;
  double after_s = 0.0;
  bool use_force = true;
  double weight = 1.0;  ///< of its specific force in the accelerometer term's mean
};

/// The IMU integrations of the terms below, at a gyro bias bg (S: double, or a Jet for
/// derivatives with respect to bg).
///
/// The gyro-integrated rotation over `segments`, in time order:
///   dR(bg) = prod_j Exp(R_body_imu (omega_j - bg) d_j)
template <typename S>
Eigen::Matrix<S, 3, 3> IntegrateRotation(const std::vector<ImuSegment>& segments,
                                         const Eigen::Matrix3d& R_body_imu,
                                         const Eigen::Matrix<S, 3, 1>& bg) {
  using M3s = Eigen::Matrix<S, 3, 3>;
  using V3s = Eigen::Matrix<S, 3, 1>;
  const M3s R_bi = R_body_imu.cast<S>();
  M3s dR = M3s::Identity();
  for (const ImuSegment& s : segments) {
    const V3s w = R_bi * (s.omega_imu.cast<S>() - bg);
    dR = dR * Exp<S>(w * S(s.before_s + s.after_s));
  }
  return dR;
}

/// The specific forces rotated into frame k's body axes, forward from t_k and backward to
/// it: sum_j w_j dR_kj(bg) R_body_imu f_j (sum_force), sum_j w_j dR_kj(bg) (sum_rotation),
/// over the samples whose force is used, w_j their weights (sum_weight, and sum_weight_sq
/// of their squares). The measured mean is (sum_force - sum_rotation
/// R_body_imu ba) / sum_weight: the accelerometer bias enters linearly.
template <typename S>
struct ForceSums {
  Eigen::Matrix<S, 3, 1> sum_force = Eigen::Matrix<S, 3, 1>::Zero();
  Eigen::Matrix<S, 3, 3> sum_rotation = Eigen::Matrix<S, 3, 3>::Zero();
  double sum_weight = 0.0, sum_weight_sq = 0.0;
};
template <typename S>
ForceSums<S> IntegrateForces(const std::vector<ImuSegment>& forward,
                             const std::vector<ImuSegment>& backward,
                             const Eigen::Matrix3d& R_body_imu, const Eigen::Matrix<S, 3, 1>& bg) {
  using M3s = Eigen::Matrix<S, 3, 3>;
  using V3s = Eigen::Matrix<S, 3, 1>;
  const M3s R_bi = R_body_imu.cast<S>();
  ForceSums<S> out;
  M3s R = M3s::Identity();
  for (const ImuSegment& s : forward) {
    const V3s w = R_bi * (s.omega_imu.cast<S>() - bg);
    R = R * Exp<S>(w * S(s.before_s));
    if (s.use_force) {
      out.sum_force += S(s.weight) * (R * (R_body_imu * s.force_imu).cast<S>());
      out.sum_rotation += S(s.weight) * R;
      out.sum_weight += s.weight;
      out.sum_weight_sq += s.weight * s.weight;
    }
    R = R * Exp<S>(w * S(s.after_s));
  }
  R = M3s::Identity();
  for (const ImuSegment& s : backward) {
    const V3s w = R_bi * (s.omega_imu.cast<S>() - bg);
    R = R * Exp<S>(V3s(-w * S(s.after_s)));
    if (s.use_force) {
      out.sum_force += S(s.weight) * (R * (R_body_imu * s.force_imu).cast<S>());
      out.sum_rotation += S(s.weight) * R;
      out.sum_weight += s.weight;
      out.sum_weight_sq += s.weight * s.weight;
    }
    R = R * Exp<S>(V3s(-w * S(s.before_s)));
  }
  return out;
}

using Jet3 = ceres::Jet<double, 3>;
inline Eigen::Matrix<Jet3, 3, 1> SeedBias(const Eigen::Vector3d& bg) {
  return {Jet3(bg.x(), 0), Jet3(bg.y(), 1), Jet3(bg.z(), 2)};
}

/// Gyro-integrated rotation between consecutive frames k and k+1:
///   r = Log(dR(bg)^T R_world_body_k^T R_world_body_k+1) / sigma_rad      [3, rad / rad]
/// dR(bg) = prod_j Exp(R_body_imu (omega_j - bg) d_j) over the samples' spans, in time order
/// (IntegrateRotation), pre-integrated once at bg0 (Preintegrate) and moved to bg to first
/// order, as visual-inertial estimators do (Forster et al., "On-manifold preintegration",
/// T-RO 2017): dR(bg) = dR(bg0) Exp(J (bg - bg0)), J = d Log(dR(bg0)^T dR(bg)) / d bg.
/// The window moves bg0 to the latest estimate every frame, where the residual is exact;
/// the rest is second order in bg - bg0.
/// sigma_rad = sqrt(gyro_sigma^2 sum_j d_j^2 + floor^2): white gyro noise integrated.
struct GyroTerm {
  std::vector<ImuSegment> segments;  ///< in time order, from t_k to t_k+1
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  double sigma_rad = 1e-3;

  /// Integrates the segments at gyro bias bg0; the residual is valid only after this.
  void Preintegrate(const Eigen::Vector3d& bg0) {
    const Eigen::Matrix<Jet3, 3, 3> dR =
        IntegrateRotation<Jet3>(segments, R_body_imu, SeedBias(bg0));
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) dR0_(i, j) = dR(i, j).a;
    }
    for (int k = 0; k < 3; ++k) {
      Eigen::Matrix3d d;
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) d(i, j) = dR(i, j).v[k];
      }
      const Eigen::Matrix3d m = dR0_.transpose() * d;  // skew-symmetric: [J e_k]x
      J_.col(k) = 0.5 * Eigen::Vector3d(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1));
    }
    bg0_ = bg0;
    ready_ = true;
  }

  template <typename T>
  bool operator()(const T* rpy_k, const T* rpy_k1, const T* bg, T* residual) const {
    using M3 = Eigen::Matrix<T, 3, 3>;
    using V3 = Eigen::Matrix<T, 3, 1>;
    if (!ready_) return false;
    const V3 db = Eigen::Map<const V3>(bg) - bg0_.cast<T>();
    const M3 dR = dR0_.cast<T>() * Exp<T>(V3(J_.cast<T>() * db));
    const M3 rel = WorldFromBody(rpy_k).transpose() * WorldFromBody(rpy_k1);
    const V3 e = Log<T>(M3(dR.transpose() * rel));
    for (int i = 0; i < 3; ++i) residual[i] = e[i] / T(sigma_rad);
    return true;
  }

 private:
  Eigen::Matrix3d dR0_ = Eigen::Matrix3d::Identity(), J_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d bg0_ = Eigen::Vector3d::Zero();
  bool ready_ = false;
};

/// Accelerometer against gravity plus the motion the odometry (or a known velocity)
/// implies, around frame k (frames a = k - m and b = k + m), in frame k's body axes:
///   m = sum_j w_j dR_kj(bg) R_body_imu (f_j - ba) / sum_j w_j             (measured)
///   e = R_level_body_k^T ((v_b - v_a) / span + g e_z)                     (expected)
///   r = (m - e) / sigma_mps2                                              [3, m/s^2 / m/s^2]
/// v_a, v_b: the velocities of frames a and b, in frame k's level frame (z up, x along its
/// measured heading): horizontal parts given (odometry displacements, so along-track
/// changes of speed and the lateral speed x yaw rate both appear; divided by 1 + s, the
/// odometry's scale), vertical parts given too (a known velocity, which s leaves alone),
/// or, for a ground vehicle, the rise of v_xy on the plane of its wheels at frames a and b
/// (RiseOnWheelPlane, with v_xy turned into each one's own heading). A velocity from the odometry
/// is the mean over a chord [t-, t+] (the displacement between the neighbouring frames over their
/// time), so v_b - v_a is the acceleration weighted by K(t) = F_a(t) - F_b(t), F the fraction of
/// each chord before t: a trapezoid from t_a- to t_b+ (a triangle when the chords meet),
/// of integral span = mid_b - mid_a. The measured force is averaged with the same kernel,
/// w_j = K(t_j) (for known instantaneous velocities K is 1 on [t_a, t_b]): averaged
/// uniformly over [t_a, t_b] instead, a weave or a change of speed at the frame rate
/// biased the term, and the accelerometer bias absorbed it (the test
/// GravityEstimator.AWeaveBetweenSlowFramesIsNotTakenForATilt). dR_kj: the gyro-integrated rotation
/// from t_k to sample j (backwards for the samples before t_k). The sums over the samples
/// (IntegrateForces) are pre-integrated once at bg0 and moved to bg to first order (their
/// derivatives with respect to bg), as GyroTerm's rotation; exact in ba. A span of several
/// frames averages the odometry's displacement noise down (it enters divided by the span).
/// sigma_mps2 = sqrt(accel_sigma^2 sum w^2 / (sum w)^2 + motion_sigma^2 + odometry
/// part^2); used with a robust loss.
struct AccelTerm {
  std::vector<ImuSegment> forward;   ///< from t_k to the kernel's end, in time order
  std::vector<ImuSegment> backward;  ///< from t_k back to its start, in reverse time order
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_minus = Eigen::Vector3d::Zero();  ///< v_a [m/s], level frame of k
  Eigen::Vector3d v_plus = Eigen::Vector3d::Zero();   ///< v_b
  bool vertical_from_pitch = true;  ///< v.z from the wheels' plane (ground vehicle) or as given
  /// The measured headings of frames a and b less frame k's [rad]: v_a, v_b turned into
  /// a's and b's own heading.
  double yaw_minus_rad = 0.0, yaw_plus_rad = 0.0;
  double span_s = 0.1;              ///< integral of the kernel [s]
  double gravity_mps2 = 9.80665;
  double sigma_mps2 = 0.05;

  /// Integrates the samples at gyro bias bg0; the residual is valid only after this.
  void Preintegrate(const Eigen::Vector3d& bg0) {
    const ForceSums<Jet3> sums =
        IntegrateForces<Jet3>(forward, backward, R_body_imu, SeedBias(bg0));
    for (int i = 0; i < 3; ++i) {
      force0_(i) = sums.sum_force(i).a;
      for (int k = 0; k < 3; ++k) force_J_(i, k) = sums.sum_force(i).v[k];
      for (int j = 0; j < 3; ++j) {
        rotation0_(i, j) = sums.sum_rotation(i, j).a;
        for (int k = 0; k < 3; ++k) rotation_J_[k](i, j) = sums.sum_rotation(i, j).v[k];
      }
    }
    weight_sum_ = sums.sum_weight;
    weight_sq_sum_ = sums.sum_weight_sq;
    bg0_ = bg0;
    ready_ = true;
  }

  /// (sum w)^2 / sum w^2 of the samples used: their number when the weights are equal.
  double effective_samples() const {
    return weight_sq_sum_ > 0.0 ? weight_sum_ * weight_sum_ / weight_sq_sum_ : 0.0;
  }

  template <typename T>
  bool operator()(const T* rpy_prev, const T* rpy_k, const T* rpy_next, const T* ba, const T* bg,
                  const T* scale, T* residual) const {
    using M3 = Eigen::Matrix<T, 3, 3>;
    using V3 = Eigen::Matrix<T, 3, 1>;
    if (!ready_ || !(weight_sum_ > 0.0)) return false;
    const V3 db = Eigen::Map<const V3>(bg) - bg0_.cast<T>();
    const V3 sum_force = force0_.cast<T>() + force_J_.cast<T>() * db;
    const M3 sum_rotation = rotation0_.cast<T>() + rotation_J_[0].cast<T>() * db[0] +
                            rotation_J_[1].cast<T>() * db[1] + rotation_J_[2].cast<T>() * db[2];
    const Eigen::Map<const V3> acc_bias(ba);
    const V3 measured =
        (sum_force - sum_rotation * (R_body_imu.cast<T>() * acc_bias)) / T(weight_sum_);

    V3 vm = v_minus.cast<T>(), vp = v_plus.cast<T>();
    if (vertical_from_pitch) {
      // Odometry velocities: the true ones are (1 + s)^-1 of them.
      const T inv = T(1.0) / (T(1.0) + scale[0]);
      vm.template head<2>() *= inv;
      vp.template head<2>() *= inv;
      vm[2] = RiseInOwnHeading(rpy_prev, yaw_minus_rad, vm);
      vp[2] = RiseInOwnHeading(rpy_next, yaw_plus_rad, vp);
    }
    const V3 accel_level = (vp - vm) / T(span_s) + V3(T(0.0), T(0.0), T(gravity_mps2));
    const V3 expected = LevelFromBody(rpy_k).transpose() * accel_level;
    for (int i = 0; i < 3; ++i) residual[i] = (measured[i] - expected[i]) / T(sigma_mps2);
    return true;
  }

 private:
  // v (frame k's level frame) climbing the wheels' plane of a frame heading yaw from k's.
  template <typename T>
  static T RiseInOwnHeading(const T* rpy, double yaw, const Eigen::Matrix<T, 3, 1>& v) {
    const double c = std::cos(yaw), s = std::sin(yaw);
    return RiseOnWheelPlane(rpy, T(c) * v[0] + T(s) * v[1], T(-s) * v[0] + T(c) * v[1]);
  }

  Eigen::Vector3d force0_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d force_J_ = Eigen::Matrix3d::Zero();  // column k: d sum_force / d bg_k
  Eigen::Matrix3d rotation0_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d rotation_J_[3] = {Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Zero(),
                                    Eigen::Matrix3d::Zero()};
  Eigen::Vector3d bg0_ = Eigen::Vector3d::Zero();
  double weight_sum_ = 0.0, weight_sq_sum_ = 0.0;
  bool ready_ = false;
};

/// The IMU's attitude output (its filter's roll and pitch) as a prior, with a constant bias
/// of its own (b[2], a slow state: the filter's error is mostly a bias, which would
/// otherwise pass for information after many frames):
///   r = (wrap(roll + b_roll - roll_imu), pitch + b_pitch - pitch_imu) / sigma_rad
///                                                                          [2, rad / rad]
struct AttitudePriorTerm {
  double roll_rad = 0.0, pitch_rad = 0.0, sigma_rad = 0.01;
  template <typename T>
  bool operator()(const T* rpy, const T* bias, T* residual) const {
    const T d_roll = rpy[0] + bias[0] - T(roll_rad);
    residual[0] = atan2(sin(d_roll), cos(d_roll)) / T(sigma_rad);
    residual[1] = (rpy[1] + bias[1] - T(pitch_rad)) / T(sigma_rad);
    return true;
  }
};

/// The measured heading (odometry, or a reference) as a prior on yaw:
///   r = wrap(yaw - yaw_measured) / sigma_rad                              [1, rad / rad]
struct YawPriorTerm {
  double yaw_rad = 0.0, sigma_rad = 0.05;
  template <typename T>
  bool operator()(const T* rpy, T* residual) const {
    const T d = rpy[2] - T(yaw_rad);
    residual[0] = atan2(sin(d), cos(d)) / T(sigma_rad);
    return true;
  }
};

/// A vertical structure's axis (a trunk, a pole), measured in the sensor frame, is vertical:
///   u = R_level_body R_mount R_body_sensor d_sensor,  u oriented up (u.z > 0)
///   r = (u.x, u.y) / (|u| sigma_rad)                                       [2, rad / rad]
/// Real trees lean: used with a robust (Cauchy) loss.
/// A wall's horizontal normal is horizontal: r = u.z / (|u| sigma_rad)    [1, rad / rad]
struct VerticalTerm {
  Eigen::Vector3d direction_sensor = Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d R_body_sensor = Eigen::Matrix3d::Identity();  ///< nominal mount
  bool wall_normal = false;
  double sigma_rad = 0.035;

  template <typename T>
  bool operator()(const T* rpy, const T* mount, T* residual) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    const V3 d = (RotY(mount[1]) * RotX(mount[0]) * R_body_sensor.cast<T>()) *
                 direction_sensor.cast<T>();
    V3 u = LevelFromBody(rpy) * d;
    const T norm = u.norm();
    if (wall_normal) {
      residual[0] = u[2] / (norm * T(sigma_rad));
      return true;
    }
    if (u[2] < T(0.0)) u = -u;
    residual[0] = u[0] / (norm * T(sigma_rad));
    residual[1] = u[1] / (norm * T(sigma_rad));
    return true;
  }
};

/// Height between consecutive frames:
///   r = (h_k+1 - h_k - dh) / sigma_m                                       [1, m / m]
/// dh = RiseOnWheelPlane(mean roll and pitch of k and k+1, d / (1 + s)) for a ground
/// vehicle whose odometry measured the planar step d = (forward, left) in the mean heading
/// of k and k+1, s its scale error (-|d| / (1 + s) tan(mean pitch) along the nose); or the
/// known vertical displacement. (An odometry 1% long adds 1% to every climb: 13 cm over the 60 m
/// uphill drive, as much as a 0.12 deg pitch error, unless s is estimated.)
struct HeightStepTerm {
  double distance_m = 0.0;  ///< the step forward, in the mean heading [m]
  double lateral_m = 0.0;   ///< and to the left [m]
  bool from_pitch = true;
  double known_dh_m = 0.0;
  double sigma_m = 0.02;
  template <typename T>
  bool operator()(const T* h_k, const T* h_k1, const T* rpy_k, const T* rpy_k1, const T* scale,
                  T* residual) const {
    const T mean[2] = {(rpy_k[0] + rpy_k1[0]) * T(0.5), (rpy_k[1] + rpy_k1[1]) * T(0.5)};
    const T inv = T(1.0) / (T(1.0) + scale[0]);
    const T dh = from_pitch ? RiseOnWheelPlane(mean, T(distance_m) * inv, T(lateral_m) * inv)
                            : T(known_dh_m);
    residual[0] = (h_k1[0] - h_k[0] - dh) / T(sigma_m);
    return true;
  }
};

/// The ground seen by frame k where frame j saw it (GroundRise): with the sensors' rotations
///   R_ws = WorldFromBody(rpy) RotY(mount_pitch) RotX(mount_roll) R_body_sensor,
/// a tilt moves the matched ground of a frame from where it was placed (R_ws0, R_wb0) by
///   D = (R_ws R_ws0^T - I) offset + (R_wb - R_wb0) t_bs,
/// the ground turned about the sensor and carried with it by the body (t_bs the sensor's
/// position on the body); over ground of gradient g its height above the other frame's
/// ground changes by dZ = D_z - g . D_xy. An odometry scale s placed frame k s / (1 + s) of
/// the step d between them too far along, on ground higher by g . d times that, so
///   r = ((h_k - h_j) + dZ_k - dZ_j - rise + (g . d) s / (1 + s)) / sigma_m   [1, m / m]
struct GroundRiseTerm {
  Eigen::Matrix3d R_body_sensor = Eigen::Matrix3d::Identity();  ///< nominal mount
  Eigen::Matrix3d R0_k = Eigen::Matrix3d::Identity(), R0_j = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d Rb0_k = Eigen::Matrix3d::Identity(), Rb0_j = Eigen::Matrix3d::Identity();
  Eigen::Vector3d sensor_on_body = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_k = Eigen::Vector3d::Zero(), offset_j = Eigen::Vector3d::Zero();
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();  ///< g (dz/dx, dz/dy)
  double rise_m = 0.0, sigma_m = 0.05;
  double climb_m = 0.0;  ///< g . d: the rise of the ground over the odometry's step [m]

  template <typename T>
  bool operator()(const T* h_j, const T* h_k, const T* rpy_j, const T* rpy_k, const T* mount,
                  const T* scale, T* residual) const {
    const Eigen::Matrix<T, 3, 3> R_mount =
        RotY(mount[1]) * RotX(mount[0]) * R_body_sensor.cast<T>();
    const Eigen::Matrix<T, 3, 3> Rb_k = WorldFromBody(rpy_k), Rb_j = WorldFromBody(rpy_j);
    const T dz_k = OverGround<T>(Moved<T>(Rb_k * R_mount, R0_k, offset_k, Rb_k, Rb0_k));
    const T dz_j = OverGround<T>(Moved<T>(Rb_j * R_mount, R0_j, offset_j, Rb_j, Rb0_j));
    const T misplaced = T(climb_m) * scale[0] / (T(1.0) + scale[0]);
    residual[0] = ((h_k[0] - h_j[0]) + dz_k - dz_j - T(rise_m) + misplaced) / T(sigma_m);
    return true;
  }

 private:
  // D: how far the matched ground moved from its placement.
  template <typename T>
  Eigen::Matrix<T, 3, 1> Moved(const Eigen::Matrix<T, 3, 3>& R, const Eigen::Matrix3d& R0,
                               const Eigen::Vector3d& offset, const Eigen::Matrix<T, 3, 3>& Rb,
                               const Eigen::Matrix3d& Rb0) const {
    const Eigen::Matrix<T, 3, 1> turned = R * (R0.transpose() * offset).cast<T>();
    const Eigen::Matrix<T, 3, 1> carried = Rb * sensor_on_body.cast<T>();
    return (turned - offset.cast<T>()) + (carried - (Rb0 * sensor_on_body).cast<T>());
  }
  template <typename T>
  T OverGround(const Eigen::Matrix<T, 3, 1>& D) const {
    return D[2] - T(gradient.x()) * D[0] - T(gradient.y()) * D[1];
  }
};

/// A measured height (frame to map, or the start's anchor): r = (h - h_measured) / sigma_m.
struct HeightTerm {
  double height_m = 0.0, sigma_m = 0.05;
  template <typename T>
  bool operator()(const T* h, T* residual) const {
    residual[0] = (h[0] - T(height_m)) / T(sigma_m);
    return true;
  }
};

/// A linear(ised) Gaussian prior over several parameter blocks, the result of marginalising
/// the frames that left the window (or the slow states' initial prior):
///   r = L (x - x0) + e0,  with L^T L the information [1/unit^2] and L^T e0 the gradient
/// at x0. Its Jacobian is L, split by blocks.
class LinearPrior : public ceres::CostFunction {
 public:
  LinearPrior(Eigen::MatrixXd L, Eigen::VectorXd x0, Eigen::VectorXd e0,
              const std::vector<int>& block_sizes)
      : L_(std::move(L)), x0_(std::move(x0)), e0_(std::move(e0)) {
    for (int s : block_sizes) mutable_parameter_block_sizes()->push_back(s);
    set_num_residuals(static_cast<int>(L_.rows()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    Eigen::VectorXd dx(x0_.size());
    int offset = 0;
    for (std::size_t b = 0; b < sizes.size(); ++b) {
      for (int i = 0; i < sizes[b]; ++i) dx[offset + i] = parameters[b][i] - x0_[offset + i];
      offset += sizes[b];
    }
    Eigen::Map<Eigen::VectorXd>(residuals, L_.rows()) = L_ * dx + e0_;
    if (jacobians != nullptr) {
      offset = 0;
      for (std::size_t b = 0; b < sizes.size(); ++b) {
        if (jacobians[b] != nullptr) {
          Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
              jacobians[b], L_.rows(), sizes[b]) = L_.middleCols(offset, sizes[b]);
        }
        offset += sizes[b];
      }
    }
    return true;
  }

 private:
  Eigen::MatrixXd L_;
  Eigen::VectorXd x0_, e0_;
};

}  // namespace cairn::map::gravity
