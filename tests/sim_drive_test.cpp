// The simulated drive: poses that follow the ground, odometry drift, IMU noise and bias.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/terrain.hpp"

namespace cairn::sim {
namespace {

DriveSpec NoiselessSpec(std::vector<Eigen::Vector2d> waypoints) {
  DriveSpec spec;
  spec.waypoints = std::move(waypoints);
  spec.odom_sigma_per_m = 0.0;
  spec.odom_yaw_sigma_rad_per_m = 0.0;
  spec.imu_sigma_rad = 0.0;
  spec.imu_bias_rad = 0.0;
  return spec;
}

// A path with straight parts and turns both ways.
std::vector<Eigen::Vector2d> WindingPath() {
  return {{0.0, 0.0}, {12.0, 0.0}, {18.0, 6.0}, {18.0, 14.0}, {6.0, 20.0}, {-4.0, 12.0}};
}

double Distance(const Pose2D& a, const Pose2D& b) {
  return std::hypot(a.x_m - b.x_m, a.y_m - b.y_m);
}

TEST(SimDrive, FrameCountFollowsLengthSpeedAndRate) {
  DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {10.0, 0.0}});
  spec.speed_mps = 2.0;
  spec.frame_rate_hz = 10.0;
  EXPECT_EQ(DriveFrameCount(spec), 51);  // 5 s at 10 Hz, both ends
  const Expected<Drive> drive = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  ASSERT_EQ(drive->samples.size(), 51u);
  EXPECT_DOUBLE_EQ(drive->path_length_m, 10.0);
  EXPECT_DOUBLE_EQ(drive->samples.back().stamp_s, 5.0);
  EXPECT_NEAR(drive->samples.back().T_world_body.translation().x(), 10.0, 1e-12);
  EXPECT_NEAR(drive->samples[7].distance_m, 1.4, 1e-12);

  const Expected<Drive> short_drive =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1, 5);
  ASSERT_TRUE(short_drive.ok());
  EXPECT_EQ(short_drive->samples.size(), 5u);
}

TEST(SimDrive, FlatGroundGivesZeroPitchAndRoll) {
  const DriveSpec spec = NoiselessSpec(WindingPath());
  const Expected<Drive> drive =
      SimulateDrive(Terrain::Flat(0.3), spec, SensorFrame::kCameraOptical, 7);
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  ASSERT_GT(drive->samples.size(), 100u);
  od::PinholeModel model = PinholeFromFov(64, 48, 1.2);
  for (const DriveSample& s : drive->samples) {
    EXPECT_NEAR(s.attitude.pitch_rad, 0.0, 1e-12) << "frame " << s.index;
    EXPECT_NEAR(s.attitude.roll_rad, 0.0, 1e-12) << "frame " << s.index;
    EXPECT_NEAR(s.T_world_body.translation().z(), 0.3, 1e-12);
    // The camera is the one a level camera at the mount, pitched down, would be.
    const Eigen::Vector3d position = s.T_world_body * spec.T_body_sensor_xyz;
    const Camera expected =
        Camera::FromAttitude(model, position, s.attitude.yaw_rad, spec.sensor_pitch_rad, 0.0);
    EXPECT_TRUE(s.T_world_sensor.matrix().isApprox(expected.T_world_camera.matrix(), 1e-12))
        << "frame " << s.index;
  }
}

