// GravityEstimator on synthetic drives with exact truth: a known tilt recovered on a side
// slope from a biased IMU attitude; an accelerometer bias observed when the vehicle turns and
// flagged when it drives straight; a sensor mount misalignment recovered from trunks and
// flagged in an open field (given no ground rises); the error terms' derivatives against
// numeric ones; a ground rise fitted between two frames and its tilts taken out.
#include "cairn/map/gravity_estimator.hpp"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/terrain.hpp"
#include "gravity_terms.hpp"
#include "ground_rise.hpp"

namespace cairn::map {
namespace {

struct Truth {
  Eigen::Matrix3d R_world_body;
  Eigen::Matrix3d R_world_sensor;
  double height_m = 0.0;  // the body's
};

struct Cues {
  bool trunks = true;         // four trunks per frame, leaning N(0, 1 deg), one in ten 12 deg
  double attitude_bias_rad = 2.5 * kDegToRad;  // the IMU attitude output's bias (roll and pitch)
  double attitude_sigma_rad = 0.4 * kDegToRad;
  std::uint64_t seed = 1;
  int resume_at = -1;        // after this frame: save, restore into a new estimator, go on
  bool state_sizes = false;  // record SaveState()'s size after each frame
  std::function<void(GravityEstimator&, int)> after_frame;  // called after each frame
  double ground_sigma_m = 0.0;  // > 0: each frame's true height (from the first frame's) as
                                // its frame-to-map ground height, with this sigma
  double odometry_scale = 0.0;  // the odometry's distances are 1 + this of the true ones
  int trunks_from = 0;          // the frames before this one see no trunks
  bool smooth = false;          // every frame also to a GravitySmoother, solved at the end
  int smoother_resume_at = -1;  // after this frame: the smoother saved, restored, gone on
};

struct DriveRun {
  std::vector<GravityEstimate> estimates;
  std::vector<double> body_error_deg;    // angle between true and estimated up (body)
  std::vector<double> sensor_error_deg;  // (sensor)
  std::vector<double> prior_error_deg;   // the IMU attitude output's
  // d^T P^+ d, d the estimated up less the true one (sensor frame), P the estimator's
  // up_sensor_covariance; and sqrt(trace P) [deg].
  std::vector<double> sensor_nees, sensor_sigma_deg;
  std::vector<std::size_t> state_bytes;  // with Cues::state_sizes
  // Cues::smooth: the smoother's estimates and sensor tilt errors, every frame from `skip`.
  std::vector<GravityEstimate> smoothed;
  std::vector<double> smoothed_sensor_error_deg;
};

// Tilt of `est_up` against the true up in the same frame [deg].
double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDegToRad;
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(q * (v.size() - 1) + 0.5));
  return v[i];
}

// The figures libmap/README.md quotes.
void Print(const char* what, const std::vector<double>& errors_deg) {
  std::printf("[ figures  ] %s: median %.3f deg, 95th percentile %.3f deg (%zu frames)\n", what,
              Percentile(errors_deg, 0.5), Percentile(errors_deg, 0.95), errors_deg.size());
}

// Feeds frames (truth poses at stamps, odometry, IMU samples) to an estimator.
DriveRun Estimate(const GravityEstimatorConfig& config, const Eigen::Matrix3d& R_body_sensor_nominal,
             const std::vector<double>& stamps, const std::vector<Truth>& truth,
             const std::vector<Eigen::Vector3d>& odometry, const std::vector<sim::ImuReading>& imu,
             const Cues& cues, int skip) {
  Expected<GravityEstimator> estimator =
      GravityEstimator::Create(config, Eigen::Matrix3d::Identity(), R_body_sensor_nominal);
  EXPECT_TRUE(estimator.ok()) << estimator.error().message;
  std::mt19937_64 rng(cues.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 2.0 * kPi);
  Expected<GravitySmoother> smoother =
      GravitySmoother::Create(config, Eigen::Matrix3d::Identity(), R_body_sensor_nominal);
  EXPECT_TRUE(smoother.ok()) << smoother.error().message;
  DriveRun run;
  std::size_t j = 0;
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    GravityFrame frame;
    frame.stamp_s = stamps[k];
    for (; j < imu.size() && imu[j].stamp_s <= stamps[k] + 1e-9; ++j) {
      frame.imu.push_back({imu[j].stamp_s, imu[j].specific_force_mps2, imu[j].angular_rate_radps});
    }
    frame.odometry_xy_yaw = odometry[k];
    frame.odometry_xy_yaw.head<2>() *= 1.0 + cues.odometry_scale;
    if (cues.ground_sigma_m > 0.0) {
      frame.ground_height_m = truth[k].height_m - truth[0].height_m;
      frame.ground_height_sigma_m = cues.ground_sigma_m;
    }
    const sim::Attitude a = sim::AttitudeFromRotation(truth[k].R_world_body);
    const Eigen::Vector2d prior(a.roll_rad + cues.attitude_bias_rad + cues.attitude_sigma_rad * normal(rng),
                                a.pitch_rad + cues.attitude_bias_rad + cues.attitude_sigma_rad * normal(rng));
    frame.attitude_prior_rad = prior;
    if (cues.trunks && static_cast<int>(k) >= cues.trunks_from) {
      for (int t = 0; t < 4; ++t) {
        const double lean =
            (k * 4 + t) % 10 == 3 ? 12.0 * kDegToRad : 1.0 * kDegToRad * normal(rng);
        const double towards = uniform(rng);
        const Eigen::Vector3d axis(std::sin(lean) * std::cos(towards),
                                   std::sin(lean) * std::sin(towards), std::cos(lean));
        frame.verticals.push_back({truth[k].R_world_sensor.transpose() * axis, false});
      }
    }
    Expected<GravityEstimate> est = estimator->AddFrame(frame);
    EXPECT_TRUE(est.ok()) << est.error().message;
    if (!est.ok()) return run;
    if (cues.smooth) {
      const Status added = smoother->Add(frame);
      EXPECT_TRUE(added.ok()) << added.message();
      if (static_cast<int>(k) == cues.smoother_resume_at) {
        const std::string state = smoother->SaveState();
        smoother =
            GravitySmoother::Create(config, Eigen::Matrix3d::Identity(), R_body_sensor_nominal);
        EXPECT_TRUE(smoother.ok());
        const Status restored = smoother->RestoreState(state);
        EXPECT_TRUE(restored.ok()) << restored.message();
        EXPECT_EQ(smoother->frames(), static_cast<int>(k) + 1);
      }
    }
    if (cues.state_sizes) run.state_bytes.push_back(estimator->SaveState().size());
    if (cues.after_frame) cues.after_frame(*estimator, static_cast<int>(k));
    if (static_cast<int>(k) == cues.resume_at) {
      const std::string state = estimator->SaveState();
      estimator =
          GravityEstimator::Create(config, Eigen::Matrix3d::Identity(), R_body_sensor_nominal);
      EXPECT_TRUE(estimator.ok());
      const Status restored = estimator->RestoreState(state);
      EXPECT_TRUE(restored.ok()) << restored.message();
      EXPECT_EQ(estimator->frames_added(), static_cast<int>(k) + 1);
    }
    const Eigen::Vector3d up_body = truth[k].R_world_body.transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up_sensor =
        truth[k].R_world_sensor.transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d prior_up =
        sim::RotationFromAttitude({prior[0], prior[1], 0.0}).transpose() * Eigen::Vector3d::UnitZ();
    if (static_cast<int>(k) >= skip) {
      run.body_error_deg.push_back(AngleDeg(est->up_body, up_body));
      run.sensor_error_deg.push_back(AngleDeg(est->up_sensor, up_sensor));
      const Eigen::Matrix3d& P = est->up_sensor_covariance;
      EXPECT_TRUE(P.allFinite()) << "frame " << k;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(P);
      EXPECT_GT(eig.eigenvalues().maxCoeff(), 0.0) << "frame " << k;
      const Eigen::Vector3d d = est->up_sensor - up_sensor;
      double nees = 0.0;
      for (int i = 0; i < 3; ++i) {
        const double l = eig.eigenvalues()(i);
        if (l > 1e-9 * eig.eigenvalues().maxCoeff()) {
          nees += std::pow(eig.eigenvectors().col(i).dot(d), 2) / l;
        }
      }
      run.sensor_nees.push_back(nees);
      run.sensor_sigma_deg.push_back(std::sqrt(P.trace()) / kDegToRad);
      run.prior_error_deg.push_back(AngleDeg(prior_up, up_body));
    }
    run.estimates.push_back(*est);
  }
  if (cues.smooth) {
    Expected<std::vector<GravityEstimate>> solved = smoother->Solve();
    EXPECT_TRUE(solved.ok()) << solved.error().message;
    if (!solved.ok()) return run;
    EXPECT_EQ(solved->size(), stamps.size());
    run.smoothed = *solved;
    for (std::size_t k = static_cast<std::size_t>(skip); k < solved->size(); ++k) {
      EXPECT_EQ((*solved)[k].stamp_s, stamps[k]);
      const Eigen::Vector3d up_sensor =
          truth[k].R_world_sensor.transpose() * Eigen::Vector3d::UnitZ();
      run.smoothed_sensor_error_deg.push_back(AngleDeg((*solved)[k].up_sensor, up_sensor));
    }
  }
  return run;
}

