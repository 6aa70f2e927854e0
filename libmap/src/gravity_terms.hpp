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

/// The IMU integrations below depend on the gyro bias alone (the accelerometer bias enters
/// linearly, after them). They run with derivatives with respect to those 3 biases only and
/// are lifted, by the chain rule, to the caller's scalar, whose derivatives span every
/// parameter of the cost (9 or 15): the values are the same, the work per sample 3-5 times
/// less. BiasScalar<T>::type is double when T is double and Jet<double, 3> otherwise.
template <typename T>
struct BiasScalar {
  using type = ceres::Jet<double, 3>;
  static type Seed(const T& bias, int k) { return type(bias.a, k); }
  static T Lift(const type& x, const T* bias) {
    T out(x.a);
    out.v = x.v[0] * bias[0].v + x.v[1] * bias[1].v + x.v[2] * bias[2].v;
    return out;
  }
};
template <>
struct BiasScalar<double> {
  using type = double;
  static double Seed(double bias, int) { return bias; }
  static double Lift(double x, const double*) { return x; }
};

template <typename T, int R, int C>
Eigen::Matrix<T, R, C> LiftBias(const Eigen::Matrix<typename BiasScalar<T>::type, R, C>& m,
                                const T* bias) {
  Eigen::Matrix<T, R, C> out;
  for (int i = 0; i < R; ++i) {
    for (int j = 0; j < C; ++j) out(i, j) = BiasScalar<T>::Lift(m(i, j), bias);
  }
  return out;
}

/// One raw IMU sample cut to an integration span: the span runs `before_s` up to the
/// sample's stamp and `after_s` beyond it (both >= 0, clipped to the span's ends). Its
/// specific force is used when the stamp lies inside the span (use_force).
struct ImuSegment {
  Eigen::Vector3d omega_imu = Eigen::Vector3d::Zero();  ///< [rad/s], measured
  Eigen::Vector3d force_imu = Eigen::Vector3d::Zero();  ///< [m/s^2], measured
  double before_s = 0.0;
  double after_s = 0.0;
  bool use_force = true;
};

/// Gyro-integrated rotation between consecutive frames k and k+1:
///   r = Log(dR(bg)^T R_world_body_k^T R_world_body_k+1) / sigma_rad      [3, rad / rad]
/// dR(bg) = prod_j Exp(R_body_imu (omega_j - bg) d_j) over the samples' spans, in time order.
/// sigma_rad = sqrt(gyro_sigma^2 sum_j d_j^2 + floor^2): white gyro noise integrated.
struct GyroTerm {
  std::vector<ImuSegment> segments;  ///< in time order, from t_k to t_k+1
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  double sigma_rad = 1e-3;

  template <typename T>
  bool operator()(const T* rpy_k, const T* rpy_k1, const T* bg, T* residual) const {
    using M3 = Eigen::Matrix<T, 3, 3>;
    using V3 = Eigen::Matrix<T, 3, 1>;
    using B = BiasScalar<T>;
    using S = typename B::type;
    using M3s = Eigen::Matrix<S, 3, 3>;
    using V3s = Eigen::Matrix<S, 3, 1>;
    const V3s bias(B::Seed(bg[0], 0), B::Seed(bg[1], 1), B::Seed(bg[2], 2));
    const M3s R_bi = R_body_imu.cast<S>();
    M3s dR_s = M3s::Identity();
    for (const ImuSegment& s : segments) {
      const V3s w = R_bi * (s.omega_imu.cast<S>() - bias);
      dR_s = dR_s * Exp<S>(w * S(s.before_s + s.after_s));
    }
    const M3 dR = LiftBias<T>(dR_s, bg);
    const M3 rel = WorldFromBody(rpy_k).transpose() * WorldFromBody(rpy_k1);
    const V3 e = Log<T>(M3(dR.transpose() * rel));
    for (int i = 0; i < 3; ++i) residual[i] = e[i] / T(sigma_rad);
    return true;
  }
};