TEST(SimDrive, PlanarSlopeGivesAnalyticPitchAndRoll) {
  const double slope = 15.0 * kDegToRad, uphill = 30.0 * kDegToRad;
  const Terrain terrain = Terrain::Slope(0.5, slope, uphill);
  const Eigen::Vector3d normal = terrain.Normal(0.0, 0.0);
  for (double heading_deg = -180.0; heading_deg < 180.0; heading_deg += 22.5) {
    const double h = heading_deg * kDegToRad;
    const Eigen::Vector2d dir(std::cos(h), std::sin(h));
    const Expected<Drive> drive = SimulateDrive(
        terrain,
        NoiselessSpec({Eigen::Vector2d(1.0, -2.0), Eigen::Vector2d(1.0, -2.0) + 8.0 * dir}),
        SensorFrame::kLidar, 3);
    ASSERT_TRUE(drive.ok()) << drive.error().message;
    // Nose down when going downhill; left side up when uphill is to the left.
    const double pitch = -std::atan(std::tan(slope) * std::cos(h - uphill));
    const double roll = std::atan(std::cos(pitch) * std::tan(slope) * std::sin(uphill - h));
    for (const DriveSample& s : drive->samples) {
      EXPECT_NEAR(s.attitude.pitch_rad, pitch, 1e-12) << "heading " << heading_deg;
      EXPECT_NEAR(s.attitude.roll_rad, roll, 1e-12) << "heading " << heading_deg;
      EXPECT_NEAR(std::remainder(s.attitude.yaw_rad - h, 2 * kPi), 0.0, 1e-12);
      // The body stands on the plane: its z axis is the plane's normal, its origin on it.
      const Eigen::Matrix3d R = s.T_world_body.linear();
      EXPECT_NEAR((R.col(2) - normal).norm(), 0.0, 1e-12);
      const Eigen::Vector3d p = s.T_world_body.translation();
      EXPECT_NEAR(p.z(), terrain.Height(p.x(), p.y()), 1e-12);
    }
  }
  // The textbook cases: straight uphill, and across with uphill on the left.
  const Expected<Drive> up = SimulateDrive(
      terrain, NoiselessSpec({{0.0, 0.0}, {5.0 * std::cos(uphill), 5.0 * std::sin(uphill)}}),
      SensorFrame::kLidar, 3);
  ASSERT_TRUE(up.ok());
  EXPECT_NEAR(up->samples[3].attitude.pitch_rad, -slope, 1e-12);
  EXPECT_NEAR(up->samples[3].attitude.roll_rad, 0.0, 1e-12);
  const double across = uphill - 90.0 * kDegToRad;
  const Expected<Drive> side = SimulateDrive(
      terrain, NoiselessSpec({{0.0, 0.0}, {5.0 * std::cos(across), 5.0 * std::sin(across)}}),
      SensorFrame::kLidar, 3);
  ASSERT_TRUE(side.ok());
  EXPECT_NEAR(side->samples[3].attitude.pitch_rad, 0.0, 1e-12);
  EXPECT_NEAR(side->samples[3].attitude.roll_rad, slope, 1e-12);
}

TEST(SimDrive, SensorPoseIsBodyTimesMount) {
  DriveSpec spec = NoiselessSpec(WindingPath());
  spec.T_body_sensor_xyz = {0.7, -0.2, 1.8};
  spec.sensor_pitch_rad = 0.2;
  const Terrain hills = Terrain::Hills(0.0, {{0.4, 15.0, 0.3, 0.0}, {0.2, 7.0, 2.0, 1.0}});
  for (SensorFrame frame : {SensorFrame::kCameraOptical, SensorFrame::kLidar}) {
    const Expected<Drive> drive = SimulateDrive(hills, spec, frame, 5);
    ASSERT_TRUE(drive.ok());
    const Eigen::Isometry3d mount = BodyToSensor(spec, frame);
    EXPECT_TRUE(mount.translation().isApprox(spec.T_body_sensor_xyz));
    // The sensor looks forward and down on the body: optical z or LiDAR x.
    const Eigen::Vector3d look = mount.linear().col(frame == SensorFrame::kCameraOptical ? 2 : 0);
    EXPECT_NEAR(look.x(), std::cos(0.2), 1e-12);
    EXPECT_NEAR(look.z(), -std::sin(0.2), 1e-12);
    for (const DriveSample& s : drive->samples) {
      EXPECT_TRUE(s.T_world_sensor.isApprox(s.T_world_body * mount, 1e-12));
      EXPECT_TRUE(s.T_world_body.linear().isUnitary(1e-12));
    }
  }
}

TEST(SimDrive, AttitudeRoundTrips) {
  for (double roll : {-2.5, -0.3, 0.0, 0.4, 3.0}) {
    for (double pitch : {-1.5, -0.2, 0.0, 0.7, 1.5}) {
      for (double yaw : {-3.1, -1.0, 0.0, 2.0, 3.1}) {
        const Attitude a = AttitudeFromRotation(RotationFromAttitude({roll, pitch, yaw}));
        EXPECT_NEAR(a.roll_rad, roll, 1e-9);
        EXPECT_NEAR(a.pitch_rad, pitch, 1e-9);
        EXPECT_NEAR(a.yaw_rad, yaw, 1e-9);
      }
    }
  }
}

