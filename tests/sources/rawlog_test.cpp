// Rawlog files as sources: malformed files give errors naming the file and the entry (never
// a crash), sensory-frame files give their actions as odometry, summaries count what a file
// holds, and the synthetic sequences of libsim/mrpt read back exactly.
#include <gtest/gtest.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3D.h>

#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/sources/rawlog_file.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "cairn/sources/rawlog_summary.hpp"
#include "helpers.hpp"
#include "io/temp_dir.hpp"

#ifdef CAIRN_HAVE_SIM_MRPT
#include "cairn/sim/camera.hpp"
#include "cairn/sim/drive.hpp"
#include "cairn/sim/mrpt/sequence.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"
#endif

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;
using ::mrpt::obs::CObservationIMU;

CObservationIMU::Ptr Imu(double stamp_s, double roll, double pitch) {
  auto imu = std::make_shared<CObservationIMU>();
  imu->sensorLabel = "IMU";
  imu->timestamp = ToMrptTime(stamp_s);
  imu->set(::mrpt::obs::IMU_ROLL, roll);
  imu->set(::mrpt::obs::IMU_PITCH, pitch);
  return imu;
}

void Write(const fs::path& path, const std::vector<const ::mrpt::serialization::CSerializable*>& objects,
           int gzip_level = 0) {
  Expected<RawlogWriter> writer = RawlogWriter::Create(path, gzip_level);
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (const auto* object : objects) ASSERT_TRUE(writer->Write(*object).ok());
  ASSERT_TRUE(writer->Commit().ok());
}

// Reads every entry; the error, or "" when the file reads to its end.
std::string ReadAll(const fs::path& path, int* entries = nullptr) {
  Expected<RawlogSource> source = RawlogSource::Open(path);
  if (!source) return source.error().message;
  int n = 0;
  while (true) {
    Expected<std::optional<SourceEntry>> entry = source->NextEntry();
    if (!entry) return entry.error().message;
    if (!*entry) break;
    ++n;
  }
  if (entries != nullptr) *entries = n;
  return "";
}

// ---------------------------------------------------------------------------------------
// Malformed files

class MalformedRawlogs : public ::testing::Test {
 protected:
  void SetUp() override {
    imu_ = Imu(100.0, 0.01, 0.02);
    scan_ = test::MakeScan(64, 48, 40.0, [](int c, int r) { return 2.0 + 0.01 * (r + c); }, true);
    Write(dir_ / "imu.rawlog", {imu_.get()});
    Write(dir_ / "good.rawlog", {imu_.get(), scan_.get(), imu_.get()});
  }
  test::TempDir dir_;
  CObservationIMU::Ptr imu_;
  ::mrpt::obs::CObservation3DRangeScan::Ptr scan_;
};

TEST_F(MalformedRawlogs, GoodFileReadsToItsEnd) {
  int entries = 0;
  EXPECT_EQ(ReadAll(dir_ / "good.rawlog", &entries), "");
  EXPECT_EQ(entries, 3);
}

TEST_F(MalformedRawlogs, TruncatedInsideAnObjectNamesFileAndEntry) {
  const auto imu_bytes = fs::file_size(dir_ / "imu.rawlog");
  const auto all_bytes = fs::file_size(dir_ / "good.rawlog");
  for (const auto cut : {imu_bytes + 10, imu_bytes + (all_bytes - 2 * imu_bytes) / 2,
                         all_bytes - imu_bytes - 1}) {
    fs::copy_file(dir_ / "good.rawlog", dir_ / "cut.rawlog", fs::copy_options::overwrite_existing);
    fs::resize_file(dir_ / "cut.rawlog", cut);
    const std::string error = ReadAll(dir_ / "cut.rawlog");
    EXPECT_NE(error.find("cut.rawlog: entry 1: truncated or corrupt"), std::string::npos)
        << "cut at " << cut << ": " << error;
  }
  // The same in a gzip-compressed file.
  Write(dir_ / "good.gz.rawlog", {imu_.get(), scan_.get()}, 6);
  fs::copy_file(dir_ / "good.gz.rawlog", dir_ / "cut.gz.rawlog");
  fs::resize_file(dir_ / "cut.gz.rawlog", fs::file_size(dir_ / "good.gz.rawlog") * 2 / 3);
  const std::string error = ReadAll(dir_ / "cut.gz.rawlog");
  EXPECT_NE(error.find("cut.gz.rawlog: entry 1: truncated or corrupt"), std::string::npos)
      << error;
}

