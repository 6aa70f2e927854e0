// GravityEstimator's IMU terms alone on EuRoC V1_01 (the ASL layout, read by
// cairn::sources): the real 200 Hz accelerometer and gyro, with the OpenVINS ground truth's
// velocity standing in for odometry (and its heading for the measured heading), no attitude
// prior and no scene cues; roll and pitch against the truth. Shared by the
// cairn_euroc_gravity program and its test.
#pragma once

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/map/gravity_estimator.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/sources/asl_dataset.hpp"

namespace cairn::test {

struct EurocGravityResult {
  int frames = 0;
  int imu_samples = 0;
  double duration_s = 0.0;
  // Errors against the truth [deg]: the angle between the true and the estimated up
  // (tilt), and the roll and pitch of the level frame described below, each |error|.
  double tilt_median_deg = 0.0, tilt_p95_deg = 0.0, tilt_max_deg = 0.0;
  double roll_median_deg = 0.0, roll_p95_deg = 0.0;
  double pitch_median_deg = 0.0, pitch_p95_deg = 0.0;
  // At rest (before take-off): the mean accelerometer direction against the truth [deg].
  double rest_accel_tilt_deg = 0.0;
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();  ///< estimated, at the end
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d truth_accel_bias_mps2 = Eigen::Vector3d::Zero();  ///< OpenVINS', at the end
  Eigen::Vector3d truth_gyro_bias_radps = Eigen::Vector3d::Zero();
};

inline double EurocPercentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5))];
}

/// The estimator's body for the VI-Sensor: its IMU's x axis points about up, so the body
/// is the IMU frame turned to put z there: z_body = x_imu, y_body = y_imu, x_body = -z_imu.
inline Eigen::Matrix3d EurocBodyFromImu() {
  Eigen::Matrix3d R;
  R << 0, 0, -1, 0, 1, 0, 1, 0, 0;
  return R;
}

/// `root` holds mav0/ and ov_data/euroc_mav/V1_01_easy.csv. `max_frames` > 0 stops early.
inline Expected<EurocGravityResult> RunEurocGravity(const std::filesystem::path& root,
                                                    int max_frames = 0) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
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
  config.motion_sigma_mps2 = 0.3;       // rotor vibration, truth velocity differences
  config.gyro_bias_sigma_radps = 0.1;   // its z bias is 0.077 rad/s
  config.yaw_sigma_rad = 0.02;          // the reference heading
  config.estimate_mount = false;        // no scene cues here
  config.accel_half_span_frames = 2;  // 0.2 s spans at 20 Hz
  config.window_frames = 10;
  config.covariance = false;
  Expected<map::GravityEstimator> estimator =
      map::GravityEstimator::Create(config, R_body_imu, Eigen::Matrix3d::Identity());
  if (!estimator) return estimator.error();

  EurocGravityResult result;
  std::vector<double> tilt, roll, pitch;
  std::size_t j = 0;
  // IMU samples before the first truth row are skipped.
  while (j < imu->samples.size() && imu->samples[j].stamp_ns <= truth->front().stamp_ns) ++j;
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
    tilt.push_back(std::atan2(up.cross(est->up_body).norm(), up.dot(est->up_body)) / kDeg);
    const double true_roll = std::atan2(R_world_body(2, 1), R_world_body(2, 2));
    const double true_pitch =
        std::atan2(-R_world_body(2, 0), std::hypot(R_world_body(0, 0), R_world_body(1, 0)));
    roll.push_back(std::abs(std::remainder(est->roll_rad - true_roll, 2.0 * 3.14159265358979)) / kDeg);
    pitch.push_back(std::abs(est->pitch_rad - true_pitch) / kDeg);
    result.accel_bias_mps2 = est->accel_bias_mps2;
    result.gyro_bias_radps = est->gyro_bias_radps;
    result.truth_accel_bias_mps2 = g.accel_bias_mps2;
    result.truth_gyro_bias_radps = g.gyro_bias_radps;
  }
  result.tilt_median_deg = EurocPercentile(tilt, 0.5);
  result.tilt_p95_deg = EurocPercentile(tilt, 0.95);
  result.tilt_max_deg = EurocPercentile(tilt, 1.0);
  result.roll_median_deg = EurocPercentile(roll, 0.5);
  result.roll_p95_deg = EurocPercentile(roll, 0.95);
  result.pitch_median_deg = EurocPercentile(pitch, 0.5);
  result.pitch_p95_deg = EurocPercentile(pitch, 0.95);
  if (rest_sum.norm() > 0.0 && rest_up.norm() > 0.0) {
    const Eigen::Vector3d a = rest_sum.normalized(), b = rest_up.normalized();
    result.rest_accel_tilt_deg = std::atan2(a.cross(b).norm(), a.dot(b)) / kDeg;
  }
  return result;
}

}  // namespace cairn::test
