// The ASL folder reader (cairn::sources) on EuRoC V1_01 and on broken copies, and the
// gravity estimator's IMU terms alone on its 145 s of flight against the ground truth.
#include "cairn/eval/euroc_gravity.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "cairn/sources/asl_dataset.hpp"

namespace cairn {
namespace {

namespace fs = std::filesystem;

const fs::path kEuroc = fs::path(CAIRN_SHARED_DATASETS) / "euroc-v101-start";

bool HaveEuroc() { return fs::is_regular_file(kEuroc / "mav0" / "imu0" / "data.csv"); }

TEST(AslDataset, ReadsTheEurocFolder) {
  if (!HaveEuroc()) GTEST_SKIP() << kEuroc << " is absent (the shared EuRoC V1_01 start)";
  Expected<sources::AslDataset> data = sources::ReadAslDataset(kEuroc / "mav0");
  ASSERT_TRUE(data.ok()) << data.error().message;
  // As SOURCE.md describes it: 29,120 IMU rows at 200 Hz over 145.6 s; two cameras.
  EXPECT_EQ(data->imu.samples.size(), 29120u);
  EXPECT_EQ(data->imu.rate_hz, 200.0);
  EXPECT_EQ(data->imu.samples.front().stamp_ns, 1403715273262142976LL);
  EXPECT_NEAR(data->imu.samples.back().stamp_s - data->imu.samples.front().stamp_s, 145.6, 0.05);
  EXPECT_TRUE(data->imu.T_body_imu.isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_NEAR(data->imu.accel_noise_density, 2.0e-3, 1e-12);
  ASSERT_EQ(data->cameras.size(), 2u);
  const sources::AslCamera& cam0 = data->cameras[0];
  EXPECT_EQ(cam0.images.size(), 95u);
  EXPECT_EQ(std::count_if(cam0.images.begin(), cam0.images.end(),
                          [](const sources::AslImage& i) { return i.exists; }),
            20);
  EXPECT_DOUBLE_EQ(cam0.fx, 458.654);
  EXPECT_EQ(cam0.width, 752);
  EXPECT_EQ(cam0.distortion.size(), 4u);
  // The baseline between the camera centres is 0.110 m.
  const double baseline =
      (data->cameras[1].T_body_camera.translation() - cam0.T_body_camera.translation()).norm();
  EXPECT_NEAR(baseline, 0.110, 0.001);

  Expected<std::vector<sources::AslGroundTruth>> truth = sources::ReadOpenVinsGroundTruth(
      kEuroc / "ov_data" / "euroc_mav" / "V1_01_easy.csv");
  ASSERT_TRUE(truth.ok()) << truth.error().message;
  EXPECT_EQ(truth->size(), 2895u);
  // At rest, world up in the body is about (0.924, 0.004, -0.382).
  const Eigen::Vector3d up =
      truth->front().q_world_body.toRotationMatrix().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(up.x(), 0.9243, 2e-3);
  EXPECT_NEAR(up.z(), -0.3816, 2e-3);
}

struct Scratch {
  fs::path dir;
  Scratch() {
    dir = fs::temp_directory_path() / ("cairn_asl_" + std::to_string(::getpid()));
    fs::create_directories(dir / "mav0" / "imu0");
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  void Write(const std::string& rel, const std::string& text) const {
    std::ofstream(dir / rel) << text;
  }
};

const char* kImuYaml =
    "%YAML:1.0\nT_BS:\n  cols: 4\n  rows: 4\n  data: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]\n"
    "rate_hz: 200\n";

TEST(AslDataset, BadInputNamesTheFileLineAndField) {
  Scratch s;
  s.Write("mav0/imu0/sensor.yaml", kImuYaml);
  s.Write("mav0/imu0/data.csv",
          "#timestamp [ns],w_RS_S_x,w_RS_S_y,w_RS_S_z,a_RS_S_x,a_RS_S_y,a_RS_S_z\n"
          "1000,0,0,0,9.8,0,0\n"
          "2000,0,0,abc,9.8,0,0\n");
  Expected<sources::AslImu> imu = sources::ReadAslImu(s.dir / "mav0");
  ASSERT_FALSE(imu.ok());
  EXPECT_NE(imu.error().message.find("data.csv:3: field w_RS_S_z"), std::string::npos)
      << imu.error().message;

  s.Write("mav0/imu0/data.csv", "1000,0,0,0,9.8,0,0\n2000,0,0,0,9.8\n");
  imu = sources::ReadAslImu(s.dir / "mav0");
  ASSERT_FALSE(imu.ok());
  EXPECT_NE(imu.error().message.find("data.csv:2: expected 7"), std::string::npos)
      << imu.error().message;

  s.Write("mav0/imu0/data.csv", "2000,0,0,0,9.8,0,0\n1000,0,0,0,9.8,0,0\n");
  imu = sources::ReadAslImu(s.dir / "mav0");
  ASSERT_FALSE(imu.ok());
  EXPECT_NE(imu.error().message.find("data.csv:2: field timestamp: expected times to increase"),
            std::string::npos)
      << imu.error().message;

  s.Write("mav0/imu0/data.csv", "1000,0,0,0,9.8,0,0\n");
  s.Write("mav0/imu0/sensor.yaml", "T_BS:\n  data: [1,0,0]\nrate_hz: 200\n");
  imu = sources::ReadAslImu(s.dir / "mav0");
  ASSERT_FALSE(imu.ok());
  EXPECT_NE(imu.error().message.find("sensor.yaml: field T_BS.data: expected a list of 16"),
            std::string::npos)
      << imu.error().message;

  s.Write("mav0/imu0/sensor.yaml", kImuYaml);
  imu = sources::ReadAslImu(s.dir / "mav0");
  ASSERT_TRUE(imu.ok()) << imu.error().message;
  EXPECT_EQ(imu->samples.size(), 1u);

  s.Write("gt.csv", "1000,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n");
  Expected<std::vector<sources::AslGroundTruth>> gt = sources::ReadOpenVinsGroundTruth(s.dir / "gt.csv");
  ASSERT_FALSE(gt.ok());
  EXPECT_NE(gt.error().message.find("gt.csv:1: field qw..qz: expected a unit quaternion"),
            std::string::npos)
      << gt.error().message;
}

// The bounds: `cairn eval --euroc` measures a tilt error of 0.27 deg median and 0.72 deg
// 95th percentile (libmap/README.md); the estimator sees only the IMU and the true velocity,
// and the truth's own up is 0.24 deg from the gravity its IMU and biases measure.
constexpr double kMaxTiltMedianDeg = 0.35;
constexpr double kMaxTiltP95Deg = 0.85;

TEST(EurocGravity, ImuTermsAloneRecoverRollAndPitch) {
  if (!HaveEuroc()) GTEST_SKIP() << kEuroc << " is absent (the shared EuRoC V1_01 start)";
  Expected<eval::EurocGravityResult> r = eval::RunEurocGravity(kEuroc);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->frames, 2895);
  EXPECT_NEAR(r->duration_s, 144.7, 0.1);
  EXPECT_LT(r->tilt_median_deg, kMaxTiltMedianDeg);
  EXPECT_LT(r->tilt_p95_deg, kMaxTiltP95Deg);
  // The first frame starts from its accelerometer (no start-up spike of tens of degrees).
  EXPECT_LT(r->tilt_max_deg, 10.0);
  // At rest the bias cannot be told from a tilt and is flagged; once moving it is not.
  EXPECT_GT(r->bias_observed_from_s, 1.0);
  EXPECT_LT(r->bias_observed_from_s, 20.0);
  EXPECT_GT(r->observed_frames, 2500);
  EXPECT_LT(r->observed_tilt_median_deg, kMaxTiltMedianDeg);
  // At rest the accelerometer alone is within 0.5-0.9 deg of the truth (SOURCE.md).
  EXPECT_GT(r->rest_accel_tilt_deg, 0.3);
  EXPECT_LT(r->rest_accel_tilt_deg, 1.0);
  // The truth against its own IMU: a constant 0.24 deg, the spans scattered 2-3 cm/s^2.
  EXPECT_NEAR(r->truth_gravity_tilt_deg, 0.24, 0.05);
  EXPECT_LT(r->truth_gravity_rms_mps2.maxCoeff(), 0.05);
}

// The 20 stereo pairs at rest, rectified and matched by od::io: the floor's normal is the up
// vector, as the accelerometer says and the truth has it. cairn_euroc_gravity measures the
// floor at 0.44 deg median (0.64 max) from the true up, the accelerometer (its 0.1 m/s^2
// bias uncorrected, about 0.6 deg) at 0.63 deg median.
TEST(EurocGravity, TheFloorSeenInStereoAtRestGivesTheTrueUp) {
  if (!HaveEuroc()) GTEST_SKIP() << kEuroc << " is absent (the shared EuRoC V1_01 start)";
  Expected<eval::EurocStereoUpResult> r = eval::RunEurocStereoUp(kEuroc);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->pairs, 20);
  EXPECT_GT(r->floor_points, 20 * 10000);
  EXPECT_LT(r->floor_median_deg, 0.8);
  EXPECT_LT(r->floor_max_deg, 1.2);
  EXPECT_LT(r->accel_median_deg, 1.0);
  EXPECT_LT(r->floor_vs_accel_median_deg, 1.5);
}

}  // namespace
}  // namespace cairn