TEST_F(MalformedRawlogs, RandomBytesTextAndOtherClassesAreNotRawlogs) {
  std::mt19937 rng(11);
  std::string bytes(4096, '\0');
  for (char& b : bytes) b = static_cast<char>(rng() & 0xFF);
  dir_.Write("random.rawlog", bytes);
  std::string error = ReadAll(dir_ / "random.rawlog");
  EXPECT_NE(error.find("random.rawlog: entry 0:"), std::string::npos) << error;

  dir_.Write("notes.txt", "# a text file\nx y z\n1 2 3\n");
  error = ReadAll(dir_ / "notes.txt");
  EXPECT_NE(error.find("notes.txt: entry 0: truncated or corrupt rawlog (or not a rawlog)"),
            std::string::npos)
      << error;

  // A valid MRPT object that is no observation, sensory frame or action collection.
  const ::mrpt::poses::CPose3D pose(1, 2, 3, 0, 0, 0);
  Write(dir_ / "pose.rawlog", {imu_.get(), &pose});
  error = ReadAll(dir_ / "pose.rawlog");
  EXPECT_NE(error.find("pose.rawlog: entry 1: a CPose3D, not an observation, sensory frame or "
                       "action collection"),
            std::string::npos)
      << error;

  error = ReadAll(dir_ / "missing.rawlog");
  EXPECT_NE(error.find("missing.rawlog: no such file"), std::string::npos) << error;
  error = ReadAll(dir_.path());
  EXPECT_NE(error.find("not a regular file"), std::string::npos) << error;
}

TEST_F(MalformedRawlogs, EmptyFileHasNoEntry) {
  int entries = -1;
  EXPECT_EQ(ReadAll(dir_.Write("empty.rawlog", ""), &entries), "");
  EXPECT_EQ(entries, 0);
  Expected<RawlogSummary> summary = SummarizeRawlog(dir_ / "empty.rawlog");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->format, RawlogFormat::kEmpty);
}

TEST_F(MalformedRawlogs, UndecodableRangeDataNamesFileEntryAndSensor) {
  scan_->cameraParams.setIntrinsicParamsFromValues(-40.0, 40.0, 31.5, 23.5);
  Write(dir_ / "bad_camera.rawlog", {imu_.get(), scan_.get()});
  const std::string error = ReadAll(dir_ / "bad_camera.rawlog");
  EXPECT_NE(error.find("bad_camera.rawlog: entry 1: CObservation3DRangeScan 'RGBD': "
                       "cameraParams: "),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("fx"), std::string::npos) << error;
  // The summary reads on and says what could not be decoded.
  Expected<RawlogSummary> summary = SummarizeRawlog(dir_ / "bad_camera.rawlog");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  ASSERT_EQ(summary->sensors.size(), 2u);
  EXPECT_EQ(summary->sensors[1].label, "RGBD");
  EXPECT_EQ(summary->sensors[1].problems, 1);
  EXPECT_NE(summary->sensors[1].problem.find("cameraParams"), std::string::npos);
}

