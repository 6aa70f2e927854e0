// TerrainMap from the poses a robot believes (libsim's drifting odometry and biased IMU): the
// claims datasets/maps/REPORT.md makes, on small drives (the worlds' 320 x 240 range camera, 2 Hz).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "cairn/eval/drift_run.hpp"
#include "cairn/od/units.hpp"
#include "sim_frames.hpp"

namespace cairn::test {
namespace {

using eval::DriftRunResult;
using eval::DriftRunSpec;
using eval::PoseError;

// A drive through a world file with the detector and rules of config/default.yaml.
DriftRunSpec SpecFor(const std::filesystem::path& world_file) {
  DriftRunSpec spec;
  spec.world = world_file.string();
  Expected<od::io::DetectSettings> settings = DefaultDetectSettings();
  EXPECT_TRUE(settings.ok()) << settings.error().message;
  if (settings) spec.settings = *settings;
  return spec;
}

// A drive through a world of datasets/worlds.
DriftRunSpec Spec(const std::string& world) {
  return SpecFor(SourceDir() / "datasets" / "worlds" / (world + ".yaml"));
}

// Maps one run, prints its figures; the test stops on a run that fails.
Expected<DriftRunResult> MapRun(const DriftRunSpec& spec, const char* label) {
  Expected<DriftRunResult> r = eval::RunDrift(spec);
  if (!r) return r;
  std::printf(
      "%s: %d frames, %.1f m, IoU %.3f, obstacles %zu, nearest lethal max %.2f mean %.2f m, "
      "false lethal %d, elevation RMS %.3f m, final position error %.2f m, tilt error "
      "%.2f deg, refined %d\n",
      label, r->frames, r->distance_m, r->score.iou, r->obstacles.size(), r->max_distance_m,
      r->mean_distance_m, r->score.false_lethal, r->score.elevation_rms_m,
      r->pose_errors.back().position_m, r->pose_errors.back().tilt_rad / kDegToRad,
      r->refined_frames);
  return r;
}

DriftRunSpec PolesAndRocks(double drift) {
  DriftRunSpec spec = Spec("poles_and_rocks");
  spec.waypoints = {{0.0, 0.0}, {16.0, 0.0}};
  eval::DriftOdometryBy(spec, drift);
  return spec;
}

// With 1 % drift (and 0.5 deg / 10 m in heading) every obstacle seen stays within 0.3 m of
// a lethal cell, and no lethal cell stands more than 0.5 m from a true obstacle: the map
// stays usable for a planner with a robot-radius inflation.
TEST(TerrainMapDrift, OnePercentDriftKeepsEveryObstacleNearALethalCell) {
  const Expected<DriftRunResult> r_run = MapRun(PolesAndRocks(0.01), "poles_and_rocks, 1% drift");
  ASSERT_TRUE(r_run.ok()) << r_run.error().message;
  const DriftRunResult& r = *r_run;
  ASSERT_GE(r.obstacles.size(), 5u);
  EXPECT_GT(r.pose_errors.back().position_m, 0.02);  // the odometry did drift
  EXPECT_LE(r.max_distance_m, 0.3);
  EXPECT_LE(r.score.false_lethal, 5);
  EXPECT_GE(r.score.iou, 0.3);
  EXPECT_LT(r.score.elevation_rms_m, 0.05);
}

// Errors grow with drift: the 3 % map is worse than the true-pose map, by the measures the
// report quotes.
TEST(TerrainMapDrift, ErrorsGrowWithDrift) {
  DriftRunSpec truth = PolesAndRocks(0.0);
  truth.true_poses = true;
  const Expected<DriftRunResult> exact_run = MapRun(truth, "poles_and_rocks, true poses");
  ASSERT_TRUE(exact_run.ok()) << exact_run.error().message;
  const DriftRunResult& exact = *exact_run;
  const Expected<DriftRunResult> drifted_run =
      MapRun(PolesAndRocks(0.03), "poles_and_rocks, 3% drift");
  ASSERT_TRUE(drifted_run.ok()) << drifted_run.error().message;
  const DriftRunResult& drifted = *drifted_run;
  ASSERT_GE(exact.obstacles.size(), 5u);
  EXPECT_GT(drifted.pose_errors.back().position_m, 0.1);
  EXPECT_LT(drifted.score.iou, exact.score.iou);
  EXPECT_GT(drifted.max_distance_m, exact.max_distance_m);
  EXPECT_GT(drifted.score.false_lethal, exact.score.false_lethal);
  EXPECT_GT(drifted.score.elevation_rms_m, exact.score.elevation_rms_m);
}

// A constant 2 deg roll and pitch IMU bias from the first frame, on the 12 deg slope. The
// dead-reckoned height (dz = -d tan(pitch)) drifts by d tan(2 deg), so the elevation is off
// by a metre after 30 m, but the map stays self-consistent: every obstacle is mapped and no
// ground is marked lethal. The tilt refiner aligns each frame with the terrain fused so far,
// which the first (biased) frame built: it cannot observe a bias present from the start,
// and it does not make the map worse in obstacles.
TEST(TerrainMapDrift, ConstantImuBiasOnASlopeKeepsObstaclesButNotElevation) {
  DriftRunSpec spec = Spec("uphill_tilted");
  spec.waypoints = {{0.0, 0.0}, {20.0, 1.0}, {30.0, -0.5}};
  spec.imu_bias_rad = 2.0 * kDegToRad;
  const Expected<DriftRunResult> biased_run = MapRun(spec, "uphill_tilted, 2 deg IMU bias");
  ASSERT_TRUE(biased_run.ok()) << biased_run.error().message;
  const DriftRunResult& biased = *biased_run;
  spec.refine_tilt = true;
  const Expected<DriftRunResult> refined_run =
      MapRun(spec, "uphill_tilted, 2 deg IMU bias, tilt refiner");
  ASSERT_TRUE(refined_run.ok()) << refined_run.error().message;
  const DriftRunResult& refined = *refined_run;
  for (const DriftRunResult* r : {&biased, &refined}) {
    EXPECT_GE(r->obstacles.size(), 6u);
    EXPECT_LE(r->max_distance_m, 0.3);
    EXPECT_EQ(r->score.false_lethal, 0);
    EXPECT_GT(r->score.elevation_rms_m, 0.3);                    // the height drift the bias causes
    EXPECT_GT(r->pose_errors.back().tilt_rad, 1.5 * kDegToRad);  // not observable
  }
  EXPECT_GT(refined.refined_frames, refined.frames / 2);
  EXPECT_GE(refined.score.iou, biased.score.iou - 0.02);
}

// The quantile of angles [rad] in degrees (the nearest rank; NaN for none).
double QuantileDeg(std::vector<double> angles_rad, double quantile) {
  if (angles_rad.empty()) return NAN;
  std::sort(angles_rad.begin(), angles_rad.end());
  const std::size_t k = std::min(angles_rad.size() - 1,
                                 static_cast<std::size_t>(quantile * (angles_rad.size() - 1) + 0.5));
  return angles_rad[k] / kDegToRad;
}

double MedianTiltDeg(const DriftRunResult& r, double quantile = 0.5) {
  std::vector<double> tilt;
  for (const PoseError& e : r.pose_errors) tilt.push_back(e.tilt_rad);
  return QuantileDeg(tilt, quantile);
}

// The same biased drive through the gravity estimator: the accelerometer and the trunks and
// poles observe gravity, so the bias present from the first frame is found and the height
// integrated along the drive follows the true slope.
TEST(TerrainMapDrift, TheGravityEstimatorFindsAConstantImuBiasOnASlope) {
  DriftRunSpec spec = Spec("uphill_tilted");
  spec.waypoints = {{0.0, 0.0}, {20.0, 1.0}, {30.0, -0.5}};
  spec.imu_bias_rad = 2.0 * kDegToRad;
  spec.imu_sigma_rad = 0.3 * kDegToRad;
  spec.measure_cues = true;
  const Expected<DriftRunResult> prior_run = MapRun(spec, "uphill_tilted, 2 deg IMU bias");
  ASSERT_TRUE(prior_run.ok()) << prior_run.error().message;
  spec.gravity = true;
  const Expected<DriftRunResult> gravity_run =
      MapRun(spec, "uphill_tilted, 2 deg IMU bias, gravity estimator");
  ASSERT_TRUE(gravity_run.ok()) << gravity_run.error().message;
  const DriftRunResult& prior = *prior_run;
  const DriftRunResult& gravity = *gravity_run;
  std::printf(
      "[ figures  ] tilt error median / 95th: prior %.2f / %.2f deg, gravity %.2f / %.2f "
      "deg; elevation RMS prior %.3f m, gravity %.3f m\n",
      MedianTiltDeg(prior), MedianTiltDeg(prior, 0.95), MedianTiltDeg(gravity),
      MedianTiltDeg(gravity, 0.95), prior.score.elevation_rms_m, gravity.score.elevation_rms_m);
  // The trunks and poles the detector found point up: the cues are measured above their
  // feet, so the slope under them does not tilt them.
  std::vector<double> cues = prior.cue_errors_rad;
  ASSERT_GE(cues.size(), 20u);
  std::sort(cues.begin(), cues.end());
  std::printf("[ figures  ] %zu vertical cues: median %.2f deg, 90th %.2f deg from the vertical\n",
              cues.size(), cues[cues.size() / 2] / kDegToRad,
              cues[cues.size() * 9 / 10] / kDegToRad);
  EXPECT_LT(cues[cues.size() / 2], 0.5 * kDegToRad);
  EXPECT_LT(cues[cues.size() * 9 / 10], 1.5 * kDegToRad);
  EXPECT_GT(MedianTiltDeg(prior), 1.5);
  EXPECT_LT(MedianTiltDeg(gravity), 0.2);
  EXPECT_LT(MedianTiltDeg(gravity, 0.95), 0.5);
  EXPECT_LT(gravity.score.elevation_rms_m, 0.05);  // the goal: 5 cm (true x, y here)
  EXPECT_LT(gravity.ground_height_rms_m, 0.05);
  EXPECT_LT(gravity.score.elevation_rms_m, prior.score.elevation_rms_m / 20);
  EXPECT_GE(gravity.obstacles.size(), 6u);
  EXPECT_LE(gravity.max_distance_m, 0.3);
  EXPECT_EQ(gravity.score.false_lethal, 0);
}

// The goal, on the 60 m uphill drive with a 2 deg IMU bias and 1% odometry: the
// terrain each frame fuses is within 5 cm RMS of the true terrain under it (2.7 cm here),
// and the grid's elevation against the truth at the same x, y is near what the odometry's
// horizontal drift leaves with a perfect tilt (the floor: true roll, pitch and height,
// odometry x, y and heading): 2.5 cm above it here (1.8 cm with the camera scaled to 160 x 120,
// before 2026-12-05). (Before the gravity step's prior turned
// the body rather than the sensor and the newest frame had a provisional velocity, it came
// 2.7 cm above the floor; 1.0 cm before the odometry's random walk was stated, which weakens
// the accelerometer terms as much as that noise says: in datasets/maps/REPORT.md the tilt's
// 95th percentile over the hill with 3 % odometry goes 0.59 -> 0.39 deg, the height over
// this climb a little the other way. Hence 3 cm, not 2.)
TEST(TerrainMapDrift, OnA60mDriveWithOnePercentOdometryTheGravityEstimatorReachesTheFloor) {
  DriftRunSpec spec = Spec("uphill_tilted");
  spec.waypoints = {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}};
  spec.imu_bias_rad = 2.0 * kDegToRad;
  spec.imu_sigma_rad = 0.3 * kDegToRad;
  eval::DriftOdometryBy(spec, 0.01);
  spec.gravity = true;
  const Expected<DriftRunResult> gravity_run = MapRun(spec, "uphill 60 m, 1% odometry, gravity");
  ASSERT_TRUE(gravity_run.ok()) << gravity_run.error().message;
  spec.gravity = false;
  spec.truth_tilt_height = true;
  const Expected<DriftRunResult> floor_run = MapRun(spec, "uphill 60 m, 1% odometry, floor");
  ASSERT_TRUE(floor_run.ok()) << floor_run.error().message;
  const DriftRunResult& gravity = *gravity_run;
  const DriftRunResult& floor = *floor_run;
  std::printf(
      "[ figures  ] gravity: tilt %.2f / %.2f deg, ground RMS %.3f m, elevation RMS %.3f m; "
      "floor: elevation RMS %.3f m\n",
      MedianTiltDeg(gravity), MedianTiltDeg(gravity, 0.95), gravity.ground_height_rms_m,
      gravity.score.elevation_rms_m, floor.score.elevation_rms_m);
  EXPECT_LT(MedianTiltDeg(gravity), 0.2);
  EXPECT_LT(MedianTiltDeg(gravity, 0.95), 0.5);
  EXPECT_LT(gravity.ground_height_rms_m, 0.03);
  EXPECT_LT(floor.ground_height_rms_m, 0.005);  // the floor's poses are true but for x, y, yaw
  EXPECT_LT(gravity.score.elevation_rms_m, floor.score.elevation_rms_m + 0.03);
}

// An accelerometer bias (0.1, -0.1, 0.05 m/s^2) on top of a 2 deg attitude bias, the uphill
// slope driven twice (datasets/maps/REPORT.md's rows): nearly straight, the bias cannot be
// told from a tilt and is flagged on most frames, and the height it tilts drifts; weaving
// +-40 deg with corners of 6 m radius, the turns change the body's attitude under gravity and
// the bias is learned: flagged on under a third of the frames, and the fused ground stays
// within the 5 cm goal (3.8 cm on this drive).
TEST(TerrainMapDrift, TurnsMakeAnAccelerometerBiasObservableThatAStraightDriveFlags) {
  DriftRunSpec spec = Spec("uphill_tilted");
  spec.imu_bias_rad = 2.0 * kDegToRad;
  spec.imu_sigma_rad = 0.3 * kDegToRad;
  spec.imu.accel_bias_mps2 = Eigen::Vector3d(0.1, -0.1, 0.05);
  spec.gravity = true;
  spec.waypoints = {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}};
  const Expected<DriftRunResult> straight_run =
      MapRun(spec, "uphill 60 m, accelerometer bias, gravity");
  ASSERT_TRUE(straight_run.ok()) << straight_run.error().message;
  spec.waypoints = {{0.0, 0.0}, {12.0, 5.0}, {24.0, -5.0}, {36.0, 5.0}, {48.0, -5.0}, {58.0, 0.0}};
  spec.turn_radius_m = 6.0;
  const Expected<DriftRunResult> weave_run =
      MapRun(spec, "uphill weaving, accelerometer bias, gravity");
  ASSERT_TRUE(weave_run.ok()) << weave_run.error().message;
  const DriftRunResult& straight = *straight_run;
  const DriftRunResult& weave = *weave_run;
  std::printf(
      "[ figures  ] accelerometer bias flagged on %d / %d frames straight, %d / %d weaving; "
      "ground RMS %.3f m straight, %.3f m weaving; tilt %.2f / %.2f deg weaving\n",
      straight.accel_bias_flagged_frames, straight.frames, weave.accel_bias_flagged_frames,
      weave.frames, straight.ground_height_rms_m, weave.ground_height_rms_m, MedianTiltDeg(weave),
      MedianTiltDeg(weave, 0.95));
  EXPECT_GT(straight.accel_bias_flagged_frames, straight.frames * 3 / 4);
  EXPECT_LT(weave.accel_bias_flagged_frames, weave.frames / 3);
  EXPECT_GT(straight.ground_height_rms_m, 0.1);
  EXPECT_LT(weave.ground_height_rms_m, 0.05);
  EXPECT_LT(MedianTiltDeg(weave), 0.2);
  EXPECT_LT(MedianTiltDeg(weave, 0.95), 0.5);
}