// A simulated drive (libsim's IMU model) through the estimator.
DriveRun EstimateDrive(const GravityEstimatorConfig& config, const sim::Terrain& terrain,
                  const sim::DriveSpec& spec, const sim::ImuSpec& imu, const Cues& cues,
                  int skip) {
  Expected<sim::Drive> drive =
      sim::SimulateDrive(terrain, spec, sim::SensorFrame::kCameraOptical, 7, 0, imu);
  EXPECT_TRUE(drive.ok()) << drive.error().message;
  std::vector<double> stamps;
  std::vector<Truth> truth;
  std::vector<Eigen::Vector3d> odometry;
  for (const sim::DriveSample& s : drive->samples) {
    stamps.push_back(s.stamp_s);
    truth.push_back(
        {s.T_world_body.linear(), s.T_world_sensor.linear(), s.T_world_body.translation().z()});
    odometry.emplace_back(s.odometry.x_m, s.odometry.y_m, s.odometry.yaw_rad);
  }
  return Estimate(config, drive->T_body_sensor.linear(), stamps, truth, odometry, drive->imu,
                  cues, skip);
}

// A smooth drive on flat ground at speed v with the heading heading(t), frames every
// frame_period_s, IMU at 100 Hz with an accelerometer bias (the simulated drive follows a
// polyline, whose corners are velocity jumps).
DriveRun EstimateFlat(const GravityEstimatorConfig& config, const Eigen::Vector3d& accel_bias,
                      double duration, const std::function<double(double)>& heading,
                      double frame_period_s, const Cues& cues, int skip) {
  const double v = 2.0, h = 1e-4;
  std::vector<Eigen::Vector2d> table(static_cast<std::size_t>((duration + 1.0) / h) + 2);
  table[0].setZero();
  for (std::size_t i = 1; i < table.size(); ++i) {
    const double mid = heading((i - 0.5) * h);
    table[i] = table[i - 1] + v * h * Eigen::Vector2d(std::cos(mid), std::sin(mid));
  }
  auto pose = [&](double t) {
    Eigen::Vector2d xy;
    if (t <= 0.0) {
      xy = Eigen::Vector2d(v * t, 0.0);
    } else {
      const double u = t / h;
      const std::size_t i = static_cast<std::size_t>(u);
      xy = table[i] + (u - i) * (table[i + 1] - table[i]);
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << xy, 0.0;
    T.linear() = Eigen::AngleAxisd(heading(t), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
  };
  const Eigen::Matrix3d R_body_sensor = sim::BodyToSensor(sim::DriveSpec{},
                                                          sim::SensorFrame::kCameraOptical).linear();
  std::vector<double> stamps;
  std::vector<Truth> truth;
  std::vector<Eigen::Vector3d> odometry;
  for (int k = 0; k * frame_period_s <= duration; ++k) {
    const double t = k * frame_period_s;
    const Eigen::Isometry3d T = pose(t);
    stamps.push_back(t);
    truth.push_back({T.linear(), T.linear() * R_body_sensor});
    odometry.emplace_back(T.translation().x(), T.translation().y(), heading(t));
  }
  std::mt19937_64 rng(cues.seed + 100);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<sim::ImuReading> imu;
  for (int j = 0; (j + 0.5) * 0.01 <= stamps.back(); ++j) {
    sim::ImuReading reading = sim::IdealImuReading(pose, (j + 0.5) * 0.01, 0.01);
    for (int i = 0; i < 3; ++i) {
      reading.specific_force_mps2[i] += accel_bias[i] + 0.02 * normal(rng);
      reading.angular_rate_radps[i] += 0.002 * normal(rng);
    }
    imu.push_back(reading);
  }
  return Estimate(config, R_body_sensor, stamps, truth, odometry, imu, cues, skip);
}

// From straight to turning and back: yaw rate omega0 (1 - cos(2 pi t / P)) / 2 (a
// constant-rate circle would let a gyro bias stand in for a tilt), frames at 10 Hz.
DriveRun EstimateTurning(const GravityEstimatorConfig& config, const Eigen::Vector3d& accel_bias,
                         double duration, const Cues& cues, int skip) {
  const double omega0 = 0.5, period = 20.0;
  auto heading = [&](double t) {
    return 0.5 * omega0 * (t - period / (2.0 * kPi) * std::sin(2.0 * kPi * t / period));
  };
  return EstimateFlat(config, accel_bias, duration, heading, 0.1, cues, skip);
}

sim::DriveSpec SideSlopeDrive(double length_m) {
  sim::DriveSpec spec;
  spec.waypoints = {{0.0, 0.0}, {length_m, 0.0}};
  spec.speed_mps = 2.0;
  spec.frame_rate_hz = 10.0;
  spec.odom_sigma_per_m = 0.01;
  spec.imu_sigma_rad = 0.0;  // the attitude output's errors come from Cues
  spec.imu_bias_rad = 0.0;
  return spec;
}

TEST(GravityEstimator, RecoversAKnownTiltOnASideSlopeFromABiasedPrior) {
  // 8 deg side slope (uphill to the left), speed changes, the IMU's attitude output 2.5 deg
  // off in roll and pitch, an accelerometer bias, trunks in view and a calibrated mount:
  // the trunks see the tilt itself, so even driving straight the bias is told from a tilt.
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 8.0 * kDegToRad, 90.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(40.0);
  spec.speed_wave_mps = 0.5;
  sim::ImuSpec imu;
  imu.accel_bias_mps2 << 0.05, -0.05, 0.0;
  GravityEstimatorConfig config;
  config.estimate_mount = false;
  const DriveRun run = EstimateDrive(config, terrain, spec, imu, Cues{}, 20);
  ASSERT_GT(run.body_error_deg.size(), 150u);
  Print("side slope, IMU attitude output (prior)", run.prior_error_deg);
  Print("side slope, estimated body tilt", run.body_error_deg);
  EXPECT_GT(Percentile(run.prior_error_deg, 0.5), 3.0);  // 2.5 deg in roll and in pitch
  EXPECT_LT(Percentile(run.body_error_deg, 0.5), 0.2);
  EXPECT_LT(Percentile(run.body_error_deg, 0.95), 0.5);
  const GravityEstimate& last = run.estimates.back();
  EXPECT_TRUE(last.IsSolutionUsable()) << last.solver_report;
  EXPECT_GE(last.cues.accel_terms, 1);
  EXPECT_GT(last.cues.verticals, 20);
  EXPECT_GT(last.cues.vertical_outliers, 0);  // the 12 deg leaners
  EXPECT_FALSE(last.Degenerate(GravityDegeneracy::State::kAccelBias)) << last.BriefReport();
  EXPECT_NEAR(last.accel_bias_mps2.x(), 0.05, 0.02) << last.BriefReport();
  EXPECT_NEAR(last.accel_bias_mps2.y(), -0.05, 0.02) << last.BriefReport();
  // The attitude output's bias is found too (it is what the prior got wrong).
  EXPECT_NEAR(last.attitude_bias_rad.x(), 2.5 * kDegToRad, 0.3 * kDegToRad);
  EXPECT_NEAR(last.attitude_bias_rad.y(), 2.5 * kDegToRad, 0.3 * kDegToRad);
  ASSERT_TRUE(std::isfinite(last.attitude_covariance(0, 0)));
  EXPECT_LT(std::sqrt(last.attitude_covariance(0, 0)), 0.3 * kDegToRad);
}

// A wheel odometry that drifts 3 % of the distance (its random walk 3 cm a metre) reads
// the speed 3 cm/s off on each 1 m step, and its accelerometer term's motion as much as
// 0.1 m/s^2 off: 0.6 deg of tilt. Stated (odometry_walk_sigma), the terms weigh as little
// as that noise says, and the trunks and the gyro hold the tilt.
TEST(GravityEstimator, AnOdometryRandomWalkStatedAsSuchDoesNotTiltTheEstimate) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 8.0 * kDegToRad, 90.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(60.0);
  spec.frame_rate_hz = 2.0;
  spec.speed_wave_mps = 0.5;
  spec.odom_sigma_per_m = 0.03;
  GravityEstimatorConfig config;
  config.estimate_mount = false;
  const DriveRun unstated = EstimateDrive(config, terrain, spec, sim::ImuSpec{}, Cues{}, 4);
  config.odometry_walk_sigma = 0.03;
  const DriveRun stated = EstimateDrive(config, terrain, spec, sim::ImuSpec{}, Cues{}, 4);
  Print("odometry 3 %, walk unstated, estimated body tilt", unstated.body_error_deg);
  Print("odometry 3 %, walk stated, estimated body tilt", stated.body_error_deg);
  EXPECT_LT(Percentile(stated.body_error_deg, 0.5), 0.2);
  EXPECT_LT(Percentile(stated.body_error_deg, 0.95), 0.5);
  EXPECT_LT(Percentile(stated.body_error_deg, 0.95), Percentile(unstated.body_error_deg, 0.95));
}

// The accelerometer sees the body's up from the third frame on: the newest frame's velocity
// is the backward difference of the odometry until the next frame brings the central one,
// so the accelerometer term that ends at the newest frame is there when it arrives. No
// trunks: only the accelerometer can tell the 2.5 deg bias of the attitude output from the
// tilt. (With no velocity for the newest frame, the third frame's estimate was the biased
// prior's: the term came a frame later.)
TEST(GravityEstimator, TheAccelerometerSeesTheUpFromTheThirdFrame) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 8.0 * kDegToRad, 90.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(10.0);
  spec.frame_rate_hz = 2.0;
  Cues cues;
  cues.trunks = false;
  GravityEstimatorConfig config;
  config.estimate_mount = false;
  const DriveRun run = EstimateDrive(config, terrain, spec, sim::ImuSpec{}, cues, 0);
  ASSERT_GE(run.body_error_deg.size(), 6u);
  for (std::size_t k = 2; k < 6; ++k) {
    EXPECT_GT(run.prior_error_deg[k], 2.5) << "frame " << k;
    EXPECT_LT(run.body_error_deg[k], 0.75) << "frame " << k;  // 0.2-0.6 deg here
    EXPECT_GE(run.estimates[k].cues.accel_terms, 1) << "frame " << k;
  }
}