TEST(SimDrive, OdometryIsExactWithZeroNoise) {
  const Terrain hills = Terrain::Hills(0.0, {{0.5, 10.0, 0.7, 0.0}});
  const Expected<Drive> drive =
      SimulateDrive(hills, NoiselessSpec(WindingPath()), SensorFrame::kCameraOptical, 11);
  ASSERT_TRUE(drive.ok());
  for (const DriveSample& s : drive->samples) {
    EXPECT_NEAR(Distance(s.odometry, s.true_planar), 0.0, 1e-9) << "frame " << s.index;
    EXPECT_NEAR(std::remainder(s.odometry.yaw_rad - s.true_planar.yaw_rad, 2 * kPi), 0.0, 1e-9);
    EXPECT_NEAR(s.imu.roll_rad, s.attitude.roll_rad, 1e-15);
    EXPECT_NEAR(s.imu.pitch_rad, s.attitude.pitch_rad, 1e-15);
  }
}

TEST(SimDrive, OdometryDriftGrowsWithDistance) {
  DriveSpec spec;
  spec.waypoints = WindingPath();
  spec.odom_sigma_per_m = 0.02;
  spec.odom_yaw_sigma_rad_per_m = 0.004;
  // Mean squared position error over many seeded drives, at a quarter, half and all of it.
  const int kSeeds = 40;
  double sq[3] = {0.0, 0.0, 0.0};
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const Expected<Drive> drive =
        SimulateDrive(Terrain::Flat(), spec, SensorFrame::kCameraOptical, seed);
    ASSERT_TRUE(drive.ok());
    const std::vector<DriveSample>& samples = drive->samples;
    EXPECT_EQ(Distance(samples[0].odometry, samples[0].true_planar), 0.0);
    const std::size_t n = samples.size() - 1;
    const std::size_t at[3] = {n / 4, n / 2, n};
    for (int i = 0; i < 3; ++i) {
      sq[i] += std::pow(Distance(samples[at[i]].odometry, samples[at[i]].true_planar), 2);
    }
  }
  EXPECT_GT(sq[0], 0.0);
  EXPECT_GT(sq[1], 1.5 * sq[0]);
  EXPECT_GT(sq[2], 1.5 * sq[1]);
  // At the end of ~55 m, a 2% per metre drift is metres, not millimetres nor kilometres.
  const double rms_end = std::sqrt(sq[2] / kSeeds);
  EXPECT_GT(rms_end, 0.3);
  EXPECT_LT(rms_end, 10.0);
}

TEST(SimDrive, ImuHasItsBiasAndNoise) {
  DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {400.0, 0.0}});
  spec.imu_sigma_rad = 0.01;
  spec.imu_bias_rad = 0.03;
  const Expected<Drive> drive =
      SimulateDrive(Terrain::Slope(0.0, 0.1, 1.0), spec, SensorFrame::kCameraOptical, 2);
  ASSERT_TRUE(drive.ok());
  double sum = 0.0, sum_sq = 0.0, yaw_sum = 0.0;
  int n = 0;
  for (const DriveSample& s : drive->samples) {
    const double e = s.imu.pitch_rad - s.attitude.pitch_rad;
    sum += e;
    sum_sq += e * e;
    yaw_sum += s.imu.yaw_rad - s.attitude.yaw_rad;
    ++n;
  }
  ASSERT_EQ(n, 2001);
  const double mean = sum / n, sigma = std::sqrt(sum_sq / n - mean * mean);
  EXPECT_NEAR(mean, 0.03, 4.0 * 0.01 / std::sqrt(n));
  EXPECT_NEAR(sigma, 0.01, 0.001);
  EXPECT_NEAR(yaw_sum / n, 0.0, 4.0 * 0.01 / std::sqrt(n));
  EXPECT_DOUBLE_EQ(drive->errors.imu_roll_bias_rad, 0.03);
}