TEST(RawlogWriter, AbandonedWriterLeavesNothingAndCommitIsAtomic) {
  test::TempDir dir;
  const auto imu = Imu(1.0, 0.0, 0.0);
  {
    Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "x.rawlog");
    ASSERT_TRUE(writer.ok());
    ASSERT_TRUE(writer->Write(*imu).ok());
    EXPECT_EQ(dir.List().size(), 1u);  // the temporary
    EXPECT_FALSE(fs::exists(dir / "x.rawlog"));
  }
  EXPECT_TRUE(dir.List().empty());
  Expected<RawlogWriter> writer = RawlogWriter::Create(dir / "x.rawlog", 12);
  ASSERT_FALSE(writer.ok());
  EXPECT_NE(writer.error().message.find("gzip level 12"), std::string::npos);
}

// ---------------------------------------------------------------------------------------
// Odometry

TEST(RawlogOdometry, SensoryFrameActionsBecomeOnePoseStream) {
  CAIRN_MRPT_DATASET_OR_SKIP(path, "kf-slam_6D_demo");
  Expected<RawlogSource> source = RawlogSource::Open(path);
  ASSERT_TRUE(source.ok()) << source.error().message;
  // Reference: MRPT's own composition of the actions' means, and the frames' stamps.
  ::mrpt::poses::CPose3D reference;
  std::vector<::mrpt::poses::CPose3D> poses = {reference};
  std::vector<double> frame_stamps;
  while (true) {
    Expected<std::optional<SourceEntry>> entry = source->NextEntry();
    ASSERT_TRUE(entry.ok()) << entry.error().message;
    if (!*entry) break;
    const auto& object = (*entry)->raw.object;
    if (auto actions = std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>(object)) {
      auto move = actions->getActionByClass<::mrpt::obs::CActionRobotMovement3D>();
      ASSERT_TRUE(move);
      reference = reference + move->poseChange.mean;
      poses.push_back(reference);
    } else {
      ASSERT_FALSE((*entry)->observations.empty());
      frame_stamps.push_back(FromMrptTime((*entry)->observations.front()->timestamp));
      EXPECT_TRUE((*entry)->frames.empty());  // bearing-range observations: no range data
    }
  }
  const std::vector<OdometrySample>& odometry = source->odometry();
  ASSERT_EQ(poses.size(), 601u);
  ASSERT_EQ(frame_stamps.size(), 600u);
  ASSERT_EQ(odometry.size(), poses.size());
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    EXPECT_EQ(odometry[k].source, "CActionRobotMovement3D");
    ASSERT_TRUE(odometry[k].T_odom_body.isApprox(FromCPose3D(poses[k]), 1e-9)) << "pose " << k;
    // The actions carry no time: pose k is where the robot observed sensory frame k; the
    // last action has no frame after it and keeps the last time of the file.
    const double expected = frame_stamps[std::min<std::size_t>(k, frame_stamps.size() - 1)];
    ASSERT_DOUBLE_EQ(odometry[k].stamp_s, expected) << "pose " << k;
  }
  // The robot's true path (MRPT's ground truth, from the same origin) ends 1.04 m from
  // where odometry puts it after a 128 m drive: the simulated odometry's drift.
  std::ifstream truth(fs::path(CAIRN_MRPT_DATASETS) / "kf-slam_6D_demo_ground_truth_robot_path.txt");
  std::string line, last;
  while (std::getline(truth, line)) {
    if (!line.empty() && line[0] != '%') last = line;
  }
  std::istringstream fields(last);
  double x = 0, y = 0, z = 0;
  fields >> x >> y >> z;
  const Eigen::Vector3d end = odometry.back().T_odom_body.translation();
  EXPECT_NEAR((end - Eigen::Vector3d(x, y, z)).norm(), 1.036, 0.001);
}

