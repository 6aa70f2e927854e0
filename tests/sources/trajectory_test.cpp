// Trajectory: interpolation against analytic motions, the IMU's tilt, the height climbed,
// the limits of the time span, and poses from real files (an MRPT sensory-frame rawlog with
// 3-D actions, a KITTI sequence, TUM files).
#include "cairn/sources/trajectory.hpp"

#include <gtest/gtest.h>
#include <mrpt/math/slerp.h>
#include <mrpt/poses/CPose3D.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "cairn/sources/rawlog_source.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;
Eigen::Isometry3d Planar(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() << x, y, 0.0;
  return T;
}

double YawOf(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

/// A circle of radius r driven anticlockwise at speed v from (r, 0) heading +y, sampled at
/// `rate_hz`, stamps from t0.
struct Circle {
  double r = 5.0, v = 2.0, t0 = 1000.0;
  double omega() const { return v / r; }
  Eigen::Isometry3d At(double t) const {
    const double a = omega() * (t - t0);
    return Planar(r * std::cos(a), r * std::sin(a), a + kPi / 2);
  }
  std::vector<OdometrySample> Samples(double rate_hz, double duration_s) const {
    std::vector<OdometrySample> out;
    const int n = static_cast<int>(std::round(duration_s * rate_hz));
    for (int k = 0; k <= n; ++k) {
      const double t = t0 + k / rate_hz;
      out.push_back({t, At(t), "ODOMETRY"});
    }
    return out;
  }
};

TEST(Trajectory, LinearInterpolationOnACircleStaysWithinTheChordError) {
  const Circle circle;
  const double rate_hz = 10.0;
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(circle.Samples(rate_hz, 20.0), {});
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  // Between samples dtheta apart, the chord lies at most r (1 - cos(dtheta / 2)) inside the
  // arc, and the heading (a rotation about z, slerped) is exact.
  const double dtheta = circle.omega() / rate_hz;
  const double chord_error = circle.r * (1.0 - std::cos(dtheta / 2));
  double worst = 0.0;
  for (double t = circle.t0; t <= circle.t0 + 20.0; t += 0.0137) {
    Expected<BodyPose> pose = trajectory->PoseAt(t);
    ASSERT_TRUE(pose) << pose.error().message;
    const Eigen::Isometry3d truth = circle.At(t);
    const double error = (pose->T_world_body.translation() - truth.translation()).norm();
    worst = std::max(worst, error);
    EXPECT_LE(error, chord_error + 1e-6) << "t = " << t;
    EXPECT_NEAR(std::remainder(YawOf(pose->T_world_body.linear()) - YawOf(truth.linear()), 2 * kPi),
                0.0, 1e-6);
    EXPECT_FALSE(pose->tilt_from_imu);
    EXPECT_EQ(pose->extrapolated_s, 0.0);
  }
  // The bound is reached half-way between samples: the test sees the real error.
  EXPECT_GT(worst, 0.9 * chord_error);
  // At the samples themselves the pose is the sample's.
  Expected<BodyPose> at_sample = trajectory->PoseAt(circle.t0 + 3.0);
  ASSERT_TRUE(at_sample);
  EXPECT_LT(
      (at_sample->T_world_body.translation() - circle.At(circle.t0 + 3.0).translation()).norm(),
      1e-6);
  // 20 s at 2 m/s: 40 m of chords, each slightly shorter than its arc.
  EXPECT_NEAR(trajectory->PathLength(), 40.0, 0.01);
}

// The trajectory interpolates without MRPT, as MRPT's CPose3DInterpolator with imLinearSlerp
// did before: position linear, rotation by MRPT's slerp, the reference here (random 3-D poses
// up to 170 deg apart, uneven stamps, queried between and at the samples). The fraction is
// the same in both; MRPT's interpolator itself rounds the time on its clock, which counts
// from 1601 (about 1e-6 s as a double), so it is not the reference.
TEST(Trajectory, InterpolatesAsMrptsSlerp) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::vector<StampedPose> poses;
  double t = 1.7e9;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  for (int k = 0; k < 60; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = 20.0 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
    q = q * Eigen::Quaterniond(Eigen::AngleAxisd(2.97 * std::abs(unit(rng)), axis));
    T.linear() = q.normalized().toRotationMatrix();
    poses.push_back({t, T});
    t += 0.05 + 0.5 * std::abs(unit(rng));
  }
  Expected<Trajectory> trajectory = Trajectory::FromPoses(poses, "random");
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  int checked = 0;
  for (std::size_t k = 0; k + 1 < poses.size(); ++k) {
    const StampedPose& a = poses[k];
    const StampedPose& b = poses[k + 1];
    for (const double f : {0.0, 0.125, 0.5, 0.7, 0.999}) {
      const double s = a.stamp_s + f * (b.stamp_s - a.stamp_s);
      Expected<BodyPose> ours = trajectory->PoseAt(s);
      ASSERT_TRUE(ours) << ours.error().message;
      ::mrpt::math::TPose3D theirs;
      ::mrpt::math::slerp(ToCPose3D(a.T_world_x).asTPose(), ToCPose3D(b.T_world_x).asTPose(),
                          (s - a.stamp_s) / (b.stamp_s - a.stamp_s), theirs);
      const Eigen::Isometry3d T = FromCPose3D(::mrpt::poses::CPose3D(theirs));
      EXPECT_LT((ours->T_world_body.translation() - T.translation()).norm(), 1e-9) << k << " " << f;
      EXPECT_LT(Eigen::AngleAxisd(ours->T_world_body.linear().transpose() * T.linear()).angle(),
                1e-8)
          << k << " " << f;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 59 * 5);
}

TEST(Trajectory, ExtrapolatesAtConstantVelocityUpToTheLimitThenNamesTheFrame) {
  // A straight line along y = x at 1.5 m/s.
  std::vector<OdometrySample> samples;
  for (int k = 0; k <= 10; ++k) {
    const double d = 0.15 * k;
    samples.push_back(
        {100.0 + 0.1 * k, Planar(d / std::sqrt(2.0), d / std::sqrt(2.0), kPi / 4), "ODOMETRY"});
  }
  TrajectoryOptions options;
  options.max_extrapolation_s = 0.25;
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(samples, {}, options);
  ASSERT_TRUE(trajectory) << trajectory.error().message;

  Expected<BodyPose> ahead = trajectory->PoseAt(101.2);  // 0.2 s after the last sample
  ASSERT_TRUE(ahead) << ahead.error().message;
  EXPECT_NEAR(ahead->extrapolated_s, 0.2, 1e-9);
  const double d = 1.5 + 1.5 * 0.2;
  EXPECT_NEAR(ahead->T_world_body.translation().x(), d / std::sqrt(2.0), 1e-9);
  EXPECT_NEAR(ahead->T_world_body.translation().y(), d / std::sqrt(2.0), 1e-9);
  Expected<BodyPose> behind = trajectory->PoseAt(99.9);
  ASSERT_TRUE(behind);
  EXPECT_NEAR(behind->T_world_body.translation().x(), -0.15 / std::sqrt(2.0), 1e-9);

  Frame frame;
  frame.index = 7;
  frame.label = "CAMERA";
  frame.entry = 31;
  frame.stamp_s = 101.5;  // 0.5 s after the end
  Expected<Eigen::Isometry3d> late = trajectory->T_world_sensor(frame);
  ASSERT_FALSE(late);
  EXPECT_NE(late.error().message.find("frame 7 ('CAMERA', entry 31)"), std::string::npos)
      << late.error().message;
  EXPECT_NE(late.error().message.find("after"), std::string::npos);
  EXPECT_NE(late.error().message.find("limit 0.250 s"), std::string::npos);
  frame.stamp_s = std::nan("");
  EXPECT_FALSE(trajectory->T_world_sensor(frame));
}

TEST(Trajectory, RefusesStampsInAGapOfTheOdometry) {
  std::vector<OdometrySample> samples = {
      {0.0, Planar(0, 0, 0), "O"}, {0.1, Planar(0.1, 0, 0), "O"}, {5.0, Planar(5.0, 0, 0), "O"}};
  TrajectoryOptions options;
  options.max_gap_s = 1.0;
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(samples, {}, options);
  ASSERT_TRUE(trajectory);
  EXPECT_TRUE(trajectory->PoseAt(0.05));
  Expected<BodyPose> in_gap = trajectory->PoseAt(2.0);
  ASSERT_FALSE(in_gap);
  EXPECT_NE(in_gap.error().message.find("gap of 4.900 s"), std::string::npos)
      << in_gap.error().message;
  options.max_gap_s = 0.0;  // no limit: interpolated across
  Expected<Trajectory> unlimited = Trajectory::FromOdometry(samples, {}, options);
  ASSERT_TRUE(unlimited);
  Expected<BodyPose> across = unlimited->PoseAt(2.0);
  ASSERT_TRUE(across);
  EXPECT_NEAR(across->T_world_body.translation().x(), 2.0, 1e-6);  // MRPT's 100 ns clock
}

TEST(Trajectory, ImuRollAndPitchReplaceThePlanarOdometrysTilt) {
  const Circle circle;
  std::vector<ImuAttitude> imu;
  for (int k = 0; k <= 50; ++k) {
    ImuAttitude a;
    a.stamp_s = circle.t0 + 0.2 * k;
    a.roll_rad = 0.05 + 0.001 * k;
    a.pitch_rad = -0.1;
    a.yaw_rad = 2.0;  // a magnetic heading: must not be used
    a.label = "IMU";
    imu.push_back(a);
  }
  TrajectoryOptions options;
  options.height_from_imu = false;
  Expected<Trajectory> trajectory =
      Trajectory::FromOdometry(circle.Samples(10.0, 10.0), imu, options);
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  const double t = circle.t0 + 3.1;  // between IMU samples 15 and 16
  Expected<BodyPose> pose = trajectory->PoseAt(t);
  ASSERT_TRUE(pose);
  EXPECT_TRUE(pose->tilt_from_imu);
  const double roll = 0.05 + 0.001 * 15.5;
  const Eigen::Matrix3d expected =
      (Eigen::AngleAxisd(YawOf(circle.At(t).linear()), Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  EXPECT_LT((pose->T_world_body.linear() - expected).norm(), 1e-6);

  // The frame's sensor pose composes the body's with the mount.
  Frame frame;
  frame.stamp_s = t;
  frame.T_body_sensor.translation() << 0.5, 0.0, 1.5;
  frame.T_body_sensor.linear() =
      Eigen::AngleAxisd(0.14, Eigen::Vector3d::UnitY()).toRotationMatrix();
  Expected<Eigen::Isometry3d> T_world_sensor = trajectory->T_world_sensor(frame);
  ASSERT_TRUE(T_world_sensor);
  EXPECT_LT(((pose->T_world_body * frame.T_body_sensor).matrix() - T_world_sensor->matrix()).norm(),
            1e-12);

  // Beyond the IMU's last sample by more than max_imu_age_s: the odometry's (level) tilt.
  options.max_imu_age_s = 0.1;
  std::vector<ImuAttitude> early(imu.begin(), imu.begin() + 10);  // up to t0 + 1.8 s
  Expected<Trajectory> partial =
      Trajectory::FromOdometry(circle.Samples(10.0, 10.0), early, options);
  ASSERT_TRUE(partial);
  Expected<BodyPose> level = partial->PoseAt(circle.t0 + 5.0);
  ASSERT_TRUE(level);
  EXPECT_FALSE(level->tilt_from_imu);
  EXPECT_NEAR(level->T_world_body.linear()(2, 2), 1.0, 1e-12);
}

TEST(Trajectory, PlanarOdometryClimbsWithTheImuPitch) {
  // 20 m along heading 30 deg at 1 m/s up a 10% grade: nose up, pitch = -atan(0.1).
  const double heading = kPi / 6;
  std::vector<OdometrySample> odometry;
  std::vector<ImuAttitude> imu;
  for (int k = 0; k <= 200; ++k) {
    const double d = 0.1 * k;
    odometry.push_back(
        {0.1 * k, Planar(d * std::cos(heading), d * std::sin(heading), heading), "ODOMETRY"});
    ImuAttitude a;
    a.stamp_s = 0.1 * k;
    a.pitch_rad = -std::atan(0.1);
    imu.push_back(a);
  }
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(odometry, imu);
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  Expected<BodyPose> end = trajectory->PoseAt(20.0);
  ASSERT_TRUE(end);
  EXPECT_NEAR(end->T_world_body.translation().z(), 2.0, 1e-9);
  Expected<BodyPose> mid = trajectory->PoseAt(10.05);
  ASSERT_TRUE(mid);
  EXPECT_NEAR(mid->T_world_body.translation().z(), 1.005, 1e-6);
  EXPECT_NEAR(trajectory->PathLength(), 20.0 * std::sqrt(1.01), 1e-9);
  // Reversing down the same grade loses height: the step counts along the heading.
  for (OdometrySample& s : odometry) {
    s.T_odom_body.translation() = -s.T_odom_body.translation();
  }
  Expected<Trajectory> reversing = Trajectory::FromOdometry(odometry, imu);
  ASSERT_TRUE(reversing);
  EXPECT_NEAR(reversing->PoseAt(20.0)->T_world_body.translation().z(), -2.0, 1e-9);
  // Without the option, planar odometry stays at its height.
  TrajectoryOptions options;
  options.height_from_imu = false;
  Expected<Trajectory> flat = Trajectory::FromOdometry(odometry, imu, options);
  ASSERT_TRUE(flat);
  EXPECT_NEAR(flat->PoseAt(20.0)->T_world_body.translation().z(), 0.0, 1e-12);
}

TEST(Trajectory, RejectsSamplesWithoutStampsAndEmptyInput) {
  EXPECT_FALSE(Trajectory::FromOdometry({}, {}));
  Expected<Trajectory> no_stamp =
      Trajectory::FromOdometry({{0.0, Planar(0, 0, 0), "O"}, {kNoStamp, Planar(1, 0, 0), "O"}}, {});
  ASSERT_FALSE(no_stamp);
  EXPECT_NE(no_stamp.error().message.find("odometry sample 1"), std::string::npos);
  TrajectoryOptions bad;
  bad.max_gap_s = -1.0;
  Expected<Trajectory> t = Trajectory::FromOdometry({{0.0, Planar(0, 0, 0), "O"}}, {}, bad);
  ASSERT_FALSE(t);
  EXPECT_NE(t.error().message.find("max_gap_s"), std::string::npos);
}

TEST(Trajectory, SensoryFrameRawlogWith3DActionsGivesAPlausiblePath) {
  // MRPT's 6-D Kalman SLAM demo: a robot moving in 3-D, odometry as CActionRobotMovement3D
  // between sensory frames; its ground truth path (600 poses) is 119 m long.
  const fs::path rawlog = "/usr/share/mrpt/datasets/kf-slam_6D_demo.rawlog";
  if (!fs::exists(rawlog)) GTEST_SKIP() << rawlog << " absent (Debian package mrpt-common)";
  SourceOptions options;
  options.decode_frames = false;
  Expected<RawlogSource> source = RawlogSource::Open(rawlog, options);
  ASSERT_TRUE(source) << source.error().message;
  while (true) {
    Expected<std::optional<SourceEntry>> entry = source->NextEntry();
    ASSERT_TRUE(entry) << entry.error().message;
    if (!*entry) break;
  }
  const std::vector<OdometrySample>& odometry = source->odometry();
  ASSERT_GT(odometry.size(), 100u);
  EXPECT_EQ(odometry.back().source, "CActionRobotMovement3D");
  Expected<Trajectory> trajectory = Trajectory::FromOdometry(odometry, {});
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  // Odometry with noise, over the same path: within 10% of the truth's length.
  EXPECT_NEAR(trajectory->PathLength(), 119.0, 12.0);
  // It moves in 3-D: some height changes.
  double z_min = 1e9, z_max = -1e9;
  for (const StampedPose& p : trajectory->samples()) {
    z_min = std::min(z_min, p.T_world_x.translation().z());
    z_max = std::max(z_max, p.T_world_x.translation().z());
  }
  EXPECT_GT(z_max - z_min, 0.1);
  // Interpolated half-way between two samples: the midpoint of their positions.
  const StampedPose& a = trajectory->samples()[40];
  const StampedPose& b = trajectory->samples()[41];
  Expected<BodyPose> mid = trajectory->PoseAt(0.5 * (a.stamp_s + b.stamp_s));
  ASSERT_TRUE(mid) << mid.error().message;
  EXPECT_LT((mid->T_world_body.translation() -
             0.5 * (a.T_world_x.translation() + b.T_world_x.translation()))
                .norm(),
            1e-4);
}

TEST(Trajectory, ReadsTumFilesAndNamesTheBadLine) {
  const fs::path dir = fs::temp_directory_path() /
                       ("cairn_trajectory_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path good = dir / "good.tum";
  {
    std::ofstream out(good);
    out << "# timestamp tx ty tz qx qy qz qw\n"
        << "10.0 0 0 0 0 0 0 1\n"
        << "\n"
        << "11.0 2 0 0 0 0 0.7071067811865476 0.7071067811865476\n";
  }
  Expected<Trajectory> trajectory = ReadTumTrajectory(good);
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  Expected<BodyPose> mid = trajectory->PoseAt(10.5);
  ASSERT_TRUE(mid);
  EXPECT_NEAR(mid->T_world_body.translation().x(), 1.0, 1e-9);
  EXPECT_NEAR(YawOf(mid->T_world_body.linear()), kPi / 4, 1e-6);

  const fs::path bad = dir / "bad.tum";
  {
    std::ofstream out(bad);
    out << "10.0 0 0 0 0 0 0 1\n10.5 1 2 3 0 0 0\n";
  }
  Expected<Trajectory> broken = ReadTumTrajectory(bad);
  ASSERT_FALSE(broken);
  EXPECT_NE(broken.error().message.find("bad.tum:2:"), std::string::npos) << broken.error().message;
  const fs::path backwards = dir / "backwards.tum";
  {
    std::ofstream out(backwards);
    out << "10.0 0 0 0 0 0 0 1\n9.0 1 2 3 0 0 0 1\n";
  }
  Expected<Trajectory> back = ReadTumTrajectory(backwards);
  ASSERT_FALSE(back);
  EXPECT_NE(back.error().message.find("backwards.tum:2:"), std::string::npos);
  EXPECT_FALSE(ReadTumTrajectory(dir / "missing.tum"));
  fs::remove_all(dir);
}

TEST(Trajectory, KittiPosesPlaceTheVelodyneInAZUpMap) {
  const fs::path folder = fs::path(CAIRN_SHARED_DATASETS) / "kitti-seq00-0-10";
  if (!fs::exists(folder)) GTEST_SKIP() << folder << " absent: see ../shared/datasets/README.md";
  Expected<od::io::KittiSequence> sequence = od::io::OpenKittiSequence(folder);
  ASSERT_TRUE(sequence) << sequence.error().message;
  Expected<Trajectory> trajectory = Trajectory::FromKitti(*sequence);
  ASSERT_TRUE(trajectory) << trajectory.error().message;
  ASSERT_EQ(trajectory->samples().size(), 11u);
  // Frame 0's velodyne is the map's origin; the car drives forward (+x) on level road:
  // 10 steps of 0.86 m (the official poses, see the data set's README), little height.
  const Eigen::Isometry3d& first = trajectory->samples().front().T_world_x;
  EXPECT_LT((first.matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-3);
  const Eigen::Vector3d last = trajectory->samples().back().T_world_x.translation();
  EXPECT_GT(last.x(), 7.5);
  EXPECT_LT(std::abs(last.y()), 1.0);
  EXPECT_LT(std::abs(last.z()), 0.3);
  EXPECT_NEAR(trajectory->PathLength(), 8.6, 0.5);
}

}  // namespace
}  // namespace cairn::sources