/// Accelerometer against gravity plus the motion the odometry (or a known velocity)
/// implies, over the span [t_a, t_b] of frames a = k - m .. b = k + m around frame k, in
/// frame k's body axes:
///   m = mean_j dR_kj(bg) R_body_imu (f_j - ba)                           (measured)
///   e = R_level_body_k^T ((v_b - v_a) / (t_b - t_a) + g e_z)              (expected)
///   r = (m - e) / sigma_mps2                                              [3, m/s^2 / m/s^2]
/// v_a, v_b: the velocities at the span's ends, in frame k's level frame (z up, x along its
/// measured heading): horizontal parts given (odometry displacements, so along-track
/// changes of speed and the lateral speed x yaw rate both appear); vertical parts given
/// too (a known velocity), or, for a ground vehicle whose velocity lies along its nose,
/// -|v_xy| tan(pitch) of frames a and b. dR_kj: the gyro-integrated rotation from t_k to
/// sample j (backwards for the samples before t_k). A span of several frames averages the
/// odometry's displacement noise down (it enters divided by the span). sigma_mps2 =
/// sqrt(accel_sigma^2 / N + motion_sigma^2 + odometry part^2); used with a robust loss.
struct AccelTerm {
  std::vector<ImuSegment> forward;   ///< from t_k to t_b, in time order
  std::vector<ImuSegment> backward;  ///< from t_k back to t_a, in reverse time order
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_minus = Eigen::Vector3d::Zero();  ///< v_a [m/s], level frame of k
  Eigen::Vector3d v_plus = Eigen::Vector3d::Zero();   ///< v_b
  bool vertical_from_pitch = true;  ///< v.z from the pitch (ground vehicle) or as given
  double span_s = 0.1;              ///< t_b - t_a [s]
  double gravity_mps2 = 9.80665;
  double sigma_mps2 = 0.05;

  template <typename T>
  bool operator()(const T* rpy_prev, const T* rpy_k, const T* rpy_next, const T* ba, const T* bg,
                  T* residual) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    using B = BiasScalar<T>;
    using S = typename B::type;
    using M3s = Eigen::Matrix<S, 3, 3>;
    using V3s = Eigen::Matrix<S, 3, 1>;
    // sum_j dR_kj R_bi (f_j - ba) = sum_j dR_kj R_bi f_j - (sum_j dR_kj) R_bi ba: the
    // rotations depend on the gyro bias only.
    const V3s gyro_bias(B::Seed(bg[0], 0), B::Seed(bg[1], 1), B::Seed(bg[2], 2));
    const M3s R_bi = R_body_imu.cast<S>();
    V3s sum_force = V3s::Zero();
    M3s sum_rotation = M3s::Zero();
    int n = 0;
    M3s R = M3s::Identity();
    for (const ImuSegment& s : forward) {
      const V3s w = R_bi * (s.omega_imu.cast<S>() - gyro_bias);
      R = R * Exp<S>(w * S(s.before_s));
      if (s.use_force) {
        sum_force += R * (R_body_imu * s.force_imu).cast<S>();
        sum_rotation += R;
        ++n;
      }
      R = R * Exp<S>(w * S(s.after_s));
    }
    R = M3s::Identity();
    for (const ImuSegment& s : backward) {
      const V3s w = R_bi * (s.omega_imu.cast<S>() - gyro_bias);
      R = R * Exp<S>(V3s(-w * S(s.after_s)));
      if (s.use_force) {
        sum_force += R * (R_body_imu * s.force_imu).cast<S>();
        sum_rotation += R;
        ++n;
      }
      R = R * Exp<S>(V3s(-w * S(s.before_s)));
    }
    if (n == 0) return false;
    const Eigen::Map<const V3> acc_bias(ba);
    const V3 measured = (LiftBias<T>(sum_force, bg) -
                         LiftBias<T>(sum_rotation, bg) * (R_body_imu.cast<T>() * acc_bias)) /
                        T(n);

    V3 vm = v_minus.cast<T>(), vp = v_plus.cast<T>();
    if (vertical_from_pitch) {
      vm[2] = -v_minus.head<2>().norm() * tan(rpy_prev[1]);
      vp[2] = -v_plus.head<2>().norm() * tan(rpy_next[1]);
    }
    const V3 accel_level = (vp - vm) / T(span_s) + V3(T(0.0), T(0.0), T(gravity_mps2));
    const V3 expected = LevelFromBody(rpy_k).transpose() * accel_level;
    for (int i = 0; i < 3; ++i) residual[i] = (measured[i] - expected[i]) / T(sigma_mps2);
    return true;
  }
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
/// dh = -d tan((pitch_k + pitch_k+1) / 2) for a ground vehicle that moved d metres
/// (planar) along its nose, or the known vertical displacement.
struct HeightStepTerm {
  double distance_m = 0.0;
  bool from_pitch = true;
  double known_dh_m = 0.0;
  double sigma_m = 0.02;
  template <typename T>
  bool operator()(const T* h_k, const T* h_k1, const T* rpy_k, const T* rpy_k1,
                  T* residual) const {
    const T dh = from_pitch ? -T(distance_m) * tan((rpy_k[1] + rpy_k1[1]) * T(0.5))
                            : T(known_dh_m);
    residual[0] = (h_k1[0] - h_k[0] - dh) / T(sigma_m);
    return true;
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