TEST(RawlogOdometry, TimedActionsKeepTheirOwnStamps) {
  test::TempDir dir;
  ::mrpt::obs::CActionRobotMovement2D::TMotionModelOptions model;
  std::vector<::mrpt::obs::CSensoryFrame> frames(3);
  std::vector<::mrpt::obs::CActionCollection> actions(2);
  for (int k = 0; k < 3; ++k) frames[k].insert(Imu(10.0 + k, 0.0, 0.01 * k));
  for (int k = 0; k < 2; ++k) {
    ::mrpt::obs::CActionRobotMovement2D move;
    move.computeFromOdometry(::mrpt::poses::CPose2D(1.0, 0.0, kPi / 2), model);
    move.timestamp = ToMrptTime(10.5 + k);
    actions[k].insert(move);
  }
  Write(dir / "sf.rawlog", {&frames[0], &actions[0], &frames[1], &actions[1], &frames[2]});
  Expected<RawlogSource> source = RawlogSource::Open(dir / "sf.rawlog");
  ASSERT_TRUE(source.ok());
  while (true) {
    Expected<std::optional<SourceEntry>> entry = source->NextEntry();
    ASSERT_TRUE(entry.ok()) << entry.error().message;
    if (!*entry) break;
  }
  const std::vector<OdometrySample>& odometry = source->odometry();
  ASSERT_EQ(odometry.size(), 3u);
  EXPECT_DOUBLE_EQ(odometry[0].stamp_s, 10.0);
  EXPECT_NEAR(odometry[1].stamp_s, 10.5, 1e-6);
  EXPECT_NEAR(odometry[2].stamp_s, 11.5, 1e-6);
  // One metre forward, turn left, one metre forward: (1, 1), facing backwards.
  EXPECT_TRUE(odometry[2].T_odom_body.translation().isApprox(Eigen::Vector3d(1, 1, 0), 1e-9));
  EXPECT_NEAR(odometry[2].T_odom_body(0, 0), -1.0, 1e-9);
  EXPECT_EQ(odometry[2].source, "CActionRobotMovement2D");

  Expected<RawlogSummary> summary = SummarizeRawlog(dir / "sf.rawlog");
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  EXPECT_EQ(summary->format, RawlogFormat::kSensoryFrames);
  EXPECT_EQ(summary->odometry_poses, 3);
  EXPECT_NEAR(summary->odometry_path_m, 2.0, 1e-9);
  EXPECT_EQ(summary->class_counts.at("CActionRobotMovement2D"), 2);
  EXPECT_EQ(summary->class_counts.at("CObservationIMU"), 3);
  ASSERT_EQ(summary->sensors.size(), 1u);
  EXPECT_NEAR(summary->sensors[0].rate_hz, 1.0, 1e-9);
}

// ---------------------------------------------------------------------------------------
// Summaries

TEST(RawlogSummaries, MrptDatasetsAreDescribed) {
  CAIRN_MRPT_DATASET_OR_SKIP(rgbd, "tests_rgbd");
  CAIRN_MRPT_DATASET_OR_SKIP(velodyne, "test_velodyne_VLP16");
  CAIRN_MRPT_DATASET_OR_SKIP(kf, "kf-slam_6D_demo");
  Expected<RawlogSummary> s = SummarizeRawlog(rgbd);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->format, RawlogFormat::kObservations);
  EXPECT_TRUE(s->gzip);
  EXPECT_EQ(s->entries, 1);
  ASSERT_EQ(s->sensors.size(), 1u);
  EXPECT_EQ(s->sensors[0].label, "OPENNI2");
  EXPECT_EQ(s->sensors[0].width, 640);
  EXPECT_EQ(s->sensors[0].height, 480);
  EXPECT_TRUE(std::isnan(s->sensors[0].rate_hz));

  s = SummarizeRawlog(velodyne);
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_EQ(s->sensors.size(), 1u);
  EXPECT_EQ(s->sensors[0].mrpt_class, "CObservationVelodyneScan");
  EXPECT_EQ(s->sensors[0].points_max, 11305);
  EXPECT_EQ(s->sensors[0].rings, 16);

  s = SummarizeRawlog(kf);
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(s->format, RawlogFormat::kSensoryFrames);
  EXPECT_EQ(s->entries, 1200);
  EXPECT_EQ(s->class_counts.at("CSensoryFrame"), 600);
  EXPECT_EQ(s->class_counts.at("CActionCollection"), 600);
  EXPECT_EQ(s->class_counts.at("CActionRobotMovement3D"), 600);
  EXPECT_EQ(s->class_counts.at("CObservationBearingRange"), 600);
  EXPECT_EQ(s->odometry_poses, 601);
  EXPECT_NEAR(s->last_stamp_s - s->first_stamp_s, 0.580, 0.001);
}