TEST(SimDrive, SameSeedSameDriveOtherSeedOtherDrift) {
  DriveSpec spec;
  spec.waypoints = WindingPath();
  const Terrain hills = Terrain::Hills(0.0, {{0.3, 9.0, 0.2, 0.0}});
  const Expected<Drive> a = SimulateDrive(hills, spec, SensorFrame::kCameraOptical, 42);
  const Expected<Drive> b = SimulateDrive(hills, spec, SensorFrame::kCameraOptical, 42);
  const Expected<Drive> c = SimulateDrive(hills, spec, SensorFrame::kCameraOptical, 43);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  ASSERT_EQ(a->samples.size(), b->samples.size());
  for (std::size_t i = 0; i < a->samples.size(); ++i) {
    const DriveSample &x = a->samples[i], &y = b->samples[i];
    EXPECT_EQ(x.T_world_sensor.matrix(), y.T_world_sensor.matrix());
    EXPECT_EQ(x.odometry.x_m, y.odometry.x_m);
    EXPECT_EQ(x.odometry.yaw_rad, y.odometry.yaw_rad);
    EXPECT_EQ(x.imu.roll_rad, y.imu.roll_rad);
  }
  // Another seed changes the errors, never the truth.
  const DriveSample &x = a->samples.back(), &z = c->samples.back();
  EXPECT_EQ(x.T_world_body.matrix(), z.T_world_body.matrix());
  EXPECT_NE(x.odometry.x_m, z.odometry.x_m);
  EXPECT_NE(x.imu.pitch_rad, z.imu.pitch_rad);
}

TEST(SimDrive, BadSpecsNameTheField) {
  DriveSpec spec;
  spec.waypoints = {{1.0, 1.0}, {1.0, 1.0}};
  Expected<Drive> drive = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_FALSE(drive.ok());
  EXPECT_NE(drive.error().message.find("drive.waypoints"), std::string::npos);
  EXPECT_EQ(DriveFrameCount(spec), 0);

  spec.waypoints = {{0.0, 0.0}, {1.0, 1.0}};
  spec.speed_mps = 0.0;
  drive = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_FALSE(drive.ok());
  EXPECT_NE(drive.error().message.find("drive.speed_mps"), std::string::npos);

  spec.speed_mps = 1.0;
  spec.odom_sigma_per_m = -0.1;
  drive = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_FALSE(drive.ok());
  EXPECT_NE(drive.error().message.find("drive.odom_sigma_per_m"), std::string::npos);
}

// ---- raw IMU ------------------------------------------------------------------------------

ImuSpec NoiselessImu() {
  ImuSpec imu;
  imu.accel_sigma_mps2 = 0.0;
  imu.gyro_sigma_radps = 0.0;
  return imu;
}

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle == 0.0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

TEST(SimImu, AtRestOnASlopeTheAccelerometerReadsGravityRotatedBySlope) {
  const Attitude attitude{0.2, -0.3, 1.1};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = RotationFromAttitude(attitude);
  T.translation() << 3.0, -2.0, 1.0;
  const ImuReading r = IdealImuReading([&](double) { return T; }, 5.0, 0.01);
  const Eigen::Vector3d expected =
      kGravityMps2 * T.linear().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR((r.specific_force_mps2 - expected).norm(), 0.0, 1e-9);
  EXPECT_NEAR(r.angular_rate_radps.norm(), 0.0, 1e-12);
  // Roll alone: the left side up puts gravity's reaction on +y... in the body, up is
  // (0, sin roll, cos roll) for roll > 0.
  EXPECT_NEAR(expected.y() / kGravityMps2, std::sin(0.2) * std::cos(-0.3), 1e-12);

  // Driving straight up a 15 deg slope at constant speed: no acceleration, the nose-up
  // accelerometer reads g (sin 15, 0, cos 15) at every sample.
  const double slope = 15.0 * kDegToRad;
  const Expected<Drive> drive = SimulateDrive(Terrain::Slope(0.0, slope, 0.0),
                                              NoiselessSpec({{0.0, 0.0}, {10.0, 0.0}}),
                                              SensorFrame::kLidar, 3, 0, NoiselessImu());
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  ASSERT_EQ(drive->imu.size(), 500u);  // 5 s at 100 Hz
  for (const ImuReading& reading : drive->imu) {
    const Eigen::Vector3d f(std::sin(slope), 0.0, std::cos(slope));
    EXPECT_NEAR((reading.specific_force_mps2 - kGravityMps2 * f).norm(), 0.0, 1e-6);
    EXPECT_NEAR(reading.angular_rate_radps.norm(), 0.0, 1e-9);
  }
}