TEST(GravityEstimator, AnAccelerometerBiasIsObservedWhenTurningAndFlaggedWhenStraight) {
  const Eigen::Vector3d bias(0.08, -0.06, 0.03);
  Cues cues;
  cues.trunks = false;
  const DriveRun turning = EstimateTurning(GravityEstimatorConfig{}, bias, 25.0, cues, 10);
  const GravityEstimate& after = turning.estimates.back();
  Print("turning, accelerometer bias, estimated body tilt", turning.body_error_deg);
  EXPECT_NEAR(after.accel_bias_mps2.x(), bias.x(), 0.02) << after.BriefReport();
  EXPECT_NEAR(after.accel_bias_mps2.y(), bias.y(), 0.02) << after.BriefReport();
  EXPECT_FALSE(after.Degenerate(GravityDegeneracy::State::kAccelBias)) << after.BriefReport();
  EXPECT_LT(Percentile(turning.body_error_deg, 0.5), 0.2);
  // The first frames, before the turn, had it flagged.
  EXPECT_TRUE(turning.estimates[5].Degenerate(GravityDegeneracy::State::kAccelBias));

  // Straight on flat ground with the same bias: flagged, with the reason, and not learned.
  sim::ImuSpec imu;
  imu.accel_bias_mps2 = bias;
  const DriveRun straight =
      EstimateDrive(GravityEstimatorConfig{}, sim::Terrain::Flat(), SideSlopeDrive(30.0), imu, cues, 10);
  const GravityEstimate& last = straight.estimates.back();
  Print("straight, accelerometer bias (flagged), estimated body tilt", straight.body_error_deg);
  ASSERT_TRUE(last.Degenerate(GravityDegeneracy::State::kAccelBias)) << last.BriefReport();
  EXPECT_NE(last.BriefReport().find("straight drive"), std::string::npos);
  // Each reason starts with its state's name (what cairn map's frames.csv lists).
  for (const GravityDegeneracy& d : last.degeneracies) {
    EXPECT_EQ(d.reason.rfind(StateName(d.state), 0), 0u) << d.reason;
  }
  EXPECT_STREQ(StateName(GravityDegeneracy::State::kAccelBias), "accelerometer bias");
  EXPECT_GT(std::abs(last.accel_bias_mps2.x() - bias.x()), 0.03);  // not learned
}

// The resume state: an estimator saved mid-drive (frames marginalised, biases learned) and
// restored into a new one gives the same estimates, to the last bit, as the one never
// interrupted; and the state stays the size of the window however long the drive.
// A weave at the frame rate (heading 0.4 rad sin(2 pi t / 4 s), frames at 1.6 Hz as on the
// demo drive): the odometry's velocities are chord means, so their difference weighs the
// acceleration with a trapezoid reaching a frame beyond each end of the span, and the
// accelerometer is averaged with the same kernel. With the tilt held at the truth (a
// reference attitude), the accelerometer bias takes whatever the term gets wrong: averaged
// uniformly over the span instead (motion noise 0.05), it reached 0.30 m/s^2 (median
// 0.0055).
TEST(GravityEstimator, AWeaveBetweenSlowFramesIsNotTakenForATilt) {
  const auto heading = [](double t) { return 0.4 * std::sin(2.0 * kPi * t / 4.0); };
  Cues cues;
  cues.trunks = false;
  cues.attitude_bias_rad = 0.0;
  cues.attitude_sigma_rad = 0.02 * kDegToRad;  // a reference attitude: the tilt is held
  GravityEstimatorConfig config;
  config.attitude_prior_sigma_rad = 0.02 * kDegToRad;
  config.attitude_bias_sigma_rad = 0.001 * kDegToRad;
  const DriveRun run = EstimateFlat(config, Eigen::Vector3d::Zero(), 40.0, heading, 0.625, cues, 6);
  ASSERT_GT(run.body_error_deg.size(), 50u);
  // With the tilt held at the truth, what the accelerometer term gets wrong goes into the
  // accelerometer bias: it stays within its noise (0.02 m/s^2 / sqrt(100 per frame)).
  std::vector<double> bias;
  for (const GravityEstimate& e : run.estimates) bias.push_back(e.accel_bias_mps2.head<2>().norm());
  std::printf(
      "[ figures  ] weave at 1.6 Hz, tilt held: accelerometer bias median %.4f, max %.4f "
      "m/s^2\n",
      Percentile(bias, 0.5), Percentile(bias, 1.0));
  EXPECT_LT(Percentile(bias, 0.5), 0.004);
  EXPECT_LT(Percentile(bias, 1.0), 0.008);
  EXPECT_EQ(run.estimates.back().cues.accel_outliers, 0) << run.estimates.back().BriefReport();
}

// An odometry 2% long adds 2% to every climb the height steps integrate; the frame-to-map
// ground heights (here the true ones, 5 cm sigma) tell a scale from a tilt where the tilt
// is pinned (trunks, a calibrated mount). On a 40 m climb of 12 deg, frames at 2 Hz:
TEST(GravityEstimator, AnOdometryScaleErrorIsLearnedOnAClimb) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 12.0 * kDegToRad, 0.0);
  sim::DriveSpec spec = SideSlopeDrive(40.0);
  spec.odom_sigma_per_m = 0.0;
  spec.frame_rate_hz = 2.0;
  Cues cues;
  cues.ground_sigma_m = 0.05;
  cues.odometry_scale = 0.02;
  GravityEstimatorConfig config;
  config.estimate_mount = false;  // calibrated: the trunks see the body's tilt
  const DriveRun learned = EstimateDrive(config, terrain, spec, sim::ImuSpec{}, cues, 10);
  config.estimate_odometry_scale = false;
  const DriveRun held = EstimateDrive(config, terrain, spec, sim::ImuSpec{}, cues, 10);
  ASSERT_GT(learned.body_error_deg.size(), 25u);
  ASSERT_EQ(held.body_error_deg.size(), learned.body_error_deg.size());
  const double scale = learned.estimates.back().odometry_scale;
  std::printf(
      "[ figures  ] odometry 2%% long on a 12 deg climb: scale estimated %+.2f%%; body "
      "tilt error median %.3f deg (%.3f deg with the scale not estimated)\n",
      100.0 * scale, Percentile(learned.body_error_deg, 0.5), Percentile(held.body_error_deg, 0.5));
  // Learned in part over 40 m (its prior is 2%): the climbs the height steps add are what
  // tell it, against the trunks' tilt.
  EXPECT_GT(scale, 0.006);
  EXPECT_LT(scale, 0.03);
  // Held at zero, the scale's climb is put down to the pitch instead.
  EXPECT_LT(Percentile(learned.body_error_deg, 0.5), 0.8 * Percentile(held.body_error_deg, 0.5));
}