#ifdef CAIRN_HAVE_SIM_MRPT
// ---------------------------------------------------------------------------------------
// Synthetic sequences of libsim/mrpt

sim::World MakeWorld() {
  sim::World world;
  world.name = "test";
  world.scene = sim::Scene(sim::Terrain::Hills(0.0, {{0.3, 14.0, 0.4, 0.0}}));
  world.scene.AddPole(9.0, 1.0, 0.15, 1.5, true, "pole");
  world.camera.model = sim::PinholeFromFov(80, 60, 1.3);
  world.camera.max_range_m = 40.0;
  world.views = {sim::Viewpoint{}};
  sim::DriveSpec drive;
  drive.waypoints = {{0.0, 0.0}, {4.0, 0.5}, {6.0, 3.0}};
  drive.speed_mps = 3.0;
  drive.frame_rate_hz = 5.0;
  drive.imu_bias_rad = 0.01;  // roll and pitch, no noise: the up vector's error is known
  drive.imu_sigma_rad = 0.0;
  world.drive = drive;
  world.seed = 3;
  return world;
}

TEST(RawlogSimulated, CameraSequenceReadsBackExactly) {
  test::TempDir dir;
  const sim::World world = MakeWorld();
  sim::SequenceOptions options;
  options.max_frames = 5;
  options.noise = false;
  Expected<sim::SequenceSummary> written = sim::WriteDriveSequence(world, dir.path(), options);
  ASSERT_TRUE(written.ok()) << written.error().message;
  const Expected<sim::Drive> drive = sim::SimulateDrive(
      world.scene.terrain(), *world.drive, sim::SensorFrame::kCameraOptical, world.seed, 5);
  ASSERT_TRUE(drive.ok());
  SourceOptions source_options;
  source_options.label = "CAMERA";
  Expected<RawlogSource> source = RawlogSource::Open(written->rawlog, source_options);
  ASSERT_TRUE(source.ok());
  for (int k = 0; k < 5; ++k) {
    Expected<std::optional<Frame>> frame = source->NextFrame();
    ASSERT_TRUE(frame.ok() && *frame) << (frame.ok() ? "end" : frame.error().message);
    const Frame& f = **frame;
    const sim::DriveSample& s = drive->samples[k];
    EXPECT_EQ(f.index, k);
    EXPECT_EQ(f.entry, 3 * k + 2);  // ODOMETRY, IMU, CAMERA per frame
    EXPECT_NEAR(f.stamp_s, options.start_unix_s + 0.2 * k, 1e-7);
    EXPECT_TRUE(f.T_body_sensor.isApprox(drive->T_body_sensor, 1e-12));
    ASSERT_TRUE(f.odometry && f.imu);
    EXPECT_EQ(f.odometry->T_odom_body.translation().x(), s.odometry.x_m);
    EXPECT_EQ(f.odometry->T_odom_body.translation().y(), s.odometry.y_m);
    EXPECT_EQ(f.imu->roll_rad, s.imu.roll_rad);
    EXPECT_EQ(f.imu->pitch_rad, s.imu.pitch_rad);
    // The depth is the render's to the millimetre the rawlog keeps.
    const Expected<sim::DepthFrame> truth =
        sim::RenderDriveCamera(world, s.T_world_sensor, k, false);
    ASSERT_TRUE(truth.ok());
    ASSERT_EQ(f.depth()->depth_m.size(), truth->depth_m.size());
    for (std::size_t i = 0; i < truth->depth_m.size(); ++i) {
      ASSERT_NEAR(f.depth()->depth_m[i], truth->depth_m[i], 0.0005 + 1e-6) << "frame " << k;
    }
    EXPECT_EQ(f.depth()->model.fx, truth->model.fx);
    // The up vector is the IMU's (roll and pitch as reported, bias included), within the
    // bias of the truth.
    const Eigen::Vector3d up_body =
        sim::RotationFromAttitude(s.imu).transpose() * Eigen::Vector3d::UnitZ();
    EXPECT_TRUE(UpInSensor(f).isApprox(drive->T_body_sensor.linear().transpose() * up_body, 1e-9));
    const double error_rad = std::acos(std::min(1.0, UpInSensor(f).dot(truth->up_optical)));
    EXPECT_NEAR(error_rad, 0.01 * std::sqrt(2.0), 2e-4);
  }
  Expected<std::optional<Frame>> end = source->NextFrame();
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(*end);
}