// The weaving climb with the camera's mount 2.5 deg off and a 2 deg bias of the IMU's attitude
// output. With the worlds' own 320 x 240 camera the trunks in view teach the mount within a few
// frames, and the window meets issue 11's goals (0.06 / 0.16 deg and 3.8 cm on this drive). With
// the camera scaled to 160 x 120 (the map
// study's until 2026-12-05) a trunk's axis is fitted from a quarter of the pixels and leans
// about three times as far (0.55 deg from the vertical, median over the drive's cues, against
// 0.17): the window answers the first ten frames before the trunks have taught it the mount, and
// the map keeps what it fused there (the tilt's 95th percentile and the height climbed
// meanwhile). Smoothed once the drive is over (DriftRunSpec::smooth, tilt.smooth)
// and fused again, every frame has the mount the whole drive showed (the map study's `smoothed`
// rows show the same at 320 x 240, where there is less to mend). The frame-to-map ground heights,
// measured against the window's map, hold the height back towards it (tilt.smooth_ground_sigma_m);
// left out, the height is right too.
TEST(TerrainMapDrift, SmoothingTheWholeDriveMendsTheFramesBeforeTheMountWasLearned) {
  DriftRunSpec spec = Spec("uphill_tilted");
  spec.imu_bias_rad = 2.0 * kDegToRad;
  spec.imu_sigma_rad = 0.3 * kDegToRad;
  spec.sensor_misalignment_rad = Eigen::Vector3d(2.5 * kDegToRad, 0.0, 0.0);
  spec.gravity = true;
  spec.waypoints = {{0.0, 0.0}, {12.0, 5.0}, {24.0, -5.0}, {36.0, 5.0}, {48.0, -5.0}, {58.0, 0.0}};
  spec.turn_radius_m = 6.0;
  spec.measure_cues = true;
  const Expected<DriftRunResult> sharp_run = MapRun(spec, "uphill weaving, mount, gravity, 320 px");
  ASSERT_TRUE(sharp_run.ok()) << sharp_run.error().message;
  std::printf(
      "[ figures  ] weaving, mount 2.5 deg, 320 x 240: tilt %.2f / %.2f deg, ground RMS "
      "%.3f m in the window\n",
      MedianTiltDeg(*sharp_run), MedianTiltDeg(*sharp_run, 0.95), sharp_run->ground_height_rms_m);
  EXPECT_LT(MedianTiltDeg(*sharp_run), 0.2);
  EXPECT_LT(MedianTiltDeg(*sharp_run, 0.95), 0.5);
  EXPECT_LT(sharp_run->ground_height_rms_m, 0.05);
  spec.camera_width = 160;
  const Expected<DriftRunResult> window_run =
      MapRun(spec, "uphill weaving, mount, gravity, 160 px");
  ASSERT_TRUE(window_run.ok()) << window_run.error().message;
  spec.measure_cues = false;
  // The trunks' axes from the vertical (median) at either resolution.
  const double sharp_cue_deg = QuantileDeg(sharp_run->cue_errors_rad, 0.5);
  const double coarse_cue_deg = QuantileDeg(window_run->cue_errors_rad, 0.5);
  std::printf(
      "[ figures  ] the cues lean %.2f deg from the vertical (median of %zu) at 320 x 240, "
      "%.2f deg (of %zu) at 160 x 120\n",
      sharp_cue_deg, sharp_run->cue_errors_rad.size(), coarse_cue_deg,
      window_run->cue_errors_rad.size());
  EXPECT_LT(sharp_cue_deg, 0.5 * coarse_cue_deg);
  spec.smooth = true;
  const Expected<DriftRunResult> smoothed_run =
      MapRun(spec, "uphill weaving, mount, smoothed, 160 px");
  ASSERT_TRUE(smoothed_run.ok()) << smoothed_run.error().message;
  spec.configure = [](map::MapperConfig& c) { c.tilt.smooth_ground_sigma_m = 0.0; };
  const Expected<DriftRunResult> free_run =
      MapRun(spec, "uphill weaving, mount, smoothed without the map's heights, 160 px");
  ASSERT_TRUE(free_run.ok()) << free_run.error().message;
  const DriftRunResult& window = *window_run;
  const DriftRunResult& smoothed = *smoothed_run;
  const DriftRunResult& free = *free_run;
  std::printf(
      "[ figures  ] weaving, mount 2.5 deg, 160 x 120: tilt %.2f / %.2f deg and ground RMS %.3f m "
      "in the "
      "window; smoothed %.2f / %.2f deg and %.3f m, without the map's heights %.2f / %.2f deg "
      "and %.3f m\n",
      MedianTiltDeg(window), MedianTiltDeg(window, 0.95), window.ground_height_rms_m,
      MedianTiltDeg(smoothed), MedianTiltDeg(smoothed, 0.95), smoothed.ground_height_rms_m,
      MedianTiltDeg(free), MedianTiltDeg(free, 0.95), free.ground_height_rms_m);
  EXPECT_GT(MedianTiltDeg(window, 0.95), 0.5);
  EXPECT_GT(window.ground_height_rms_m, 0.06);
  for (const DriftRunResult* r : {&smoothed, &free}) {
    EXPECT_LT(MedianTiltDeg(*r), 0.1);
    EXPECT_LT(MedianTiltDeg(*r, 0.95), 0.2);
    // The second pass fused every frame, and the first pass's flags are kept.
    EXPECT_EQ(r->frames, window.frames);
    EXPECT_EQ(r->degenerate_frames, window.degenerate_frames);
    EXPECT_EQ(r->pose_errors.size(), window.pose_errors.size());
  }
  EXPECT_LT(smoothed.ground_height_rms_m, window.ground_height_rms_m * 0.8);
  EXPECT_LT(free.ground_height_rms_m, 0.04);
}