TEST(GravityEstimator, ARestoredStateGivesTheSameEstimatesAndStaysTheSizeOfTheWindow) {
  GravityEstimatorConfig config;
  Cues cues;
  cues.state_sizes = true;
  const Eigen::Vector3d bias(0.05, -0.04, 0.02);
  const DriveRun whole = EstimateTurning(config, bias, 30.0, cues, 0);
  cues.resume_at = 150;
  const DriveRun resumed = EstimateTurning(config, bias, 30.0, cues, 0);
  ASSERT_EQ(whole.estimates.size(), 301u);
  ASSERT_EQ(resumed.estimates.size(), whole.estimates.size());
  for (std::size_t k = 0; k < whole.estimates.size(); ++k) {
    const GravityEstimate& a = whole.estimates[k];
    const GravityEstimate& b = resumed.estimates[k];
    EXPECT_EQ(a.roll_rad, b.roll_rad) << "frame " << k;
    EXPECT_EQ(a.pitch_rad, b.pitch_rad) << "frame " << k;
    EXPECT_EQ(a.height_m, b.height_m) << "frame " << k;
    EXPECT_TRUE(a.accel_bias_mps2 == b.accel_bias_mps2) << "frame " << k;
    EXPECT_TRUE(a.gyro_bias_radps == b.gyro_bias_radps) << "frame " << k;
    EXPECT_TRUE(a.mount_rad == b.mount_rad) << "frame " << k;
    // The covariance differs in its last digits even between two runs that never stopped:
    // ceres::Covariance orders the parameter blocks by their addresses. (So may the flags
    // drawn from it, near their thresholds: they are not compared.)
    EXPECT_NEAR(a.attitude_covariance(0, 0), b.attitude_covariance(0, 0),
                1e-9 * std::abs(a.attitude_covariance(0, 0)))
        << "frame " << k;
    EXPECT_EQ(a.cues.heading_change_rad, b.cues.heading_change_rad) << "frame " << k;
  }
  // The bias was learned before the save and is carried: the run is not trivially equal.
  EXPECT_NEAR(whole.estimates.back().accel_bias_mps2.x(), 0.05, 0.02);
  // Bounded: from frame 50 on (the window of 12 long full) the state grows no more than
  // the noise of the numbers' digits, while the drive grows sixfold.
  const std::size_t at_50 = whole.state_bytes[50];
  const std::size_t most =
      *std::max_element(whole.state_bytes.begin() + 50, whole.state_bytes.end());
  EXPECT_LT(most, at_50 + at_50 / 10) << "state " << at_50 << " bytes at frame 50, up to " << most;
}

// A state that is not one, or not this estimator's, is refused naming what is wrong, and the
// estimator it was given to is left exactly as it was (its own state text unchanged).
TEST(GravityEstimator, ABadStateIsRefusedAndChangesNothing) {
  GravityEstimatorConfig config;
  Cues cues;
  int checked = 0;
  cues.after_frame = [&](GravityEstimator& estimator, int k) {
    if (k != 100) return;
    const std::string good = estimator.SaveState();
    const nlohmann::json state = nlohmann::json::parse(good);
    const auto refused = [&](const std::string& text, const std::string& why) {
      const Status s = estimator.RestoreState(text);
      EXPECT_FALSE(s.ok()) << why;
      EXPECT_NE(s.message().find("gravity.state"), std::string::npos) << s.message();
      EXPECT_EQ(estimator.SaveState(), good) << why << ": the estimator changed";
      ++checked;
    };
    refused("{\"window\": 3}", "not a state");
    refused("not json", "not JSON");
    nlohmann::json other = state;
    other["config"]["accel_half_span_frames"] = 2;
    refused(other.dump(), "other settings");
    other = state;
    other["window"][0]["id"] = other["window"][0]["id"].get<int>() - 1;
    refused(other.dump(), "ids not consecutive");
    other = state;
    other["added"] = other["added"].get<int>() + 1;
    refused(other.dump(), "added does not end the window");
    other = state;
    other["window"][1]["stamp"] = other["window"][0]["stamp"];
    refused(other.dump(), "stamps not increasing");
    other = state;
    other["priors"].back()["blocks"][0] = "rpy:99999";
    refused(other.dump(), "a prior on no frame of the window");
    other = state;
    other["priors"].back()["blocks"][0] = "rpy:1x";
    refused(other.dump(), "a frame id with trailing text");
    other = state;
    other["priors"].back()["blocks"][1] = other["priors"].back()["blocks"][0];
    refused(other.dump(), "a block named twice");
    other = state;
    other["priors"].back()["L"].erase(0);
    refused(other.dump(), "L of the wrong size");
    other = state;
    other["odometry_scale"] = 0.7;
    refused(other.dump(), "an odometry scale out of its bounds");
    other = state;
    other.erase("odometry_scale");
    refused(other.dump(), "no odometry scale (a state of an earlier cairn)");
    other = state;
    other["window"][2]["chord"] = {2.0, 1.0};
    refused(other.dump(), "a velocity's chord backwards");
    // And the good state, restored, gives back the same text.
    ASSERT_TRUE(estimator.RestoreState(good).ok());
    EXPECT_EQ(estimator.SaveState(), good);
  };
  const DriveRun run = EstimateTurning(config, Eigen::Vector3d(0.05, -0.04, 0.02), 12.0, cues, 0);
  EXPECT_EQ(checked, 13);
  EXPECT_EQ(run.estimates.size(), 121u);
}

// The estimator alone, fed no ground rises (the Mapper's tilt step gives them, and with them
// the mount is found in an open field too: TerrainMapDrift.InAnOpenFieldTheMountIsFound...):
// trunks find the mount; with neither structure nor ground seen twice it is flagged.
TEST(GravityEstimator, AMountMisalignmentIsRecoveredFromTrunksAndFlaggedInAnOpenField) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 6.0 * kDegToRad, 45.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(30.0);
  // About the camera's x axis (right): the camera pitches 2.5 deg more than its nominal mount.
  spec.sensor_misalignment_rad << 2.5 * kDegToRad, 0.0, 0.0;
  const DriveRun trees = EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, Cues{}, 20);
  const GravityEstimate& seen = trees.estimates.back();
  Print("mount misaligned 2.5 deg, trunks, estimated sensor tilt", trees.sensor_error_deg);
  EXPECT_FALSE(seen.Degenerate(GravityDegeneracy::State::kMount)) << seen.BriefReport();
  EXPECT_GT(seen.mount_rad.norm(), 2.0 * kDegToRad);
  EXPECT_LT(Percentile(trees.sensor_error_deg, 0.5), 0.2);
  EXPECT_LT(Percentile(trees.sensor_error_deg, 0.95), 0.5);

  Cues open;
  open.trunks = false;
  const DriveRun field = EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, open, 20);
  const GravityEstimate& blind = field.estimates.back();
  Print("mount misaligned 2.5 deg, open field (flagged), sensor tilt", field.sensor_error_deg);
  Print("mount misaligned 2.5 deg, open field, body tilt", field.body_error_deg);
  ASSERT_TRUE(blind.Degenerate(GravityDegeneracy::State::kMount)) << blind.BriefReport();
  EXPECT_NE(blind.BriefReport().find("0 vertical cues"), std::string::npos);
  EXPECT_LT(blind.mount_rad.norm(), 0.5 * kDegToRad);       // no correction invented
  EXPECT_GT(Percentile(field.sensor_error_deg, 0.5), 2.0);  // the misalignment remains
  EXPECT_LT(Percentile(field.body_error_deg, 0.5), 0.2);    // the body tilt is still right
}

// The sensor's tilt as the estimator states it (GravityEstimate::up_sensor_covariance, from
// the frame's attitude, the mount and their cross terms) holds its error: within the 95 %
// region on at least 95 % of the frames with trunks in view and in an open field alike. With
// trunks, which see the sensor's tilt, the body's and the mount's errors cancel in it (the
// cross terms): it is stated much tighter than either alone. In an open field, where the
// mount is flagged, it is stated as loose as the mount's prior, and the 2.5 deg the mount is
// off stays inside it.
TEST(GravityEstimator, TheSensorsStatedTiltHoldsItsError) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 6.0 * kDegToRad, 45.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(30.0);
  spec.sensor_misalignment_rad << 2.5 * kDegToRad, 0.0, 0.0;
  const auto covered = [](const DriveRun& run) {
    int n = 0;
    for (const double nees : run.sensor_nees) n += nees <= 5.991 ? 1 : 0;  // chi^2(2), 95 %
    return static_cast<double>(n) / static_cast<double>(run.sensor_nees.size());
  };
  const DriveRun trees =
      EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, Cues{}, 0);
  Cues open;
  open.trunks = false;
  const DriveRun field =
      EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, open, 0);
  for (const DriveRun* run : {&trees, &field}) {
    const bool t = run == &trees;
    std::printf(
        "[ figures  ] %s: sensor tilt error median %.3f deg, stated %.3f deg (median); in the "
        "95 %% region on %.0f %% of %zu frames\n",
        t ? "trunks" : "open field", Percentile(run->sensor_error_deg, 0.5),
        Percentile(run->sensor_sigma_deg, 0.5), 100.0 * covered(*run), run->sensor_nees.size());
    EXPECT_GE(covered(*run), 0.95) << (t ? "trunks" : "open field");
  }
  // Not loose beyond use: the error it expects within 5x the error there is (the trunks'
  // stated 2 deg lean against their simulated 1 deg).
  EXPECT_LT(Percentile(trees.sensor_sigma_deg, 0.5), 5.0 * Percentile(trees.sensor_error_deg, 0.5));
  EXPECT_LT(Percentile(field.sensor_sigma_deg, 0.5), 5.0 * Percentile(field.sensor_error_deg, 0.5));
  // With trunks: tighter than the body's and the mount's variances added.
  const GravityEstimate& last = trees.estimates.back();
  const double apart = std::sqrt(last.attitude_covariance.topLeftCorner<2, 2>().trace() +
                                 last.mount_covariance.trace());
  std::printf("[ figures  ] trunks, last frame: stated %.3f deg, body and mount apart %.3f deg\n",
              std::sqrt(last.up_sensor_covariance.trace()) / kDegToRad, apart / kDegToRad);
  EXPECT_LT(std::sqrt(last.up_sensor_covariance.trace()), 0.7 * apart);
  // In the open field the mount's prior: the misalignment stays, and is stated.
  EXPECT_GT(Percentile(field.sensor_error_deg, 0.5), 2.0);
  EXPECT_GT(Percentile(field.sensor_sigma_deg, 0.5), 2.5);
}