TEST(SimImu, AConstantRateTurnGivesTheCentripetalTerm) {
  const double radius = 10.0, speed = 3.0, rate = speed / radius;
  auto pose = [&](double t) {
    const double a = rate * t;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << radius * std::cos(a), radius * std::sin(a), 0.0;
    T.linear() = Eigen::AngleAxisd(a + 0.5 * kPi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
  };
  for (double t : {0.0, 1.3, 7.7}) {
    const ImuReading r = IdealImuReading(pose, t, 0.01);
    // Left turn: the accelerometer reads v omega towards the centre (body +y).
    EXPECT_NEAR(r.specific_force_mps2.x(), 0.0, 1e-6);
    EXPECT_NEAR(r.specific_force_mps2.y(), speed * rate, 1e-5);
    EXPECT_NEAR(r.specific_force_mps2.z(), kGravityMps2, 1e-9);
    EXPECT_NEAR((r.angular_rate_radps - Eigen::Vector3d(0.0, 0.0, rate)).norm(), 0.0, 1e-9);
  }
}

TEST(SimImu, TheGyroIntegratesToTheTrueRotationBetweenFrames) {
  const Terrain terrain = Terrain::Hills(0.0, {{0.3, 9.0, 0.4}, {0.2, 5.0, 1.9}});
  const Expected<Drive> drive = SimulateDrive(terrain, NoiselessSpec(WindingPath()),
                                              SensorFrame::kLidar, 5, 0, NoiselessImu());
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  // 10 Hz frames, 100 Hz IMU: the samples of frame k..k+1 are 10k .. 10k+9.
  ASSERT_GE(drive->imu.size(), 10 * (drive->samples.size() - 1));
  double largest_turn = 0.0;
  for (std::size_t k = 0; k + 5 < drive->samples.size(); k += 5) {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    for (std::size_t j = 10 * k; j < 10 * (k + 5); ++j) {
      R = R * ExpSO3(drive->imu[j].angular_rate_radps * 0.01);
    }
    const Eigen::Matrix3d truth = drive->samples[k].T_world_body.linear().transpose() *
                                  drive->samples[k + 5].T_world_body.linear();
    EXPECT_NEAR((R - truth).norm(), 0.0, 1e-9) << "frame " << k;
    const double heading = std::remainder(
        drive->samples[k + 5].attitude.yaw_rad - drive->samples[k].attitude.yaw_rad, 2 * kPi);
    largest_turn = std::max(largest_turn, std::abs(heading));
  }
  EXPECT_GT(largest_turn, 20.0 * kDegToRad);  // the path turns
}

// A right-angle corner rounded by a 5 m arc: the path is 2 r - r pi / 2 shorter than the
// polyline; in the arc the accelerometer reads v^2 / r towards the centre and the gyro v / r,
// on the straight parts neither; the heading never jumps. Sharp, the corner is a velocity
// jump: one sample reads (nearly) v sqrt(2) / dt.
TEST(SimImu, ARoundedCornerTurnsOnAnArcOfTheTurnRadius) {
  const double radius = 5.0, speed = 2.0;
  DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {20.0, 0.0}, {20.0, 20.0}});
  spec.speed_mps = speed;
  spec.turn_radius_m = radius;
  const Expected<Drive> drive =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 3, 0, NoiselessImu());
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  EXPECT_NEAR(drive->path_length_m, 40.0 - 2.0 * radius + radius * 0.5 * kPi, 1e-9);
  // The arc runs from (15, 0) to (20, 5) around (15, 5): it starts 15 m along the path. The
  // body's heading is the chord between its axles: more than half a wheelbase from the arc's
  // ends, body and path turn alike.
  const double arc_begin = 15.0, arc_end = 15.0 + radius * 0.5 * kPi;
  const double margin = 0.5 * spec.wheelbase_m + 0.05;
  int in_arc = 0, straight = 0;
  for (const ImuReading& r : drive->imu) {
    const double s = speed * r.stamp_s;
    if (s > arc_begin + margin && s < arc_end - margin) {
      ++in_arc;
      EXPECT_NEAR(r.specific_force_mps2.y(), speed * speed / radius, 2e-3) << s;
      EXPECT_NEAR(r.angular_rate_radps.z(), speed / radius, 1e-3) << s;
    } else if (s < arc_begin - margin || s > arc_end + margin) {
      ++straight;
      EXPECT_NEAR(r.specific_force_mps2.head<2>().norm(), 0.0, 1e-6) << s;
      EXPECT_NEAR(r.angular_rate_radps.norm(), 0.0, 1e-9) << s;
    }
    EXPECT_LT(r.specific_force_mps2.head<2>().norm(), 2.0 * speed * speed / radius) << s;
  }
  EXPECT_GT(in_arc, 100);
  EXPECT_GT(straight, 1000);
  for (std::size_t k = 1; k < drive->samples.size(); ++k) {
    const double turn = std::abs(std::remainder(
        drive->samples[k].attitude.yaw_rad - drive->samples[k - 1].attitude.yaw_rad, 2.0 * kPi));
    EXPECT_LE(turn, speed / spec.frame_rate_hz / radius + 1e-9) << k;
  }
  // The same corner sharp: the velocity turns within one sample.
  spec.turn_radius_m = 0.0;
  const Expected<Drive> sharp =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 3, 0, NoiselessImu());
  ASSERT_TRUE(sharp.ok()) << sharp.error().message;
  EXPECT_DOUBLE_EQ(sharp->path_length_m, 40.0);
  double largest = 0.0;
  for (const ImuReading& r : sharp->imu) {
    largest = std::max(largest, r.specific_force_mps2.head<2>().norm());
  }
  EXPECT_GT(largest, 50.0);

  // A right turn and a left one, each beside a 3 m segment: their arcs take half of it (a
  // tangent of 1.5 m, so a radius of 1.5 m at 90 deg), and the gyro turns the other way.
  spec.waypoints = {{0.0, 0.0}, {20.0, 0.0}, {20.0, -3.0}, {40.0, -3.0}};
  spec.turn_radius_m = radius;
  const Expected<Drive> clipped =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 3, 0, NoiselessImu());
  ASSERT_TRUE(clipped.ok()) << clipped.error().message;
  EXPECT_NEAR(clipped->path_length_m, 43.0 - 4.0 * 1.5 + 1.5 * kPi, 1e-9);
  // The right arc runs from 18.5 m along the path for 1.5 pi / 2 m; more than half a
  // wheelbase inside it the body turns right at v / 1.5 with v^2 / 1.5 towards the centre.
  int mid_arc = 0;
  for (const ImuReading& r : clipped->imu) {
    const double s = speed * r.stamp_s;
    if (s < 18.5 + margin || s > 18.5 + 0.75 * kPi - margin) continue;
    ++mid_arc;
    EXPECT_NEAR(r.angular_rate_radps.z(), -speed / 1.5, 1e-3) << s;
    EXPECT_NEAR(r.specific_force_mps2.y(), -speed * speed / 1.5, 5e-3) << s;
  }
  EXPECT_GT(mid_arc, 20);

  spec.turn_radius_m = -1.0;
  const Expected<Drive> bad = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 3);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("drive.turn_radius_m"), std::string::npos);
}

