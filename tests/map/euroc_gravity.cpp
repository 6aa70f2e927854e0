// cairn_euroc_gravity [DATASET_DIR]: the gravity estimator's IMU terms alone on EuRoC V1_01
// (default: the shared copy), roll and pitch against the OpenVINS ground truth. Prints the
// figures; exits 1 when the data cannot be read.
#include <cstdio>
#include <filesystem>

#include "euroc_gravity_run.hpp"

int main(int argc, char** argv) {
  const std::filesystem::path root =
      argc > 1 ? std::filesystem::path(argv[1])
               : std::filesystem::path(CAIRN_SHARED_DATASETS) / "euroc-v101-start";
  const auto result = cairn::test::RunEurocGravity(root);
  if (!result) {
    std::fprintf(stderr, "cairn_euroc_gravity: %s\n", result.error().message.c_str());
    return 1;
  }
  const auto& r = *result;
  std::printf("EuRoC V1_01, IMU terms alone, true velocity as odometry: %d frames, %d IMU "
              "samples, %.1f s\n", r.frames, r.imu_samples, r.duration_s);
  std::printf("tilt error  median %.3f deg, 95th percentile %.3f deg, max %.3f deg\n",
              r.tilt_median_deg, r.tilt_p95_deg, r.tilt_max_deg);
  std::printf("roll error  median %.3f deg, 95th percentile %.3f deg\n", r.roll_median_deg,
              r.roll_p95_deg);
  std::printf("pitch error median %.3f deg, 95th percentile %.3f deg\n", r.pitch_median_deg,
              r.pitch_p95_deg);
  std::printf("at rest: mean accelerometer direction vs the true up: %.3f deg\n",
              r.rest_accel_tilt_deg);
  std::printf("accel bias (IMU frame) estimated (%.3f %.3f %.3f), OpenVINS (%.3f %.3f %.3f) m/s^2\n",
              r.accel_bias_mps2.x(), r.accel_bias_mps2.y(), r.accel_bias_mps2.z(),
              r.truth_accel_bias_mps2.x(), r.truth_accel_bias_mps2.y(),
              r.truth_accel_bias_mps2.z());
  std::printf("gyro bias estimated (%.4f %.4f %.4f), OpenVINS (%.4f %.4f %.4f) rad/s\n",
              r.gyro_bias_radps.x(), r.gyro_bias_radps.y(), r.gyro_bias_radps.z(),
              r.truth_gyro_bias_radps.x(), r.truth_gyro_bias_radps.y(),
              r.truth_gyro_bias_radps.z());
  const auto up = cairn::test::RunEurocStereoUp(root);
  if (!up) {
    std::fprintf(stderr, "cairn_euroc_gravity: %s\n", up.error().message.c_str());
    return 1;
  }
  std::printf("stereo pairs at rest: floor found in %d (%d inlier points); up from the floor vs "
              "the truth median %.3f deg (max %.3f), from the accelerometer median %.3f deg "
              "(max %.3f); floor vs accelerometer median %.3f deg\n",
              up->pairs, up->floor_points, up->floor_median_deg, up->floor_max_deg,
              up->accel_median_deg, up->accel_max_deg, up->floor_vs_accel_median_deg);
  return 0;
}