// The window answers a frame from the frames up to it: with a misaligned mount and the first
// trunks 5 s into the drive, the first frames' sensor tilt is the misalignment. The smoother,
// given the same frames, applies the mount the trunks showed to every frame (and a smoother
// saved and restored halfway solves the same).
TEST(GravitySmoother, AppliesTheMountLearnedFromLaterTrunksToTheFirstFrames) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 6.0 * kDegToRad, 45.0 * kDegToRad);
  sim::DriveSpec spec = SideSlopeDrive(30.0);
  spec.sensor_misalignment_rad << 2.5 * kDegToRad, 0.0, 0.0;
  Cues cues;
  cues.trunks_from = 50;  // 10 Hz: the first 5 s see none
  cues.smooth = true;
  const DriveRun run =
      EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, cues, 0);
  ASSERT_EQ(run.smoothed.size(), run.estimates.size());
  const std::vector<double> window_first(run.sensor_error_deg.begin(),
                                         run.sensor_error_deg.begin() + 50);
  const std::vector<double> smoothed_first(run.smoothed_sensor_error_deg.begin(),
                                           run.smoothed_sensor_error_deg.begin() + 50);
  Print("mount misaligned 2.5 deg, trunks from 5 s, window, first 5 s", window_first);
  Print("mount misaligned 2.5 deg, trunks from 5 s, smoother, first 5 s", smoothed_first);
  Print("mount misaligned 2.5 deg, trunks from 5 s, smoother, whole drive",
        run.smoothed_sensor_error_deg);
  EXPECT_GT(Percentile(window_first, 0.5), 1.0);  // the window could not know
  EXPECT_LT(Percentile(smoothed_first, 0.5), 0.2);
  EXPECT_LT(Percentile(run.smoothed_sensor_error_deg, 0.95), 0.5);
  // The mount the trunks showed.
  const GravityEstimate& first = run.smoothed.front();
  EXPECT_NEAR(first.mount_rad.norm(), 2.5 * kDegToRad, 0.3 * kDegToRad);
  EXPECT_TRUE(first.IsSolutionUsable()) << first.solver_report;

  cues.smoother_resume_at = 120;
  const DriveRun resumed =
      EstimateDrive(GravityEstimatorConfig{}, terrain, spec, sim::ImuSpec{}, cues, 0);
  ASSERT_EQ(resumed.smoothed.size(), run.smoothed.size());
  for (std::size_t k = 0; k < run.smoothed.size(); ++k) {
    EXPECT_NEAR(resumed.smoothed[k].roll_rad, run.smoothed[k].roll_rad, 1e-9) << "frame " << k;
    EXPECT_NEAR(resumed.smoothed[k].pitch_rad, run.smoothed[k].pitch_rad, 1e-9) << "frame " << k;
    EXPECT_NEAR(resumed.smoothed[k].height_m, run.smoothed[k].height_m, 1e-9) << "frame " << k;
  }
}

// Solving leaves the smoother as it was: a second solve gives the same, and so does a smoother
// saved after the first. A frame the window answered first starts from that answer, and the
// solve ends where it ends from the gyro's chain.
TEST(GravitySmoother, SolvingChangesNothingCarriedAndStartsWhereItIsTold) {
  const sim::Terrain terrain = sim::Terrain::Slope(0.0, 6.0 * kDegToRad, 45.0 * kDegToRad);
  Expected<sim::Drive> drive =
      sim::SimulateDrive(terrain, SideSlopeDrive(10.0), sim::SensorFrame::kCameraOptical, 7, 0, {});
  ASSERT_TRUE(drive.ok());
  const GravityEstimatorConfig config;
  Expected<GravitySmoother> plain =
      GravitySmoother::Create(config, Eigen::Matrix3d::Identity(), drive->T_body_sensor.linear());
  Expected<GravitySmoother> started =
      GravitySmoother::Create(config, Eigen::Matrix3d::Identity(), drive->T_body_sensor.linear());
  Expected<GravityEstimator> window =
      GravityEstimator::Create(config, Eigen::Matrix3d::Identity(), drive->T_body_sensor.linear());
  ASSERT_TRUE(plain.ok() && started.ok() && window.ok());
  std::size_t j = 0;
  for (const sim::DriveSample& s : drive->samples) {
    GravityFrame frame;
    frame.stamp_s = s.stamp_s;
    for (; j < drive->imu.size() && drive->imu[j].stamp_s <= s.stamp_s + 1e-9; ++j) {
      frame.imu.push_back({drive->imu[j].stamp_s, drive->imu[j].specific_force_mps2,
                           drive->imu[j].angular_rate_radps});
    }
    frame.odometry_xy_yaw = Eigen::Vector3d(s.odometry.x_m, s.odometry.y_m, s.odometry.yaw_rad);
    const sim::Attitude a = sim::AttitudeFromRotation(s.T_world_body.linear());
    frame.attitude_prior_rad = Eigen::Vector2d(a.roll_rad, a.pitch_rad);
    const Expected<GravityEstimate> est = window->AddFrame(frame);
    ASSERT_TRUE(est.ok()) << est.error().message;
    ASSERT_TRUE(plain->Add(frame).ok());
    ASSERT_TRUE(started->Add(frame, &*est).ok());
  }
  const std::string before = plain->SaveState();
  EXPECT_NE(started->SaveState(), before);  // its frames start elsewhere
  const Expected<std::vector<GravityEstimate>> a = plain->Solve();
  ASSERT_TRUE(a.ok()) << a.error().message;
  EXPECT_EQ(plain->SaveState(), before);
  const Expected<std::vector<GravityEstimate>> b = plain->Solve();
  const Expected<std::vector<GravityEstimate>> c = started->Solve();
  ASSERT_TRUE(b.ok() && c.ok());
  ASSERT_EQ(a->size(), drive->samples.size());
  for (std::size_t k = 0; k < a->size(); ++k) {
    EXPECT_EQ((*a)[k].roll_rad, (*b)[k].roll_rad) << "frame " << k;
    EXPECT_EQ((*a)[k].height_m, (*b)[k].height_m) << "frame " << k;
    // Within 1e-4 rad (0.006 deg): the second solve's IMU terms are pre-integrated at the
    // gyro bias each first solve found.
    EXPECT_NEAR((*a)[k].roll_rad, (*c)[k].roll_rad, 1e-4) << "frame " << k;
    EXPECT_NEAR((*a)[k].pitch_rad, (*c)[k].pitch_rad, 1e-4) << "frame " << k;
    EXPECT_NEAR((*a)[k].height_m, (*c)[k].height_m, 1e-3) << "frame " << k;
  }
  // A start that is not finite is refused.
  GravityEstimate bad;
  bad.roll_rad = NAN;
  GravityFrame later;
  later.stamp_s = drive->samples.back().stamp_s + 1.0;
  EXPECT_FALSE(plain->Add(later, &bad).ok());
  EXPECT_EQ(plain->SaveState(), before);
  // A sliding window's state, whose first frames left it, is no smoother's: its settings
  // differ, and so does one with the smoother's settings whose first frame is gone.
  EXPECT_FALSE(plain->RestoreState(window->SaveState()).ok());
  nlohmann::json cut = nlohmann::json::parse(before);
  cut.at("window").erase(cut.at("window").begin());
  const Status refused = plain->RestoreState(cut.dump());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("sliding window"), std::string::npos) << refused.message();
  EXPECT_EQ(plain->SaveState(), before);
}

TEST(GravitySmoother, RefusesToSolveNothingAndChecksItsFrames) {
  Expected<GravitySmoother> smoother = GravitySmoother::Create(
      GravityEstimatorConfig{}, Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(smoother.ok());
  const Expected<std::vector<GravityEstimate>> none = smoother->Solve();
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("no frames"), std::string::npos) << none.error().message;
  GravityFrame frame;
  frame.stamp_s = 1.0;
  ASSERT_TRUE(smoother->Add(frame).ok());
  frame.stamp_s = 0.5;
  const Status late = smoother->Add(frame);
  ASSERT_FALSE(late.ok());
  EXPECT_NE(late.message().find("frame.stamp_s"), std::string::npos) << late.message();
  EXPECT_EQ(smoother->frames(), 1);
  // A frame whose second IMU sample is bad changes nothing: the next frame's samples may
  // start right after the first frame's.
  const std::string before = smoother->SaveState();
  frame.stamp_s = 2.0;
  frame.imu = {{1.5, Eigen::Vector3d(0, 0, 9.8), Eigen::Vector3d::Zero()},
               {1.4, Eigen::Vector3d(0, 0, 9.8), Eigen::Vector3d::Zero()}};
  const Status backwards = smoother->Add(frame);
  ASSERT_FALSE(backwards.ok());
  EXPECT_NE(backwards.message().find("frame.imu[1].stamp_s"), std::string::npos)
      << backwards.message();
  EXPECT_EQ(smoother->SaveState(), before);
  frame.imu = {{1.2, Eigen::Vector3d(0, 0, 9.8), Eigen::Vector3d::Zero()}};
  EXPECT_TRUE(smoother->Add(frame).ok());
  EXPECT_FALSE(smoother->RestoreState("{}").ok());
  EXPECT_EQ(smoother->frames(), 2);
}