TEST(SimImu, ASpeedWaveGivesTheAlongTrackAcceleration) {
  DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {40.0, 0.0}});
  spec.speed_mps = 2.0;
  spec.speed_wave_mps = 0.8;
  spec.speed_wave_period_s = 4.0;
  const Expected<Drive> drive =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 3, 0, NoiselessImu());
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  const double w = 2.0 * kPi / spec.speed_wave_period_s;
  for (std::size_t j = 0; j < drive->imu.size(); j += 37) {
    const ImuReading& r = drive->imu[j];
    EXPECT_NEAR(r.specific_force_mps2.x(), spec.speed_wave_mps * w * std::cos(w * r.stamp_s),
                1e-4);
    EXPECT_NEAR(r.specific_force_mps2.z(), kGravityMps2, 1e-9);
  }
  // Distance is the integral of the speed, and the drive takes as long as it must.
  const DriveSample& last = drive->samples.back();
  EXPECT_NEAR(last.distance_m,
              2.0 * last.stamp_s + 0.8 / w * (1.0 - std::cos(w * last.stamp_s)), 1e-9);
  EXPECT_LE(last.distance_m, 40.0);
  EXPECT_GT(last.distance_m, 40.0 - (2.0 + 0.8) / spec.frame_rate_hz);
}

