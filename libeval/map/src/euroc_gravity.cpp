#include "cairn/eval/euroc_gravity.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/eval/plane_fit.hpp"
#include "cairn/map/gravity_estimator.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sources/asl_dataset.hpp"
#include "cairn/util/quantile.hpp"

namespace cairn::eval {
namespace {

/// The estimator's body for the VI-Sensor: its IMU's x axis points about up, so the body
/// is the IMU frame turned to put z there: z_body = x_imu, y_body = y_imu, x_body = -z_imu.
Eigen::Matrix3d EurocBodyFromImu() {
  Eigen::Matrix3d R;
  R << 0, 0, -1, 0, 1, 0, 1, 0, 0;
  return R;
}

/// The floor of a rectified depth image: RANSAC over planes whose normal lies within 40 deg
/// of the image's up (-y), 2 cm inlier band, points 0.3-6 m; then the least-squares plane of
/// its inliers (FitPlane), the normal turned up. Deterministic (fixed seed).
bool FloorNormal(const std::vector<Eigen::Vector3d>& points, Eigen::Vector3d* normal,
                 int* inliers_out) {
  if (points.size() < 100) return false;
  std::mt19937 rng(1);
  std::uniform_int_distribution<std::size_t> pick(0, points.size() - 1);
  const double band = 0.02, cos_gate = std::cos(40.0 * 3.14159265358979323846 / 180.0);
  int best = 0;
  Eigen::Vector3d best_n = Eigen::Vector3d::Zero();
  double best_d = 0.0;
  for (int it = 0; it < 400; ++it) {
    const Eigen::Vector3d a = points[pick(rng)], b = points[pick(rng)], c = points[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    if (std::abs(n.y()) < cos_gate) continue;
    const double d = -n.dot(a);
    int count = 0;
    for (std::size_t k = 0; k < points.size(); k += 4)
      count += std::abs(n.dot(points[k]) + d) < band;
    if (count > best) {
      best = count;
      best_n = n;
      best_d = d;
    }
  }
  if (best == 0) return false;
  std::vector<Eigen::Vector3d> in;
  for (const Eigen::Vector3d& p : points) {
    if (std::abs(best_n.dot(p) + best_d) < band) in.push_back(p);
  }
  *normal = FitPlane(in).normal;  // turned to -y: up in the optical frame
  *inliers_out = static_cast<int>(in.size());
  return true;
}

// The truth against its own IMU: over spans of 4 truth rows (0.2 s), the specific force
// in the world frame by the truth's attitude (interpolated per sample), less the truth's
// accelerometer bias, averaged, against the acceleration of the truth's velocity plus
// gravity along world z. Its mean is what the truth's world frame and gravity disagree on.
void TruthGravity(const sources::AslImu& imu, const std::vector<sources::AslGroundTruth>& truth,
                  EurocGravityResult* result) {
  constexpr int kSpan = 4;
  constexpr double kG = 9.80665;
  const Eigen::Matrix3d R_body_imu = imu.T_body_imu.linear();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero(), sum_sq = Eigen::Vector3d::Zero();
  int spans = 0;
  std::size_t j = 0;
  for (std::size_t k = 0; k + kSpan < truth.size(); k += kSpan) {
    const sources::AslGroundTruth& a = truth[k];
    const sources::AslGroundTruth& b = truth[k + kSpan];
    while (j < imu.samples.size() && imu.samples[j].stamp_ns <= a.stamp_ns) ++j;
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    int n = 0;
    for (std::size_t r = k; r < k + kSpan; ++r) {
      const sources::AslGroundTruth& g0 = truth[r];
      const sources::AslGroundTruth& g1 = truth[r + 1];
      for (; j < imu.samples.size() && imu.samples[j].stamp_ns <= g1.stamp_ns; ++j) {
        const sources::AslImuSample& s = imu.samples[j];
        const double u = (s.stamp_s - g0.stamp_s) / (g1.stamp_s - g0.stamp_s);
        const Eigen::Quaterniond q = g0.q_world_body.slerp(u, g1.q_world_body);
        const Eigen::Vector3d bias = (1.0 - u) * g0.accel_bias_mps2 + u * g1.accel_bias_mps2;
        force += q * (R_body_imu * (s.specific_force_mps2 - bias));
        ++n;
      }
    }
    if (n < kSpan * 9) continue;  // a gap in the IMU stream
    const Eigen::Vector3d expected =
        (b.v_world_mps - a.v_world_mps) / (b.stamp_s - a.stamp_s) + Eigen::Vector3d(0, 0, kG);
    const Eigen::Vector3d d = force / n - expected;
    sum += d;
    sum_sq += d.cwiseProduct(d);
    ++spans;
  }
  if (spans == 0) return;
  const Eigen::Vector3d mean = sum / spans;
  result->truth_gravity_tilt_deg = std::atan2(mean.head<2>().norm(), kG + mean.z()) / kDegToRad;
  result->truth_gravity_rms_mps2 =
      (sum_sq / spans - mean.cwiseProduct(mean)).cwiseMax(0.0).cwiseSqrt();
}

}  // namespace

/// `root` holds mav0/ and ov_data/euroc_mav/V1_01_easy.csv. `max_frames` > 0 stops early.
Expected<EurocGravityResult> RunEurocGravity(const std::filesystem::path& root, int max_frames) {
  Expected<sources::AslImu> imu = sources::ReadAslImu(root / "mav0");
  if (!imu) return imu.error();
  Expected<std::vector<sources::AslGroundTruth>> truth =
      sources::ReadOpenVinsGroundTruth(root / "ov_data" / "euroc_mav" / "V1_01_easy.csv");
  if (!truth) return truth.error();

  // The estimator's body E from the data set's body B: v_E = M v_B; the IMU S on it.
  const Eigen::Matrix3d R_body_imu = EurocBodyFromImu() * imu->T_body_imu.linear();
  map::GravityEstimatorConfig config;
  const double rate = imu->rate_hz;
  // The ADIS16448's noise densities, per sample at its rate.
  config.accel_sigma_mps2 = imu->accel_noise_density * std::sqrt(rate);
  config.gyro_sigma_radps = imu->gyro_noise_density * std::sqrt(rate);
  // The motion the true velocity's differences miss: against the truth's own attitude and
  // accelerometer bias, the specific force averaged over 0.2 s spans departs from them by
  // 0.02-0.03 m/s^2 RMS per axis (truth_gravity_rms_mps2 below); the terms' 0.1 s spans
  // (half span 1 at 20 Hz) see more of the velocity's noise, hence 0.05.
  config.motion_sigma_mps2 = 0.05;
  config.gyro_bias_sigma_radps = 0.1;  // its z bias is 0.077 rad/s
  config.yaw_sigma_rad = 0.02;         // the reference heading
  config.estimate_mount = false;       // no scene cues here
  config.accel_half_span_frames = 1;   // 0.1 s spans at 20 Hz
  config.window_frames = 10;
  config.covariance = true;  // the degeneracy flags come from it
  Expected<map::GravityEstimator> estimator =
      map::GravityEstimator::Create(config, R_body_imu, Eigen::Matrix3d::Identity());
  if (!estimator) return estimator.error();

  EurocGravityResult result;
  std::vector<double> tilt, roll, pitch, tilt_observed;
  std::size_t j = 0;
  // IMU samples before the first truth row are skipped, but for those within half a sample
  // period of it: they are the first frame's, which has no attitude to start from without.
  const auto half_period_ns = static_cast<std::int64_t>(0.5e9 / rate);
  while (j < imu->samples.size() &&
         imu->samples[j].stamp_ns < truth->front().stamp_ns - half_period_ns) {
    ++j;
  }
  Eigen::Vector3d rest_sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d rest_up = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < truth->size(); ++k) {
    if (max_frames > 0 && static_cast<int>(k) >= max_frames) break;
    const sources::AslGroundTruth& g = (*truth)[k];
    const Eigen::Matrix3d R_world_body =
        g.q_world_body.toRotationMatrix() * EurocBodyFromImu().transpose();
    map::GravityFrame frame;
    frame.stamp_s = g.stamp_s - truth->front().stamp_s;
    const double t0 = truth->front().stamp_s;
    for (; j < imu->samples.size() && imu->samples[j].stamp_ns <= g.stamp_ns; ++j) {
      const sources::AslImuSample& s = imu->samples[j];
      frame.imu.push_back({s.stamp_s - t0, s.specific_force_mps2, s.angular_rate_radps});
      if (g.stamp_s - t0 < 3.0) rest_sum += R_body_imu * s.specific_force_mps2;
    }
    if (g.stamp_s - t0 < 3.0) rest_up += R_world_body.transpose() * Eigen::Vector3d::UnitZ();
    result.imu_samples += static_cast<int>(frame.imu.size());
    const double yaw = std::atan2(R_world_body(1, 0), R_world_body(0, 0));
    frame.odometry_xy_yaw << g.p_world_body.x(), g.p_world_body.y(), yaw;
    frame.velocity_world_mps = g.v_world_mps;
    Expected<map::GravityEstimate> est = estimator->AddFrame(frame);
    if (!est) return est.error();
    ++result.frames;
    result.duration_s = frame.stamp_s;
    const Eigen::Vector3d up = R_world_body.transpose() * Eigen::Vector3d::UnitZ();
    tilt.push_back(std::atan2(up.cross(est->up_body).norm(), up.dot(est->up_body)) / kDegToRad);
    if (!est->Degenerate(map::GravityDegeneracy::State::kAccelBias) &&
        !est->Degenerate(map::GravityDegeneracy::State::kCovariance)) {
      tilt_observed.push_back(tilt.back());
      if (result.bias_observed_from_s < 0.0) result.bias_observed_from_s = frame.stamp_s;
    }
    const double true_roll = std::atan2(R_world_body(2, 1), R_world_body(2, 2));
    const double true_pitch =
        std::atan2(-R_world_body(2, 0), std::hypot(R_world_body(0, 0), R_world_body(1, 0)));
    roll.push_back(std::abs(std::remainder(est->roll_rad - true_roll, 2.0 * 3.14159265358979)) /
                   kDegToRad);
    pitch.push_back(std::abs(est->pitch_rad - true_pitch) / kDegToRad);
    result.accel_bias_mps2 = est->accel_bias_mps2;
    result.gyro_bias_radps = est->gyro_bias_radps;
    result.truth_accel_bias_mps2 = g.accel_bias_mps2;
    result.truth_gyro_bias_radps = g.gyro_bias_radps;
  }
  result.observed_frames = static_cast<int>(tilt_observed.size());
  if (!tilt_observed.empty()) {
    result.observed_tilt_median_deg = util::Quantile(tilt_observed, 0.5);
    result.observed_tilt_p95_deg = util::Quantile(tilt_observed, 0.95);
  }
  TruthGravity(*imu, *truth, &result);
  result.tilt_median_deg = util::Quantile(tilt, 0.5);
  result.tilt_p95_deg = util::Quantile(tilt, 0.95);
  result.tilt_max_deg = util::Quantile(tilt, 1.0);
  result.roll_median_deg = util::Quantile(roll, 0.5);
  result.roll_p95_deg = util::Quantile(roll, 0.95);
  result.pitch_median_deg = util::Quantile(pitch, 0.5);
  result.pitch_p95_deg = util::Quantile(pitch, 0.95);
  if (rest_sum.norm() > 0.0 && rest_up.norm() > 0.0) {
    const Eigen::Vector3d a = rest_sum.normalized(), b = rest_up.normalized();
    result.rest_accel_tilt_deg = std::atan2(a.cross(b).norm(), a.dot(b)) / kDegToRad;
  }
  return result;
}

/// The EuRoC pairs at rest: rectified with the data set's calibration (an OpenCV stereo
/// calibration built from cam0/cam1's intrinsics, distortion and extrinsics), matched with
/// od::ComputeStereoDepth, the floor's normal and the accelerometer's mean direction
/// (+-25 ms around each pair) against the true up (OpenVINS' attitude).
Expected<EurocStereoUpResult> RunEurocStereoUp(const std::filesystem::path& root) {
  Expected<sources::AslDataset> data = sources::ReadAslDataset(root / "mav0");
  if (!data) return data.error();
  if (data->cameras.size() < 2) return Error{"EuRoC: cam0 and cam1 needed"};
  const sources::AslCamera& c0 = data->cameras[0];
  const sources::AslCamera& c1 = data->cameras[1];
  Expected<std::vector<sources::AslGroundTruth>> truth =
      sources::ReadOpenVinsGroundTruth(root / "ov_data" / "euroc_mav" / "V1_01_easy.csv");
  if (!truth) return truth.error();
  // p_cam1 = R p_cam0 + T.
  const Eigen::Isometry3d T_c1_c0 = c1.T_body_camera.inverse() * c0.T_body_camera;
  std::ostringstream yaml;
  yaml.precision(17);
  auto list = [&](const std::vector<double>& v) {
    yaml << "[";
    for (std::size_t k = 0; k < v.size(); ++k) yaml << (k ? ", " : "") << v[k];
    yaml << "]\n";
  };
  yaml << "image_size: [" << c0.width << ", " << c0.height << "]\nM1: ";
  list({c0.fx, 0, c0.cx, 0, c0.fy, c0.cy, 0, 0, 1});
  yaml << "D1: ";
  list(c0.distortion);
  yaml << "M2: ";
  list({c1.fx, 0, c1.cx, 0, c1.fy, c1.cy, 0, 0, 1});
  yaml << "D2: ";
  list(c1.distortion);
  const Eigen::Matrix3d R = T_c1_c0.linear();
  yaml << "R: ";
  list({R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)});
  yaml << "T: ";
  list({T_c1_c0.translation().x(), T_c1_c0.translation().y(), T_c1_c0.translation().z()});
  Expected<od::StereoCalibration> calibration =
      od::io::ParseOpenCvStereoCalibration(yaml.str(), "EuRoC cam0/cam1");
  if (!calibration) return calibration.error();
  const Eigen::Matrix3d R_rect_body =
      calibration->rectification->R1 * c0.T_body_camera.linear().transpose();
  od::StereoConfig config;
  config.min_depth_m = 0.5;
  config.max_depth_m = 6.0;
  EurocStereoUpResult result;
  std::vector<double> floor_err, accel_err, floor_accel;
  for (std::size_t k = 0; k < c0.images.size() && k < c1.images.size(); ++k) {
    if (!c0.images[k].exists || !c1.images[k].exists) continue;
    Expected<od::GreyImage> left = od::io::ReadGreyImage(c0.images[k].path);
    if (!left) return left.error();
    Expected<od::GreyImage> right = od::io::ReadGreyImage(c1.images[k].path);
    if (!right) return right.error();
    Expected<od::StereoPair> pair = od::PrepareStereoPair(*left, *right, *calibration);
    if (!pair) return pair.error();
    Expected<od::StereoDepth> depth = od::ComputeStereoDepth(*pair, config);
    if (!depth) return depth.error();
    const od::PinholeModel& m = pair->calibration.model;
    std::vector<Eigen::Vector3d> points;
    for (int v = 0; v < depth->depth_m.height; ++v) {
      for (int u = 0; u < depth->depth_m.width; ++u) {
        const double z =
            depth->depth_m.data[static_cast<std::size_t>(v) * depth->depth_m.width + u];
        if (!(z >= 0.3 && z <= 6.0)) continue;
        points.emplace_back((u - m.cx) * z / m.fx, (v - m.cy) * z / m.fy, z);
      }
    }
    Eigen::Vector3d floor;
    int inliers = 0;
    if (!FloorNormal(points, &floor, &inliers)) continue;
    // The truth nearest in time, and the accelerometer around the pair.
    const std::int64_t t = c0.images[k].stamp_ns;
    const sources::AslGroundTruth* g = &truth->front();
    for (const sources::AslGroundTruth& row : *truth) {
      if (std::llabs(row.stamp_ns - t) < std::llabs(g->stamp_ns - t)) g = &row;
    }
    const Eigen::Vector3d up_true =
        R_rect_body * g->q_world_body.toRotationMatrix().transpose() * Eigen::Vector3d::UnitZ();
    Eigen::Vector3d f = Eigen::Vector3d::Zero();
    for (const sources::AslImuSample& s : data->imu.samples) {
      if (std::llabs(s.stamp_ns - t) <= 25000000) f += s.specific_force_mps2;
    }
    const Eigen::Vector3d up_accel = R_rect_body * data->imu.T_body_imu.linear() * f.normalized();
    auto angle = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
      return std::atan2(a.cross(b).norm(), a.dot(b)) / kDegToRad;
    };
    floor_err.push_back(angle(floor, up_true));
    accel_err.push_back(angle(up_accel, up_true));
    floor_accel.push_back(angle(floor, up_accel));
    ++result.pairs;
    result.floor_points += inliers;
  }
  result.floor_median_deg = util::Quantile(floor_err, 0.5);
  result.floor_max_deg = util::Quantile(floor_err, 1.0);
  result.accel_median_deg = util::Quantile(accel_err, 0.5);
  result.accel_max_deg = util::Quantile(accel_err, 1.0);
  result.floor_vs_accel_median_deg = util::Quantile(floor_accel, 0.5);
  return result;
}

}  // namespace cairn::eval