// ---- derivatives ------------------------------------------------------------------------

void ExpectDerivativesMatchNumeric(const ceres::CostFunction& cost,
                                   std::vector<std::vector<double>> values) {
  std::vector<double*> parameters;
  for (auto& v : values) parameters.push_back(v.data());
  ceres::NumericDiffOptions numeric;
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(&cost, no_manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(parameters.data(), 1e-6, &results)) << results.error_log;
}

std::vector<gravity::ImuSegment> SomeSegments(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<gravity::ImuSegment> out;
  for (int i = 0; i < n; ++i) {
    gravity::ImuSegment s;
    s.omega_imu << 0.3 * normal(rng), 0.3 * normal(rng), 0.5 * normal(rng);
    s.force_imu << normal(rng), normal(rng), 9.8 + normal(rng);
    s.before_s = 0.005;
    s.after_s = 0.005;
    s.weight = 0.2 + 0.1 * i;  // an averaging kernel's (AccelTerm)
    out.push_back(s);
  }
  return out;
}

TEST(GravityTerms, DerivativesMatchNumericOnes) {
  const std::vector<double> rpy0 = {0.05, -0.12, 0.7}, rpy1 = {0.06, -0.1, 0.75},
                            rpy2 = {0.08, -0.09, 0.8};
  const std::vector<double> bias3 = {0.02, -0.01, 0.03}, gyro3 = {0.001, -0.002, 0.0015};
  const std::vector<double> mount = {0.01, -0.02}, bias2 = {0.03, -0.01};

  const Eigen::Vector3d bg0(gyro3[0], gyro3[1], gyro3[2]);
  auto* gyro = new gravity::GyroTerm;
  gyro->segments = SomeSegments(10, 1);
  gyro->R_body_imu = Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  gyro->Preintegrate(bg0);
  ceres::AutoDiffCostFunction<gravity::GyroTerm, 3, 3, 3, 3> gyro_cost(gyro);
  ExpectDerivativesMatchNumeric(gyro_cost, {rpy0, rpy1, gyro3});

  for (bool from_pitch : {true, false}) {
    auto* acc = new gravity::AccelTerm;
    acc->forward = SomeSegments(5, 2);
    acc->backward = SomeSegments(5, 3);
    acc->v_minus << 1.9, 0.1, 0.05;
    acc->v_plus << 2.1, 0.3, -0.02;
    acc->vertical_from_pitch = from_pitch;
    acc->yaw_minus_rad = -0.08;
    acc->yaw_plus_rad = 0.05;
    acc->Preintegrate(bg0);
    ceres::AutoDiffCostFunction<gravity::AccelTerm, 3, 3, 3, 3, 3, 3, 1> acc_cost(acc);
    ExpectDerivativesMatchNumeric(acc_cost, {rpy0, rpy1, rpy2, bias3, gyro3, {0.013}});
  }

  ceres::AutoDiffCostFunction<gravity::AttitudePriorTerm, 2, 3, 2> prior_cost(
      new gravity::AttitudePriorTerm{0.1, -0.05, 0.01});
  ExpectDerivativesMatchNumeric(prior_cost, {rpy0, bias2});

  for (bool wall : {false, true}) {
    auto* vertical = new gravity::VerticalTerm;
    vertical->direction_sensor = Eigen::Vector3d(0.1, -0.98, 0.05).normalized();
    vertical->R_body_sensor =
        sim::BodyToSensor(sim::DriveSpec{}, sim::SensorFrame::kCameraOptical).linear();
    vertical->wall_normal = wall;
    if (wall) {
      vertical->direction_sensor = Eigen::Vector3d(0.9, 0.05, 0.4).normalized();
      ceres::AutoDiffCostFunction<gravity::VerticalTerm, 1, 3, 2> cost(vertical);
      ExpectDerivativesMatchNumeric(cost, {rpy0, mount});
    } else {
      ceres::AutoDiffCostFunction<gravity::VerticalTerm, 2, 3, 2> cost(vertical);
      ExpectDerivativesMatchNumeric(cost, {rpy0, mount});
    }
  }

  ceres::AutoDiffCostFunction<gravity::HeightStepTerm, 1, 1, 1, 3, 3, 1> step(
      new gravity::HeightStepTerm{0.2, -0.03, true, 0.0, 0.02});
  ExpectDerivativesMatchNumeric(step, {{0.1}, {0.12}, rpy0, rpy1, {0.013}});

  auto* rise = new gravity::GroundRiseTerm;
  rise->R_body_sensor =
      sim::BodyToSensor(sim::DriveSpec{}, sim::SensorFrame::kCameraOptical).linear();
  rise->R0_k = gravity::WorldFromBody(rpy1.data()) * rise->R_body_sensor;
  rise->R0_j = gravity::WorldFromBody(rpy0.data()) * rise->R_body_sensor;
  rise->offset_k << 6.0, 1.0, -1.8;
  rise->offset_j << 10.0, 0.5, -2.6;
  rise->rise_m = 0.8;
  rise->climb_m = 0.4;
  rise->gradient << 0.2, -0.05;
  rise->sensor_on_body << 0.5, 0.0, 1.5;
  rise->Rb0_k = gravity::WorldFromBody(rpy1.data());
  rise->Rb0_j = gravity::WorldFromBody(rpy0.data());
  ceres::AutoDiffCostFunction<gravity::GroundRiseTerm, 1, 1, 1, 3, 3, 2, 1> rise_cost(rise);
  ExpectDerivativesMatchNumeric(rise_cost, {{0.1}, {0.9}, rpy0, rpy1, mount, {0.013}});

  // The marginal prior's Jacobian is written by hand.
  Eigen::MatrixXd L(4, 4);
  L << 2, 0.1, 0, 0.3, 0, 1, 0.2, 0, 0, 0, 3, 0.1, 0, 0, 0, 0.5;
  gravity::LinearPrior linear(L, Eigen::Vector4d(0.1, 0.2, 0.3, 0.4),
                              Eigen::Vector4d(0.01, 0.0, -0.02, 0.0), {2, 2});
  ExpectDerivativesMatchNumeric(linear, {{0.5, 0.1}, {-0.2, 0.7}});
}

// ---- ground rises ------------------------------------------------------------------------

// Rolling terrain, its height at (x, y) [m].
double RollingTerrain(double x, double y) {
  return 0.21 * x - 0.06 * y + 0.25 * std::sin(0.2 * x + 0.1 * y) + 0.05 * std::cos(0.5 * y);
}

// A camera's ground points in its sensor frame: the terrain seen from T_world_sensor on rays
// of a 60 x 40 deg field of view (80 x 60 pixels), found by bisection along each ray, within
// 25 m.
std::vector<Eigen::Vector3f> GroundSeenFrom(const Eigen::Isometry3d& T_world_sensor) {
  std::vector<Eigen::Vector3f> out;
  for (int v = 0; v < 60; ++v) {
    for (int u = 0; u < 80; ++u) {
      const double az = (u - 39.5) / 80.0 * 60.0 * kDegToRad;
      const double el = (v - 29.5) / 60.0 * 40.0 * kDegToRad;
      // Optical frame: x right, y down, z forward.
      const Eigen::Vector3d ray_s(std::tan(az), std::tan(el), 1.0);
      const Eigen::Vector3d o = T_world_sensor.translation();
      const Eigen::Vector3d d = (T_world_sensor.linear() * ray_s).normalized();
      auto above = [&](double t) {
        const Eigen::Vector3d p = o + t * d;
        return p.z() - RollingTerrain(p.x(), p.y());
      };
      if (above(25.0) > 0.0) continue;
      double lo = 0.0, hi = 25.0;
      for (int it = 0; it < 60; ++it) (above(0.5 * (lo + hi)) > 0.0 ? lo : hi) = 0.5 * (lo + hi);
      const Eigen::Vector3d p_world = o + 0.5 * (lo + hi) * d;
      out.push_back((T_world_sensor.inverse() * p_world).cast<float>());
    }
  }
  return out;
}

// A body on the terrain at (x, y) heading `yaw`, attitude from the terrain's gradient there,
// the camera 1.5 m above it pitched 8 deg down.
struct Placed {
  double rpy[3] = {0.0, 0.0, 0.0};
  double h = 0.0;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};