// An open field has no trunk, pole or wall to show the vertical, but the ground the camera
// sees ahead is ground it sees again two frames on: the rise the sensor measures over it
// against the climb the wheels' plane gives tells the sensor's tilt from the body's, so a
// 2.5 deg misalignment of the mount is found (and no longer flagged) once the rises begin,
// when the estimator's window is full. Without those ground rises the mount stays flagged
// and the misalignment stays in the map.
TEST(TerrainMapDrift, InAnOpenFieldTheMountIsFoundFromTheGroundTwoFramesSee) {
  DriftRunSpec spec = SpecFor(SourceDir() / "datasets" / "maps" / "worlds" / "open_field.yaml");
  spec.waypoints = {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}};
  spec.imu_sigma_rad = 0.3 * kDegToRad;
  spec.sensor_misalignment_rad = Eigen::Vector3d(2.5 * kDegToRad, 0.0, 0.0);
  spec.gravity = true;
  const Expected<DriftRunResult> run = MapRun(spec, "open field, mount 2.5 deg, gravity");
  ASSERT_TRUE(run.ok()) << run.error().message;
  spec.configure = [](map::MapperConfig& c) { c.tilt.gravity_rise_frames_back = 0; };
  const Expected<DriftRunResult> blind = MapRun(spec, "open field, mount 2.5 deg, no rises");
  ASSERT_TRUE(blind.ok()) << blind.error().message;
  const auto flags_mount = [](const DriftRunResult& r) {
    return std::any_of(r.last_degeneracies.begin(), r.last_degeneracies.end(),
                       [](const map::GravityDegeneracy& d) {
                         return d.state == map::GravityDegeneracy::State::kMount;
                       });
  };
  // The rises begin once the estimator's window (12 frames) is full.
  std::vector<double> after;
  for (std::size_t k = 12; k < run->pose_errors.size(); ++k) {
    after.push_back(run->pose_errors[k].tilt_rad / kDegToRad);
  }
  std::sort(after.begin(), after.end());
  ASSERT_FALSE(after.empty());
  const double after_median = after[after.size() / 2];
  const double after_p95 = after[static_cast<std::size_t>(0.95 * (after.size() - 1) + 0.5)];
  std::printf(
      "[ figures  ] open field, mount 2.5 deg: tilt %.2f / %.2f deg (%.2f / %.2f from the "
      "13th frame), ground RMS %.3f m; without ground rises %.2f / %.2f deg, %.3f m\n",
      MedianTiltDeg(*run), MedianTiltDeg(*run, 0.95), after_median, after_p95,
      run->ground_height_rms_m, MedianTiltDeg(*blind), MedianTiltDeg(*blind, 0.95),
      blind->ground_height_rms_m);
  EXPECT_LT(MedianTiltDeg(*run), 0.2);
  EXPECT_LT(after_median, 0.2);
  EXPECT_LT(after_p95, 0.5);
  EXPECT_FALSE(flags_mount(*run));
  EXPECT_LT(run->ground_height_rms_m, 0.6 * blind->ground_height_rms_m);
  EXPECT_GT(MedianTiltDeg(*blind), 2.0);
  EXPECT_TRUE(flags_mount(*blind));
  // Nothing here tells an accelerometer bias from a tilt but the drive's two turns: the
  // estimator does not claim the height better than it has it.
  std::printf("[ figures  ] the estimator's height sigma at the end: %.3f m\n",
              run->final_height_sigma_m);
  EXPECT_GT(run->final_height_sigma_m, run->ground_height_rms_m);
}