TEST(SimImu, EachErrorSourceIsSeparate) {
  const DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {30.0, 0.0}});
  const Expected<Drive> ideal =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 9, 0, NoiselessImu());
  ImuSpec imu = NoiselessImu();
  imu.accel_bias_mps2 << 0.05, -0.03, 0.1;
  imu.gyro_bias_radps << 0.001, 0.002, -0.003;
  const Expected<Drive> biased =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 9, 0, imu);
  imu = NoiselessImu();
  imu.accel_sigma_mps2 = 0.05;
  imu.gyro_sigma_radps = 0.01;
  const Expected<Drive> noisy =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 9, 0, imu);
  imu = NoiselessImu();
  imu.misalignment_rad << 2.5 * kDegToRad, -1.0 * kDegToRad, 0.0;
  const Expected<Drive> tilted =
      SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 9, 0, imu);
  ASSERT_TRUE(ideal.ok() && biased.ok() && noisy.ok() && tilted.ok());
  const std::size_t n = ideal->imu.size();
  ASSERT_EQ(n, 1500u);
  double sum_sq_f = 0.0, sum_sq_w = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    const ImuReading &a = ideal->imu[j], &b = biased->imu[j], &c = noisy->imu[j];
    EXPECT_NEAR((b.specific_force_mps2 - a.specific_force_mps2 -
                 Eigen::Vector3d(0.05, -0.03, 0.1)).norm(), 0.0, 1e-12);
    EXPECT_NEAR((b.angular_rate_radps - a.angular_rate_radps -
                 Eigen::Vector3d(0.001, 0.002, -0.003)).norm(), 0.0, 1e-12);
    sum_sq_f += (c.specific_force_mps2 - a.specific_force_mps2).squaredNorm();
    sum_sq_w += (c.angular_rate_radps - a.angular_rate_radps).squaredNorm();
    // A misaligned IMU reads gravity in its own frame.
    const Eigen::Vector3d up_imu = tilted->R_body_imu.transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_NEAR((tilted->imu[j].specific_force_mps2 - kGravityMps2 * up_imu).norm(), 0.0, 1e-6);
  }
  EXPECT_NEAR(std::sqrt(sum_sq_f / (3.0 * n)), 0.05, 0.003);
  EXPECT_NEAR(std::sqrt(sum_sq_w / (3.0 * n)), 0.01, 0.0006);
  // Its attitude output is its own frame's; the frames, odometry and body are untouched.
  EXPECT_NEAR(tilted->samples[4].imu.roll_rad, 2.5 * kDegToRad, 1e-9);
  EXPECT_NEAR(tilted->samples[4].imu.pitch_rad, -1.0 * kDegToRad, 1e-9);
  for (std::size_t k = 0; k < ideal->samples.size(); ++k) {
    for (const Drive* d : {&*biased, &*noisy, &*tilted}) {
      EXPECT_TRUE(d->samples[k].T_world_sensor.isApprox(ideal->samples[k].T_world_sensor, 0.0));
      EXPECT_EQ(d->samples[k].odometry.x_m, ideal->samples[k].odometry.x_m);
    }
  }
}

TEST(SimImu, ASensorMisalignmentMovesTheTrueSensorPoseOnly) {
  DriveSpec spec = NoiselessSpec({{0.0, 0.0}, {10.0, 0.0}});
  spec.sensor_misalignment_rad << 0.0, 2.5 * kDegToRad, 0.0;
  const Expected<Drive> drive = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_TRUE(drive.ok()) << drive.error().message;
  EXPECT_TRUE(drive->T_body_sensor.isApprox(BodyToSensor(spec, SensorFrame::kLidar)));
  const Eigen::Matrix3d extra =
      drive->T_body_sensor.linear().transpose() * drive->T_body_sensor_true.linear();
  EXPECT_NEAR(Eigen::AngleAxisd(extra).angle(), 2.5 * kDegToRad, 1e-12);
  const DriveSample& s = drive->samples[3];
  EXPECT_TRUE(s.T_world_sensor.isApprox(s.T_world_body * drive->T_body_sensor_true, 1e-12));
  spec.speed_wave_mps = 3.0;  // faster than the speed: the vehicle would back up
  const Expected<Drive> bad = SimulateDrive(Terrain::Flat(), spec, SensorFrame::kLidar, 1);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("speed_wave_mps"), std::string::npos);
  ImuSpec imu;
  imu.rate_hz = 0.0;
  const Expected<Drive> bad_imu =
      SimulateDrive(Terrain::Flat(), NoiselessSpec({{0.0, 0.0}, {10.0, 0.0}}),
                    SensorFrame::kLidar, 1, 0, imu);
  ASSERT_FALSE(bad_imu.ok());
  EXPECT_NE(bad_imu.error().message.find("imu.rate_hz"), std::string::npos);
}

}  // namespace
}  // namespace cairn::sim