Placed PlaceBody(double x, double y, double yaw, const Eigen::Matrix3d& R_body_sensor) {
  const double e = 1e-5;
  const double gx = (RollingTerrain(x + e, y) - RollingTerrain(x - e, y)) / (2 * e);
  const double gy = (RollingTerrain(x, y + e) - RollingTerrain(x, y - e)) / (2 * e);
  const double slope_x = std::cos(yaw) * gx + std::sin(yaw) * gy;
  const double slope_y = -std::sin(yaw) * gx + std::cos(yaw) * gy;
  Placed p;
  p.rpy[2] = yaw;
  p.rpy[1] = -std::atan(slope_x);
  p.rpy[0] = std::atan(std::cos(p.rpy[1]) * slope_y);
  p.h = RollingTerrain(x, y);
  const Eigen::Matrix3d R_world_body = gravity::WorldFromBody(p.rpy);
  p.T_world_sensor.linear() = R_world_body * R_body_sensor;
  p.T_world_sensor.translation() =
      Eigen::Vector3d(x, y, p.h) + R_world_body * Eigen::Vector3d(0.5, 0.0, 1.5);
  return p;
}

// The ground two frames see, fitted where both saw it: placed at the true poses the later
// frame needs no correction (the rise is the true climb); placed with the later frame's
// sensor tilted and raised, and the earlier one's tilted too, the fitted rise is off, and
// GroundRiseTerm, told the placements, takes the tilts back out: its residual at the true
// states is a few millimetres, against decimetres without the tilts' part.
TEST(GroundRise, TheFittedRiseIsTheTrueClimbOnceThePlacementsTiltsAreTakenOut) {
  const Eigen::Matrix3d R_bs =
      sim::BodyToSensor(sim::DriveSpec{}, sim::SensorFrame::kCameraOptical).linear();
  const internal::GroundRiseFitConfig config;
  const Placed j = PlaceBody(0.0, 0.0, 0.3, R_bs);
  const Placed k = PlaceBody(3.8, 1.2, 0.32, R_bs);
  const std::vector<Eigen::Vector3f> ground_j =
      internal::ThinGroundPoints(GroundSeenFrom(j.T_world_sensor), config);
  const std::vector<Eigen::Vector3f> ground_k =
      internal::ThinGroundPoints(GroundSeenFrom(k.T_world_sensor), config);
  ASSERT_GT(ground_k.size(), 1000u);

  const internal::GroundSurface truth_j(ground_j, j.T_world_sensor, config);
  const std::optional<internal::GroundRiseFit> exact =
      internal::FitGroundRise(ground_k, k.T_world_sensor, truth_j, config);
  ASSERT_TRUE(exact.has_value());
  std::printf("true placements: %d points, dz %.4f m, rms %.4f m\n", exact->points, exact->dz_m,
              exact->rms_m);
  EXPECT_GT(exact->points, 500);
  EXPECT_LT(std::abs(exact->dz_m), 0.003);
  EXPECT_GT(exact->offset_m.head<2>().norm(), 4.0);  // the matched ground lies ahead

  // Misplaced: each sensor turned about its origin (by 0.3 and -0.4 deg about the world's x
  // and y axes, the later one by -0.2 and 0.6 deg), the later one 0.12 m too high.
  const auto turned = [](const Eigen::Isometry3d& T, double ax, double ay) {
    Eigen::Isometry3d out = T;
    out.linear() = (Eigen::AngleAxisd(ay, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(ax, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix() *
                   T.linear();
    return out;
  };
  const Eigen::Isometry3d placed_j = turned(j.T_world_sensor, 0.3 * kDegToRad, -0.4 * kDegToRad);
  Eigen::Isometry3d placed_k = turned(k.T_world_sensor, -0.2 * kDegToRad, 0.6 * kDegToRad);
  placed_k.translation().z() += 0.12;
  const internal::GroundSurface surface_j(ground_j, placed_j, config);
  const std::optional<internal::GroundRiseFit> fit =
      internal::FitGroundRise(ground_k, placed_k, surface_j, config);
  ASSERT_TRUE(fit.has_value());
  // The heights of the placements' bodies: the true ones, the later one raised.
  const double h_j0 = j.h, h_k0 = k.h + 0.12;
  gravity::GroundRiseTerm term;
  term.R_body_sensor = R_bs;
  term.R0_k = placed_k.linear();
  term.R0_j = placed_j.linear();
  term.offset_k = fit->offset_m;
  term.offset_j = fit->offset_earlier_m;
  term.rise_m = fit->dz_m + h_k0 - h_j0;
  term.gradient = fit->gradient;
  term.sigma_m = 1.0;
  const double zero_mount[2] = {0.0, 0.0}, zero_scale = 0.0;
  double residual = 0.0;
  ASSERT_TRUE(term(&j.h, &k.h, j.rpy, k.rpy, zero_mount, &zero_scale, &residual));
  // Without the tilts' part: the measured rise against the true climb.
  const double untilted = term.rise_m - (k.h - j.h);
  std::printf("misplaced: rise off by %.4f m as measured, %.4f m with the tilts taken out\n",
              untilted, residual);
  EXPECT_GT(std::abs(untilted), 0.05);
  EXPECT_LT(std::abs(residual), 0.005);

  // Odometry 3 % long: the later frame placed s / (1 + s) of the step further along; the
  // term with that scale takes it out too.
  const double s = 0.03;
  const Eigen::Vector2d step =
      (k.T_world_sensor.translation() - j.T_world_sensor.translation()).head<2>() * (1.0 + s);
  Eigen::Isometry3d along = placed_k;
  along.translation().head<2>() += step * s / (1.0 + s);
  const std::optional<internal::GroundRiseFit> long_fit =
      internal::FitGroundRise(ground_k, along, surface_j, config);
  ASSERT_TRUE(long_fit.has_value());
  term.offset_k = long_fit->offset_m;
  term.offset_j = long_fit->offset_earlier_m;
  term.rise_m = long_fit->dz_m + h_k0 - h_j0;
  term.gradient = long_fit->gradient;
  term.climb_m = long_fit->gradient.dot(step);
  double scaled = 0.0, unscaled = 0.0;
  ASSERT_TRUE(term(&j.h, &k.h, j.rpy, k.rpy, zero_mount, &s, &scaled));
  ASSERT_TRUE(term(&j.h, &k.h, j.rpy, k.rpy, zero_mount, &zero_scale, &unscaled));
  std::printf("odometry 3 %% long: %.4f m with its scale, %.4f m without\n", scaled, unscaled);
  EXPECT_GT(std::abs(unscaled), 0.015);
  EXPECT_LT(std::abs(scaled), 0.005);

  // The later body placed pitched 1.5 deg nose down about its own origin: the sensor, 0.5 m
  // ahead of it and 1.5 m up, goes down with it. The term carries the sensor with the body.
  const Eigen::Vector3d on_body(0.5, 0.0, 1.5);
  const Eigen::Matrix3d Rb_true = gravity::WorldFromBody(k.rpy);
  const Eigen::Matrix3d Rb_placed =
      Rb_true * Eigen::AngleAxisd(1.5 * kDegToRad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  Eigen::Isometry3d body_placed = Eigen::Isometry3d::Identity();
  body_placed.linear() = Rb_placed;
  body_placed.translation() = k.T_world_sensor.translation() - Rb_true * on_body;
  const Eigen::Isometry3d pitched =
      body_placed * (Eigen::Translation3d(on_body) * Eigen::Isometry3d(R_bs));
  const std::optional<internal::GroundRiseFit> pitched_fit =
      internal::FitGroundRise(ground_k, pitched, truth_j, config);
  ASSERT_TRUE(pitched_fit.has_value());
  gravity::GroundRiseTerm carried;
  carried.R_body_sensor = R_bs;
  carried.R0_k = pitched.linear();
  carried.R0_j = j.T_world_sensor.linear();
  carried.Rb0_k = Rb_placed;
  carried.Rb0_j = gravity::WorldFromBody(j.rpy);
  carried.sensor_on_body = on_body;
  carried.offset_k = pitched_fit->offset_m;
  carried.offset_j = pitched_fit->offset_earlier_m;
  carried.rise_m = pitched_fit->dz_m + k.h - j.h;  // both bodies placed at their true heights
  carried.gradient = pitched_fit->gradient;
  carried.sigma_m = 1.0;
  double with_carry = 0.0, without_carry = 0.0;
  ASSERT_TRUE(carried(&j.h, &k.h, j.rpy, k.rpy, zero_mount, &zero_scale, &with_carry));
  carried.sensor_on_body.setZero();
  ASSERT_TRUE(carried(&j.h, &k.h, j.rpy, k.rpy, zero_mount, &zero_scale, &without_carry));
  std::printf("body pitched 1.5 deg: %.4f m with the sensor carried, %.4f m without\n", with_carry,
              without_carry);
  EXPECT_GT(std::abs(without_carry), 0.01);
  EXPECT_LT(std::abs(with_carry), 0.005);
}

// A step on the plane of the wheels, written in the body frame as (u, v, 0) and turned into
// the world: its horizontal part, in the vehicle's heading, rises by its vertical part.
TEST(GravityTerms, AStepOnTheWheelsPlaneRisesAsTheBodysAttitudeSays) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(-0.3, 0.3), step(-1.5, 1.5), yaw(-kPi, kPi);
  for (int i = 0; i < 200; ++i) {
    const double rpy[3] = {angle(rng), angle(rng), yaw(rng)};
    const Eigen::Matrix3d R = sim::RotationFromAttitude({rpy[0], rpy[1], rpy[2]});
    const Eigen::Vector3d world = R * Eigen::Vector3d(step(rng), step(rng), 0.0);
    // The horizontal part in the level frame of the heading (x forward, y left).
    const Eigen::Vector2d level = Eigen::Rotation2Dd(-rpy[2]).toRotationMatrix() * world.head<2>();
    EXPECT_NEAR(gravity::RiseOnWheelPlane(rpy, level.x(), level.y()), world.z(), 1e-12);
  }
}

// The IMU terms are pre-integrated at one gyro bias and moved to another to first order:
// against their definitions evaluated sample by sample at that bias (the references,
// written here with Eigen's rotations), the residual differs by the second order only,
// and not at all at the bias it was integrated at.
TEST(GravityTerms, PreintegratedTermsMatchTheSamplesIntegratedAtTheBias) {
  const double rpy0[3] = {0.05, -0.12, 0.7}, rpy1[3] = {0.09, -0.1, 0.78},
               rpy2[3] = {0.1, -0.08, 0.85};
  const double ba[3] = {0.02, -0.01, 0.03};
  const double scale = 0.013;
  const Eigen::Vector3d bg0(0.001, -0.002, 0.0015);
  const Eigen::Matrix3d R_bi =
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  // Residuals of the terms integrated at `at`, evaluated at bias `bg`.
  auto gyro_at = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& bg) {
    gravity::GyroTerm t;
    t.segments = SomeSegments(20, 1);
    t.R_body_imu = R_bi;
    t.Preintegrate(at);
    Eigen::Vector3d r;
    EXPECT_TRUE(t(rpy0, rpy1, bg.data(), r.data()));
    return r;
  };
  auto accel_at = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& bg) {
    gravity::AccelTerm t;
    t.forward = SomeSegments(20, 2);
    t.backward = SomeSegments(4, 3);  // mostly forward: a bias turns the sum one way
    t.R_body_imu = R_bi;
    t.v_minus << 1.9, 0.1, 0.05;
    t.v_plus << 2.1, 0.3, -0.02;
    t.yaw_minus_rad = 0.3;  // frame a heads 0.3 rad left of frame k, frame b 0.2 right
    t.yaw_plus_rad = -0.2;
    t.Preintegrate(at);
    Eigen::Vector3d r;
    EXPECT_TRUE(t(rpy0, rpy1, rpy2, ba, bg.data(), &scale, r.data()));
    return r;
  };
  // The references: the terms' definitions, sample by sample, in double, with Eigen's
  // rotations (none of the terms' own code).
  const auto exp = [](const Eigen::Vector3d& w) -> Eigen::Matrix3d {
    const double angle = w.norm();
    if (angle == 0.0) return Eigen::Matrix3d::Identity();
    return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
  };
  const auto gyro_reference = [&](const Eigen::Vector3d& bg) {
    Eigen::Matrix3d dR = Eigen::Matrix3d::Identity();
    for (const gravity::ImuSegment& s : SomeSegments(20, 1)) {
      dR = dR * exp(R_bi * (s.omega_imu - bg) * (s.before_s + s.after_s));
    }
    const Eigen::Matrix3d rel =
        gravity::WorldFromBody(rpy0).transpose() * gravity::WorldFromBody(rpy1);
    const Eigen::AngleAxisd e(Eigen::Matrix3d(dR.transpose() * rel));
    return Eigen::Vector3d(e.axis() * e.angle() / 1e-3);
  };
  const auto accel_reference = [&](const Eigen::Vector3d& bg) {
    // The mean of dR_kj(bg) R_bi (f_j - ba) weighted by w_j, forward from t_k and backward
    // to it.
    const Eigen::Vector3d bias(ba[0], ba[1], ba[2]);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double n = 0.0;
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    for (const gravity::ImuSegment& s : SomeSegments(20, 2)) {
      const Eigen::Vector3d w = R_bi * (s.omega_imu - bg);
      R = R * exp(w * s.before_s);
      sum += s.weight * (R * (R_bi * (s.force_imu - bias)));
      n += s.weight;
      R = R * exp(w * s.after_s);
    }
    R = Eigen::Matrix3d::Identity();
    for (const gravity::ImuSegment& s : SomeSegments(4, 3)) {
      const Eigen::Vector3d w = R_bi * (s.omega_imu - bg);
      R = R * exp(-w * s.after_s);
      sum += s.weight * (R * (R_bi * (s.force_imu - bias)));
      n += s.weight;
      R = R * exp(-w * s.before_s);
    }
    // Expected: R_level_body^T ((v_b - v_a) / span + g e_z), the odometry's velocities
    // divided by 1 + scale, the vertical speeds on the plane of the wheels at the span's
    // ends: its normal is their attitude's z, turned by their heading from frame k's (the
    // term's defaults: span 0.1 s, sigma 0.05 m/s^2).
    Eigen::Vector3d vm(1.9, 0.1, 0.05), vp(2.1, 0.3, -0.02);
    vm.head<2>() /= 1.0 + scale;
    vp.head<2>() /= 1.0 + scale;
    const auto on_plane = [](const double* rpy, double yaw, Eigen::Vector3d& v) {
      const Eigen::Vector3d normal =
          Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * gravity::LevelFromBody(rpy).col(2);
      v.z() = -(normal.x() * v.x() + normal.y() * v.y()) / normal.z();
    };
    on_plane(rpy0, 0.3, vm);
    on_plane(rpy2, -0.2, vp);
    const Eigen::Vector3d expected =
        gravity::LevelFromBody(rpy1).transpose() *
        Eigen::Vector3d((vp - vm) / 0.1 + Eigen::Vector3d(0.0, 0.0, 9.80665));
    return Eigen::Vector3d((sum / n - expected) / 0.05);
  };
  // At the bias they were integrated at, the terms are their definitions.
  EXPECT_LT((gyro_at(bg0, bg0) - gyro_reference(bg0)).norm(), 1e-6);
  EXPECT_LT((accel_at(bg0, bg0) - accel_reference(bg0)).norm(), 1e-9);
  EXPECT_GT(accel_reference(bg0).norm(), 1.0);  // a residual worth comparing
  double last_gyro_error = 0.0, last_accel_error = 0.0;
  for (const double step : {2e-3, 1e-2}) {
    const Eigen::Vector3d bg = bg0 + step * Eigen::Vector3d(1.0, -0.5, 0.7);
    // Moved from bg0 against integrated at bg: the change the bias makes is first order
    // in the step, what the pre-integration misses second order.
    const double gyro_change = (gyro_reference(bg0) - gyro_reference(bg)).norm();
    const double gyro_error = (gyro_at(bg0, bg) - gyro_reference(bg)).norm();
    EXPECT_GT(gyro_change, 100 * gyro_error) << step;
    const double accel_change = (accel_reference(bg0) - accel_reference(bg)).norm();
    const double accel_error = (accel_at(bg0, bg) - accel_reference(bg)).norm();
    EXPECT_GT(accel_change, 100 * accel_error) << step;
    if (last_gyro_error > 0.0) {
      // Second order: five times the step, 25 times the error.
      EXPECT_GT(gyro_error / last_gyro_error, 15.0);
      EXPECT_GT(accel_error / last_accel_error, 15.0);
    }
    last_gyro_error = gyro_error;
    last_accel_error = accel_error;
  }
}

TEST(GravityEstimator, ConfigAndInputErrorsNameTheField) {
  GravityEstimatorConfig config;
  config.window_frames = 2;
  Status s = config.Validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("gravity.window_frames"), std::string::npos);
  config = {};
  config.vertical_sigma_rad = -1.0;
  s = config.Validate();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("gravity.vertical_sigma_rad"), std::string::npos);

  Expected<GravityEstimator> estimator = GravityEstimator::Create(
      GravityEstimatorConfig{}, Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(estimator.ok());
  GravityFrame frame;
  frame.stamp_s = 1.0;
  ASSERT_TRUE(estimator->AddFrame(frame).ok());
  Expected<GravityEstimate> again = estimator->AddFrame(frame);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("gravity.frame.stamp_s"), std::string::npos);
  frame.stamp_s = 2.0;
  frame.verticals.push_back({Eigen::Vector3d::Zero(), false});
  again = estimator->AddFrame(frame);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("gravity.frame.verticals[0]"), std::string::npos);
  frame.verticals.clear();
  frame.ground_rises.resize(2);
  frame.ground_rises[0].earlier_stamp_s = 1.0;
  frame.ground_rises[1].earlier_stamp_s = 1.0;
  frame.ground_rises[1].sigma_m = 0.0;
  again = estimator->AddFrame(frame);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("gravity.frame.ground_rises[1]"), std::string::npos);
  frame.ground_rises[1].sigma_m = 0.05;
  frame.ground_rises[1].earlier_stamp_s = 2.0;
  again = estimator->AddFrame(frame);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("gravity.frame.ground_rises[1].earlier_stamp_s"),
            std::string::npos);
  frame.ground_rises.pop_back();
  EXPECT_TRUE(estimator->AddFrame(frame).ok());  // a rise to the frame before
}

}  // namespace
}  // namespace cairn::map