// Over the hill (hill_drive's world: up 1.6 m and down 2.9 m in 36 m) the fused ground is
// as good with a 3 deg bias of the IMU's attitude output as with none: the accelerometer
// sees the body's up from the third frame, and the prior carried from frame to frame puts
// the sensor where the estimate did. (Before, the first frames were fused at the biased
// prior's height and the frame-to-map height held the map there: 2.2 cm with no bias,
// 8.0 cm with 3 deg.)
TEST(TerrainMapDrift, OverTheHillTheFusedGroundDoesNotGrowWithTheImuBias) {
  std::vector<double> ground_rms;
  for (const double bias_deg : {0.0, 3.0}) {
    DriftRunSpec spec =
        SpecFor(SourceDir() / "datasets" / "sequences" / "hill_drive" / "world.yaml");
    spec.waypoints = {{0.0, 0.0}, {12.0, 1.0}, {24.0, -1.0}, {36.0, 1.0}};
    spec.imu_bias_rad = bias_deg * kDegToRad;
    spec.imu_sigma_rad = 0.3 * kDegToRad;
    spec.gravity = true;
    const Expected<DriftRunResult> run = MapRun(spec, "hill, gravity");
    ASSERT_TRUE(run.ok()) << run.error().message;
    std::printf("[ figures  ] hill, IMU bias %.0f deg: tilt %.2f / %.2f deg, ground RMS %.3f m\n",
                bias_deg, MedianTiltDeg(*run), MedianTiltDeg(*run, 0.95), run->ground_height_rms_m);
    EXPECT_LT(MedianTiltDeg(*run), 0.2);
    EXPECT_LT(MedianTiltDeg(*run, 0.95), 0.5);
    ground_rms.push_back(run->ground_height_rms_m);
  }
  EXPECT_LT(ground_rms[0], 0.03);
  EXPECT_LT(ground_rms[1], 0.04);
  EXPECT_LT(ground_rms[1] - ground_rms[0], 0.015);
}

}  // namespace
}  // namespace cairn::test