TEST(RawlogSimulated, LidarSequenceRingsAreTheSimulatorsRings) {
  test::TempDir dir;
  sim::World world = MakeWorld();
  Expected<sim::LidarSpec> lidar = sim::LidarSpec::Preset("VLP-16");
  ASSERT_TRUE(lidar.ok());
  lidar->azimuth_steps = 512;
  world.lidar = *lidar;
  sim::SequenceOptions options;
  options.sensor = sim::SensorFrame::kLidar;
  options.max_frames = 2;
  options.noise = false;
  Expected<sim::SequenceSummary> written = sim::WriteDriveSequence(world, dir.path(), options);
  ASSERT_TRUE(written.ok()) << written.error().message;
  Expected<RawlogSource> source = RawlogSource::Open(written->rawlog);
  ASSERT_TRUE(source.ok());
  for (int k = 0; k < 2; ++k) {
    Expected<std::optional<Frame>> frame = source->NextFrame();
    ASSERT_TRUE(frame.ok() && *frame) << (frame.ok() ? "end" : frame.error().message);
    const PointScan& scan = *(*frame)->points();
    EXPECT_EQ((*frame)->mrpt_class, "CObservationPointCloud");
    // The simulator's ring of every point, from truth/NNNNNN.rowcol (uint16 ring, column).
    char name[32];
    std::snprintf(name, sizeof(name), "truth/%06d.rowcol", k);
    std::ifstream rowcol(dir / name, std::ios::binary);
    std::vector<std::uint16_t> cells(2 * scan.points.size());
    rowcol.read(reinterpret_cast<char*>(cells.data()),
                static_cast<std::streamsize>(cells.size() * sizeof(std::uint16_t)));
    ASSERT_EQ(rowcol.gcount(), static_cast<std::streamsize>(cells.size() * 2));
    // Rings found from the elevations: the simulator's rings that hit something, in order.
    std::set<int> hit;
    for (std::size_t i = 0; i < scan.points.size(); ++i) hit.insert(cells[2 * i]);
    std::vector<int> row_of_ring(16, -1);
    int row = 0;
    for (int ring : hit) row_of_ring[ring] = row++;
    ASSERT_EQ(scan.model.height(), static_cast<int>(hit.size())) << scan.layout;
    for (int ring : hit) {
      EXPECT_NEAR(scan.model.ring_elevation_rad[row_of_ring[ring]], lidar->elevations_rad[ring],
                  1e-5);
    }
    EXPECT_EQ(scan.model.width, 512);
    for (std::size_t i = 0; i < scan.points.size(); ++i) {
      ASSERT_EQ(scan.rows[i], row_of_ring[cells[2 * i]]) << "point " << i;
    }
  }
}
#endif  // CAIRN_HAVE_SIM_MRPT

}  // namespace
}  // namespace cairn::sources
