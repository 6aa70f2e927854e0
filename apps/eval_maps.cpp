// The evidence about maps and tilt (libeval/map):
//   cairn eval --maps: the map study (map_study.hpp) into --report (datasets/maps):
//     REPORT.md, runs.csv, obstacles.csv, tilt.csv and figures/. Run from the source tree
//     (its worlds are read from --root).
//   cairn eval --euroc DIR: the gravity estimator on EuRoC V1_01 (euroc_gravity.hpp), its
//     figures printed.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "cairn/eval/euroc_gravity.hpp"
#include "cairn/eval/map_study.hpp"
#include "detect.hpp"
#include "eval_run.hpp"
#include "progress.hpp"

namespace cairn::apps::eval {

int RunMapStudy(const EvalOptions& o) {
  // Checked before the drives, which take minutes.
  if (!o.euroc.empty() && !std::filesystem::is_directory(std::filesystem::path(o.euroc) / "mav0")) {
    return Fail("--euroc " + o.euroc +
                ": expected the EuRoC V1_01 folder holding mav0/ and ov_data/");
  }
  cairn::eval::MapStudyOptions study;
  study.root = o.root;
  Expected<od::io::DetectSettings> settings = LoadDetectSettingsFile(
      o.config.empty() ? (o.root / "config" / "default.yaml").string() : o.config);
  if (!settings) return Fail(settings.error().message);
  study.settings = std::move(*settings);
  study.settings.detector.threads = 1;  // the drives run side by side instead
  study.threads = o.threads;
  study.command =
      "cmake --build build --target cairn && build/apps/cairn eval --maps --report " + o.report;
  if (!o.euroc.empty()) {
    study.euroc = o.euroc;
    study.command += " --euroc " + o.euroc;
  }
  std::unique_ptr<Progress> progress;
  study.on_drive = [&](const std::string& line, int done, int total) {
    if (!progress)
      progress = std::make_unique<Progress>("cairn eval --maps", total, 10, 0, "drives");
    progress->Note(line);
    progress->Update(done);
  };
  if (Status st = cairn::eval::WriteMapStudy(study, o.report); !st) return Fail(st.message());
  if (progress) progress->Finish();
  std::cout << "wrote " << (std::filesystem::path(o.report) / "REPORT.md").string() << "\n";
  return 0;
}

int RunEurocStudy(const EvalOptions& o) {
  const auto result = cairn::eval::RunEurocGravity(o.euroc);
  if (!result) return Fail(result.error().message);
  const auto& r = *result;
  std::printf(
      "EuRoC V1_01, IMU terms alone, true velocity as odometry: %d frames, %d IMU "
      "samples, %.1f s\n",
      r.frames, r.imu_samples, r.duration_s);
  std::printf("tilt error  median %.3f deg, 95th percentile %.3f deg, max %.3f deg\n",
              r.tilt_median_deg, r.tilt_p95_deg, r.tilt_max_deg);
  std::printf("roll error  median %.3f deg, 95th percentile %.3f deg\n", r.roll_median_deg,
              r.roll_p95_deg);
  std::printf("pitch error median %.3f deg, 95th percentile %.3f deg\n", r.pitch_median_deg,
              r.pitch_p95_deg);
  if (r.observed_frames > 0) {
    std::printf(
        "over the %d frames where the accelerometer bias is not flagged unobservable (the "
        "first at %.1f s): tilt error median %.3f deg, 95th percentile %.3f deg\n",
        r.observed_frames, r.bias_observed_from_s, r.observed_tilt_median_deg,
        r.observed_tilt_p95_deg);
  } else {
    std::printf("the accelerometer bias stays flagged unobservable in every frame\n");
  }
  std::printf("at rest: mean accelerometer direction vs the true up: %.3f deg\n",
              r.rest_accel_tilt_deg);
  std::printf(
      "the truth against its own IMU (its attitude, velocity and accelerometer bias, 0.2 s "
      "spans): gravity %.3f deg from its world z, scatter (%.3f %.3f %.3f) m/s^2\n",
      r.truth_gravity_tilt_deg, r.truth_gravity_rms_mps2.x(), r.truth_gravity_rms_mps2.y(),
      r.truth_gravity_rms_mps2.z());
  std::printf(
      "accel bias (IMU frame) estimated (%.3f %.3f %.3f), OpenVINS (%.3f %.3f %.3f) m/s^2\n",
      r.accel_bias_mps2.x(), r.accel_bias_mps2.y(), r.accel_bias_mps2.z(),
      r.truth_accel_bias_mps2.x(), r.truth_accel_bias_mps2.y(), r.truth_accel_bias_mps2.z());
  std::printf("gyro bias estimated (%.4f %.4f %.4f), OpenVINS (%.4f %.4f %.4f) rad/s\n",
              r.gyro_bias_radps.x(), r.gyro_bias_radps.y(), r.gyro_bias_radps.z(),
              r.truth_gyro_bias_radps.x(), r.truth_gyro_bias_radps.y(),
              r.truth_gyro_bias_radps.z());
  const auto up = cairn::eval::RunEurocStereoUp(o.euroc);
  if (!up) {
    return Fail(up.error().message);
  }
  std::printf(
      "stereo pairs at rest: floor found in %d (%d inlier points); up from the floor vs "
      "the truth median %.3f deg (max %.3f), from the accelerometer median %.3f deg "
      "(max %.3f); floor vs accelerometer median %.3f deg\n",
      up->pairs, up->floor_points, up->floor_median_deg, up->floor_max_deg, up->accel_median_deg,
      up->accel_max_deg, up->floor_vs_accel_median_deg);
  return 0;
}

}  // namespace cairn::apps::eval
