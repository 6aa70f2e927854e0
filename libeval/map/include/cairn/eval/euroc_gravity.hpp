// GravityEstimator on real data: EuRoC V1_01 (the ASL layout, read by cairn::sources), its
// real 200 Hz accelerometer and gyro with the OpenVINS ground truth's velocity standing in for
// odometry (and its heading for the measured heading), no attitude prior and no scene cues;
// roll and pitch against the truth. And the up vector at rest measured on the floor seen by
// its stereo pairs, against the truth and the accelerometer. `cairn eval --euroc DIR`
// prints both; map_euroc_gravity_test bounds them.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <filesystem>

#include "cairn/od/expected.hpp"

namespace cairn::eval {

struct EurocGravityResult {
  int frames = 0;
  int imu_samples = 0;
  double duration_s = 0.0;
  // Errors against the truth [deg]: the angle between the true and the estimated up
  // (tilt), and the roll and pitch of the level frame described below, each |error|.
  double tilt_median_deg = 0.0, tilt_p95_deg = 0.0, tilt_max_deg = 0.0;
  double roll_median_deg = 0.0, roll_p95_deg = 0.0;
  double pitch_median_deg = 0.0, pitch_p95_deg = 0.0;
  // The same over the frames at which the estimator does not flag the accelerometer bias
  // as unobservable (at rest it cannot tell the bias from a tilt, and says so).
  int observed_frames = 0;
  double bias_observed_from_s = -1.0;  ///< stamp of the first such frame [s], -1: none
  double observed_tilt_median_deg = NAN, observed_tilt_p95_deg = NAN;
  // At rest (before take-off): the mean accelerometer direction against the truth [deg].
  double rest_accel_tilt_deg = 0.0;
  // The truth against its own IMU (its attitude, velocity and accelerometer bias): the tilt
  // of gravity in the truth's world frame [deg], the mean over 0.2 s spans, and the spans'
  // scatter about that mean per world axis [m/s^2]. An estimator of the true gravity is
  // scored against a truth whose up is this far from it.
  double truth_gravity_tilt_deg = NAN;
  Eigen::Vector3d truth_gravity_rms_mps2 = Eigen::Vector3d::Constant(NAN);
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();  ///< estimated, at the end
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d truth_accel_bias_mps2 = Eigen::Vector3d::Zero();  ///< OpenVINS', at the end
  Eigen::Vector3d truth_gyro_bias_radps = Eigen::Vector3d::Zero();
};

/// `root` holds mav0/ and ov_data/euroc_mav/V1_01_easy.csv. `max_frames` > 0 stops early.
Expected<EurocGravityResult> RunEurocGravity(const std::filesystem::path& root, int max_frames = 0);

/// The up vector at rest from the stereo pairs' floor and from the accelerometer, each
/// against the truth, in the rectified left camera's frame [deg].
struct EurocStereoUpResult {
  int pairs = 0;         ///< pairs whose floor was found
  int floor_points = 0;  ///< inliers of the floor plane, summed over pairs
  double floor_median_deg = 0.0, floor_max_deg = 0.0;  ///< floor normal vs the true up
  double accel_median_deg = 0.0, accel_max_deg = 0.0;  ///< mean specific force vs the true up
  double floor_vs_accel_median_deg = 0.0;
};

/// The EuRoC pairs at rest: rectified with the data set's calibration (an OpenCV stereo
/// calibration built from cam0/cam1's intrinsics, distortion and extrinsics), matched with
/// od::ComputeStereoDepth, the floor's normal and the accelerometer's mean direction
/// (+-25 ms around each pair) against the true up (OpenVINS' attitude).
Expected<EurocStereoUpResult> RunEurocStereoUp(const std::filesystem::path& root);

}  // namespace cairn::eval
