// `cairn map` end to end: a tiny synthetic drive made by `cairn synth` is fused from its
// rawlog (odometry + IMU) and from a folder of depth PNGs with its true poses; every file is
// written, the cost grid loads as map_server would read it, the obstacles stand where the
// world has them, and bad input fails with a message naming the file or field, leaving
// nothing behind.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cairn/map/map_files.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/sources/rawlog_source.hpp"
#include "io/temp_dir.hpp"

namespace cairn {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The world of the drive: the obstacles' true positions are asserted below.
constexpr const char* kWorld = R"(description: a short drive up a gentle slope past three obstacles
seed: 3
terrain:
  slope: 5
  uphill_heading: 0
camera:
  width: 160
  height: 120
  fx: 130
  max_range: 25
  noise: {depth_sigma_per_m2: 0.0005}
views:
  - {x: 0, y: 0, height: 1.6, heading: 0, pitch: 10, roll: 0, follow_terrain: true}
drive:
  waypoints: [[0, 0], [10, 0]]
  speed: 2.0
  frame_rate: 2
  wheelbase: 1.5
  track: 1.2
  sensor_xyz: [0.5, 0.0, 1.6]
  sensor_pitch: 10
  odom_sigma_per_m: 0.005
  odom_yaw_sigma_per_m: 0.05
  imu_sigma: 0.2
  imu_bias: 0.3
objects:
  - {kind: pole, name: pole, obstacle: true, x: 9.0, y: 2.5, radius: 0.15, height: 1.5}
  - {kind: box, name: crate, obstacle: true, x: 12.0, y: -2.5, size: [1.0, 0.8, 0.8], yaw: 0}
  - {kind: rock, name: rock, obstacle: true, x: 15.0, y: 2.0, radii: [0.5, 0.5, 0.4], height: 0.6}
)";

struct TrueObstacle {
  const char* name;
  double x, y;
};
constexpr TrueObstacle kObstacles[] = {
    {"pole", 9.0, 2.5}, {"crate", 12.0, -2.5}, {"rock", 15.0, 2.0}};

const std::vector<std::string> kMapFiles = {
    "map.bt",    "map.ot",      "obstacles.ot",   "cost.yaml",      "cost.pgm",
    "cost.png",  "overlay.png", "elevation.tiff", "elevation.yaml", "obstacles.json",
    "poses.tum", "frames.csv",  "summary.json",   "summary.txt"};

struct CommandRun {
  int status = -1;
  std::string out, err;
};

using test::ReadFile;

/// Runs `cairn <args>`, capturing stdout and stderr.
CommandRun Cairn(const std::string& args, const fs::path& scratch) {
  const fs::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string command = std::string("'") + CAIRN_EXE + "' " + args + " >'" + out.string() +
                              "' 2>'" + err.string() + "'";
  const int raw = std::system(command.c_str());
  CommandRun run;
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = ReadFile(out);
  run.err = ReadFile(err);
  return run;
}

/// Runs `cairn <args>` and interrupts it (SIGINT, as Ctrl-C does) as soon as `watched`
/// exists: a run stopped part-way, at whatever frame it has reached.
CommandRun CairnInterruptedOnceThere(const std::string& args, const fs::path& watched,
                                     const fs::path& scratch) {
  const fs::path out = scratch / "stdout.txt", err = scratch / "stderr.txt";
  const std::string command = std::string("exec '") + CAIRN_EXE + "' " + args + " >'" +
                              out.string() + "' 2>'" + err.string() + "'";
  CommandRun run;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int raw = 0;
  bool sent = false;
  while (::waitpid(pid, &raw, WNOHANG) == 0) {
    if (!sent && fs::exists(watched)) {
      ::kill(pid, SIGINT);
      sent = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  run.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  run.out = ReadFile(out);
  run.err = ReadFile(err);
  return run;
}

class MapCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("cairn_map_cli_test_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    std::ofstream(*dir_ / "world.yaml") << kWorld;
    const CommandRun synth = Cairn("synth --world '" + (*dir_ / "world.yaml").string() +
                                       "' --drive --out '" + (*dir_ / "seq").string() + "'",
                                   *dir_);
    ASSERT_EQ(synth.status, 0) << synth.err;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  static const fs::path& dir() { return *dir_; }
  static fs::path rawlog() { return *dir_ / "seq" / "sequence.rawlog"; }
  /// The rawlog fused with config/default.yaml and scored against the world (one test uses
  /// it: each test runs in its own process under ctest).
  static fs::path FuseTheRawlog() {
    const fs::path out = *dir_ / "out";
    const CommandRun map =
        Cairn("map --rawlog '" + rawlog().string() + "' --config '" +
                  (fs::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml").string() + "' --out '" +
                  out.string() + "' --truth '" + (*dir_ / "world.yaml").string() + "'",
              *dir_);
    EXPECT_EQ(map.status, 0) << map.err;
    return out;
  }

  /// Asserts that each true obstacle has a map obstacle within 1 m (odometry drift and the
  /// grid's cells) and that no map obstacle stands more than 1.5 m from every true one.
  static void ExpectObstaclesNearTheTrueOnes(const fs::path& obstacles_json) {
    const json doc = json::parse(ReadFile(obstacles_json));
    const json& obstacles = doc.at("obstacles");
    ASSERT_FALSE(obstacles.empty());
    const auto distance_to = [](const json& o, double x, double y) {
      // From the point to the obstacle's footprint box (0 inside).
      const double dx = std::max({o.at("footprint_min")[0].get<double>() - x, 0.0,
                                  x - o.at("footprint_max")[0].get<double>()});
      const double dy = std::max({o.at("footprint_min")[1].get<double>() - y, 0.0,
                                  y - o.at("footprint_max")[1].get<double>()});
      return std::hypot(dx, dy);
    };
    for (const TrueObstacle& t : kObstacles) {
      double best = 1e9;
      for (const json& o : obstacles) best = std::min(best, distance_to(o, t.x, t.y));
      EXPECT_LT(best, 1.0) << t.name << " at (" << t.x << ", " << t.y << ")";
    }
    for (const json& o : obstacles) {
      double best = 1e9;
      for (const TrueObstacle& t : kObstacles) best = std::min(best, distance_to(o, t.x, t.y));
      EXPECT_LT(best, 1.5) << "map obstacle " << o.at("id") << " stands where the world has none";
    }
  }

 private:
  static fs::path* dir_;
};
fs::path* MapCli::dir_ = nullptr;

TEST_F(MapCli, FusesARawlogIntoEveryFileWithTheObstaclesWhereTheWorldHasThem) {
  const fs::path out = FuseTheRawlog();
  for (const std::string& name : kMapFiles) {
    EXPECT_TRUE(fs::is_regular_file(out / name)) << name;
    EXPECT_GT(fs::file_size(out / name), 0u) << name;
  }
  for (const fs::directory_entry& e : fs::directory_iterator(out)) {
    EXPECT_TRUE(e.is_regular_file()) << "left behind: " << e.path();
  }
  const json summary = json::parse(ReadFile(out / "summary.json"));
  EXPECT_EQ(summary.at("frames").get<int>(), 11);  // 10 m at 2 m/s, 2 Hz: t = 0 .. 5 s
  EXPECT_NEAR(summary.at("distance_driven_m").get<double>(), 10.0, 0.5);
  EXPECT_EQ(summary.at("map").at("mode"), "offline");
  for (const char* stage : {"read", "detect", "refine", "fuse", "write", "total"}) {
    EXPECT_GE(summary.at("time_s").at(stage).get<double>(), 0.0) << stage;
  }
  EXPECT_EQ(summary.at("input").at("poses"), "odometry 'ODOMETRY' + IMU 'IMU'");
  // The poses file has one line per frame.
  std::istringstream poses(ReadFile(out / "poses.tum"));
  int lines = 0;
  for (std::string line; std::getline(poses, line);) {
    lines += line.empty() || line[0] == '#' ? 0 : 1;
  }
  EXPECT_EQ(lines, 11);

  // The cost grid loads as map_server reads it.
  Expected<map::OccupancyGrid> grid = map::ReadMapServerMap(out / "cost.yaml");
  ASSERT_TRUE(grid) << grid.error().message;
  EXPECT_DOUBLE_EQ(grid->resolution_m, 0.2);
  // The PGM's own header agrees with what map_server made of it: binary grey, 8 bits.
  std::ifstream pgm(out / "cost.pgm", std::ios::binary);
  std::string magic;
  int width = 0, height = 0, max_value = 0;
  pgm >> magic >> width >> height >> max_value;
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(width, grid->width);
  EXPECT_EQ(height, grid->height);
  EXPECT_EQ(max_value, 255);
  pgm.get();  // the one whitespace before the pixels
  const std::string pixels((std::istreambuf_iterator<char>(pgm)), std::istreambuf_iterator<char>());
  EXPECT_EQ(pixels.size(), static_cast<std::size_t>(width) * height);
  // Lethal cells read back as 100, as many as the summary counts; unknown as -1; the
  // observed ground as free or costed.
  int lethal = 0, unknown = 0, free_or_costed = 0;
  for (const std::int8_t v : grid->data) {
    lethal += v == 100 ? 1 : 0;
    unknown += v == -1 ? 1 : 0;
    free_or_costed += v >= 0 && v <= 98 ? 1 : 0;
  }
  EXPECT_EQ(lethal, summary.at("map").at("lethal_cells").get<int>());
  EXPECT_GT(lethal, 0);
  EXPECT_GT(unknown, 0);
  EXPECT_GT(free_or_costed, lethal);

  // The obstacles stand where the world has them.
  ExpectObstaclesNearTheTrueOnes(out / "obstacles.json");
  EXPECT_EQ(summary.at("truth").at("found").get<int>(), 3);
  EXPECT_EQ(summary.at("truth").at("false_obstacles").get<int>(), 0);
}

/// The rawlog's depth frames as PNGs named by their stamps in `frames`, with intrinsics.yaml.
void WriteDepthFrames(const fs::path& rawlog, const fs::path& frames) {
  fs::create_directories(frames);
  Expected<sources::RawlogSource> source = sources::RawlogSource::Open(rawlog);
  ASSERT_TRUE(source) << source.error().message;
  while (true) {
    Expected<std::optional<sources::Frame>> frame = source->NextFrame();
    ASSERT_TRUE(frame) << frame.error().message;
    if (!*frame) break;
    const sources::DepthImage* depth = (*frame)->depth();
    ASSERT_NE(depth, nullptr);
    od::Grid<float> grid;
    grid.width = depth->model.width;
    grid.height = depth->model.height;
    grid.data = depth->depth_m;
    std::ostringstream name;
    name << std::fixed << std::setprecision(6) << (*frame)->stamp_s << ".png";
    ASSERT_TRUE(od::io::WriteDepthPng(frames / name.str(), grid, 0.001));
    od::io::CameraIntrinsics intrinsics;
    intrinsics.model = depth->model;
    intrinsics.depth_scale_m = 0.001;
    intrinsics.up = Eigen::Vector3d(0, -1, 0);
    ASSERT_TRUE(od::io::WriteIntrinsics(frames / "intrinsics.yaml", intrinsics, "# test"));
  }
}

std::vector<fs::path> Pngs(const fs::path& dir) {
  std::vector<fs::path> pngs;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".png") pngs.push_back(e.path());
  }
  std::sort(pngs.begin(), pngs.end());
  return pngs;
}

TEST_F(MapCli, DepthFolderWithTumPosesGivesTheSameObstacles) {
  // The rawlog's depth frames as PNGs named by their stamps, with the true sensor poses.
  const fs::path frames = dir() / "frames";
  WriteDepthFrames(rawlog(), frames);
  const CommandRun run = Cairn("map --frames '" + frames.string() + "' --poses '" +
                                   (dir() / "seq" / "poses_sensor.tum").string() + "' --out '" +
                                   (dir() / "out_frames").string() + "'",
                               dir());
  ASSERT_EQ(run.status, 0) << run.err;
  ExpectObstaclesNearTheTrueOnes(dir() / "out_frames" / "obstacles.json");
  const json summary = json::parse(ReadFile(dir() / "out_frames" / "summary.json"));
  EXPECT_EQ(summary.at("frames").get<int>(), 11);
  EXPECT_EQ(summary.at("input").at("kind"), "depth_frames");

  // A corrupt image after the first frames: exit 1 naming it, and the output folder that
  // this run created is gone again.
  const fs::path broken = dir() / "frames_broken";
  fs::copy(frames, broken);
  std::vector<fs::path> pngs;
  for (const fs::directory_entry& e : fs::directory_iterator(broken)) {
    if (e.path().extension() == ".png") pngs.push_back(e.path());
  }
  std::sort(pngs.begin(), pngs.end());
  std::ofstream(pngs.back(), std::ios::binary | std::ios::trunc) << "not a png";
  const CommandRun bad = Cairn("map --frames '" + broken.string() + "' --poses '" +
                                   (dir() / "seq" / "poses_sensor.tum").string() + "' --out '" +
                                   (dir() / "out_broken").string() + "'",
                               dir());
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find(pngs.back().filename().string()), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir() / "out_broken"));
}

TEST_F(MapCli, OnlineWindowBoundsTheGrid) {
  const fs::path out_online = dir() / "out_online";
  const CommandRun run = Cairn(
      "map --rawlog '" + rawlog().string() + "' --window 12 --out '" + out_online.string() + "'",
      dir());
  ASSERT_EQ(run.status, 0) << run.err;
  Expected<map::OccupancyGrid> grid = map::ReadMapServerMap(out_online / "cost.yaml");
  ASSERT_TRUE(grid) << grid.error().message;
  EXPECT_EQ(grid->width, 60);  // 12 m / 0.2 m: the window, wherever the robot ended
  EXPECT_EQ(grid->height, 60);
  const json summary = json::parse(ReadFile(out_online / "summary.json"));
  EXPECT_EQ(summary.at("map").at("mode"), "online");
}

// `cairn bench` on the same rawlog: the Mapper over the sequence, every stage with a median
// and a 95th percentile no smaller than it, frames fused as the map counts them.
TEST_F(MapCli, BenchTimesEveryStageOfTheMapperOverTheSequence) {
  const CommandRun run =
      Cairn("bench --rawlog '" + rawlog().string() + "' --max-frames 4 --rate 5", dir());
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find("4 frames fused of 4 read (0 skipped)"), std::string::npos) << run.out;
  for (const char* stage :
       {"read", "detect", "tilt", "fuse", "octree", "classify", "grid", "frame"}) {
    const std::regex line(std::string("\\n +") + stage + " +([0-9.]+) +([0-9.]+) +([0-9.]+)\\n");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(run.out, m, line)) << stage << " in:\n" << run.out;
    EXPECT_LE(std::stod(m[1]), std::stod(m[2])) << stage;  // median <= 95th percentile
    EXPECT_NEAR(std::stod(m[3]), std::stod(m[1]) / 200.0, 0.01) << stage;  // of 200 ms at 5 Hz
  }
  EXPECT_NE(run.out.find("frames/s"), std::string::npos);
  EXPECT_NE(run.out.find("peak memory:"), std::string::npos);
  // A rawlog that is not there: exit 1, naming it.
  const CommandRun bad = Cairn("bench --rawlog '" + (dir() / "none.rawlog").string() + "'", dir());
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("none.rawlog"), std::string::npos) << bad.err;
}

TEST_F(MapCli, TiltRefinementReportsItsCorrection) {
  const fs::path config = dir() / "refine.yaml";
  std::ofstream(config) << "tilt:\n  refine: true\n  max_range: 15\n";
  const fs::path out_refined = dir() / "out_refined";
  const CommandRun run = Cairn("map --rawlog '" + rawlog().string() + "' --config '" +
                                   config.string() + "' --out '" + out_refined.string() + "'",
                               dir());
  ASSERT_EQ(run.status, 0) << run.err;
  const json summary = json::parse(ReadFile(out_refined / "summary.json"));
  EXPECT_TRUE(summary.at("tilt").at("refine").get<bool>());
  // Frame 0 has no terrain to match yet; the others do.
  EXPECT_GE(summary.at("tilt").at("refined_frames").get<int>(), 9);
  EXPECT_LE(summary.at("tilt").at("mean_rms_after_m").get<double>(),
            summary.at("tilt").at("mean_rms_before_m").get<double>());
  EXPECT_NE(run.out.find("tilt (refine_to_map): applied on"), std::string::npos) << run.out;
  ExpectObstaclesNearTheTrueOnes(out_refined / "obstacles.json");
}

TEST_F(MapCli, BadInputFailsNamingTheFileOrFieldAndWritesNothing) {
  const fs::path target = dir() / "out_bad";
  const auto expect_failure = [&](const std::string& args, const std::string& named) {
    const CommandRun run = Cairn("map " + args + " --out '" + target.string() + "'", dir());
    EXPECT_EQ(run.status, 1) << args << "\n" << run.err;
    EXPECT_NE(run.err.find(named), std::string::npos) << args << "\n" << run.err;
    EXPECT_FALSE(fs::exists(target)) << args;
  };
  // A missing file.
  expect_failure("--rawlog '" + (dir() / "missing.rawlog").string() + "'", "missing.rawlog");
  // A truncated rawlog: the pose pass reads it all before anything is written.
  const std::string bytes = ReadFile(rawlog());
  const fs::path truncated = dir() / "truncated.rawlog";
  std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  expect_failure("--rawlog '" + truncated.string() + "'", "truncated.rawlog");
  // Not a rawlog at all.
  const fs::path garbage = dir() / "garbage.rawlog";
  std::ofstream(garbage, std::ios::binary) << std::string(4096, '\x5a');
  expect_failure("--rawlog '" + garbage.string() + "'", "garbage.rawlog");
  // Unknown keys in each section the map command reads.
  const fs::path bad_map = dir() / "bad_map.yaml";
  std::ofstream(bad_map) << "map:\n  cel_size: 0.2\n";
  expect_failure("--rawlog '" + rawlog().string() + "' --config '" + bad_map.string() + "'",
                 "map.cel_size");
  const fs::path bad_tilt = dir() / "bad_tilt.yaml";
  std::ofstream(bad_tilt) << "tilt:\n  refine: true\n  prior_sigm: 2\n";
  expect_failure("--rawlog '" + rawlog().string() + "' --config '" + bad_tilt.string() + "'",
                 "tilt.prior_sigm");
  const fs::path bad_detector = dir() / "bad_detector.yaml";
  std::ofstream(bad_detector) << "detector:\n  min_hieght: 0.3\ntilt:\n  refine: false\n";
  expect_failure("--rawlog '" + rawlog().string() + "' --config '" + bad_detector.string() + "'",
                 "detector.min_hieght");
  const fs::path bad_value = dir() / "bad_value.yaml";
  std::ofstream(bad_value) << "tilt:\n  refine: maybe\n";
  expect_failure("--rawlog '" + rawlog().string() + "' --config '" + bad_value.string() + "'",
                 "tilt.refine");
  // A sensor label the rawlog does not have.
  expect_failure("--rawlog '" + rawlog().string() + "' --label LIDAR", "'CAMERA'");
  // Depth frames without poses.
  expect_failure("--frames '" + dir().string() + "'", "--poses");
}

TEST_F(MapCli, AnInterruptedRunResumesFromItsCheckpointToTheSameMap) {
  const std::string common = "map --rawlog '" + rawlog().string() + "' --config '" +
                             (fs::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml").string() +
                             "' --refine-tilt --out '";
  const fs::path whole = dir() / "whole", parts = dir() / "parts";
  const CommandRun once = Cairn(common + whole.string() + "'", dir());
  ASSERT_EQ(once.status, 0) << once.err;
  EXPECT_FALSE(fs::exists(whole / "map.checkpoint"));  // removed once the map is written

  // Interrupted (SIGINT through the handler) once the first checkpoint (after 2 of 11
  // frames) is written: the run stops at the next frame and saves where it is.
  const CommandRun cut = CairnInterruptedOnceThere(
      common + parts.string() + "' --checkpoint-every 2", parts / "map.checkpoint", dir());
  EXPECT_EQ(cut.status, 130) << cut.err;
  std::smatch where;
  ASSERT_TRUE(std::regex_search(cut.err, where, std::regex("interrupted after ([0-9]+) frames")))
      << cut.err;
  const std::string frames_done = where[1];
  EXPECT_NE(cut.err.find("--resume"), std::string::npos) << cut.err;
  std::vector<std::string> left;
  for (const fs::directory_entry& e : fs::directory_iterator(parts)) {
    left.push_back(e.path().filename().string());
  }
  // and no half-written map
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"map.checkpoint", "map.checkpoint.records"}));
  // A save of the records that was cut short after the checkpoint (a crash) left part of a
  // record beyond what the checkpoint counts: the resumed run drops it.
  std::ofstream(parts / "map.checkpoint.records", std::ios::app) << "{\"index\": 99, \"sta";

  // Resumed with other settings, or on another input: refused, naming the checkpoint.
  const fs::path other_config = dir() / "other.yaml";
  std::ofstream(other_config) << "map:\n  cell_size: 0.25\n";
  const CommandRun wrong_config = Cairn("map --rawlog '" + rawlog().string() + "' --config '" +
                                            other_config.string() + "' --out '" +
                                            parts.string() + "' --resume",
                                        dir());
  EXPECT_EQ(wrong_config.status, 1);
  EXPECT_NE(wrong_config.err.find("map.checkpoint"), std::string::npos) << wrong_config.err;
  const CommandRun other_tilt = Cairn("map --rawlog '" + rawlog().string() + "' --config '" +
                                          (fs::path(CAIRN_SOURCE_DIR) / "config" / "default.yaml")
                                              .string() +
                                          "' --out '" + parts.string() + "' --resume",
                                      dir());  // without --refine-tilt
  EXPECT_EQ(other_tilt.status, 1);
  EXPECT_NE(other_tilt.err.find("--tilt"), std::string::npos) << other_tilt.err;
  // A run that forgets --resume does not overwrite the interrupted run's checkpoint.
  const CommandRun afresh = Cairn(common + parts.string() + "'", dir());
  EXPECT_EQ(afresh.status, 1);
  EXPECT_NE(afresh.err.find("--resume"), std::string::npos) << afresh.err;
  const CommandRun no_checkpoint = Cairn(common + (dir() / "none").string() + "' --resume", dir());
  EXPECT_EQ(no_checkpoint.status, 1);
  EXPECT_NE(no_checkpoint.err.find("no checkpoint"), std::string::npos) << no_checkpoint.err;

  // Records missing from what the checkpoint counts: refused, naming the records file.
  const fs::path short_of = dir() / "short";
  fs::create_directories(short_of);
  fs::copy_file(parts / "map.checkpoint", short_of / "map.checkpoint");
  std::ofstream(short_of / "map.checkpoint.records") << "{}\n";
  const CommandRun short_run = Cairn(common + short_of.string() + "' --resume", dir());
  EXPECT_EQ(short_run.status, 1);
  EXPECT_NE(short_run.err.find((short_of / "map.checkpoint.records").string()), std::string::npos)
      << short_run.err;

  // A record broken inside what the checkpoint counts (its length kept): refused, naming the
  // file and the record.
  std::string records = ReadFile(parts / "map.checkpoint.records");
  ASSERT_GT(records.size(), 2u);
  records[1] = '#';
  std::ofstream(short_of / "map.checkpoint.records", std::ios::binary | std::ios::trunc) << records;
  const CommandRun broken = Cairn(common + short_of.string() + "' --resume", dir());
  EXPECT_EQ(broken.status, 1);
  EXPECT_NE(broken.err.find((short_of / "map.checkpoint.records").string() + ": record 1"),
            std::string::npos)
      << broken.err;

  const CommandRun resumed = Cairn(common + parts.string() + "' --resume", dir());
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("after " + frames_done + " frames"), std::string::npos)
      << resumed.err;
  EXPECT_FALSE(fs::exists(parts / "map.checkpoint"));
  EXPECT_FALSE(fs::exists(parts / "map.checkpoint.records"));
  EXPECT_FALSE(fs::exists(whole / "map.checkpoint.records"));
  // The same map, byte for byte, as the run that was never interrupted.
  for (const char* name : {"map.bt", "map.ot", "obstacles.ot", "cost.pgm", "cost.yaml",
                           "elevation.tiff", "obstacles.json", "poses.tum"}) {
    EXPECT_TRUE(ReadFile(whole / name) == ReadFile(parts / name)) << name << " differs";
  }
  const json a = json::parse(ReadFile(whole / "summary.json"));
  const json b = json::parse(ReadFile(parts / "summary.json"));
  EXPECT_EQ(b.at("frames"), 11);
  EXPECT_EQ(a.at("obstacles"), b.at("obstacles"));
  EXPECT_EQ(a.at("tilt").at("refined_frames"), b.at("tilt").at("refined_frames"));
  EXPECT_EQ(a.at("distance_driven_m"), b.at("distance_driven_m"));
}

TEST_F(MapCli, ACorruptCheckpointIsRefusedNamingIt) {
  const fs::path out = dir() / "corrupt";
  fs::create_directories(out);
  std::ofstream(out / "map.checkpoint", std::ios::binary) << "CAIRNMCK not really";
  const CommandRun run = Cairn("map --rawlog '" + rawlog().string() + "' --out '" +
                                   out.string() + "' --resume",
                               dir());
  EXPECT_EQ(run.status, 1);
  EXPECT_NE(run.err.find((out / "map.checkpoint").string()), std::string::npos) << run.err;
  EXPECT_TRUE(fs::exists(out / "map.checkpoint"));  // left as it was
  EXPECT_FALSE(fs::exists(out / "map.bt"));
}

// `--tilt gravity` on a drive recorded with raw IMU samples (`cairn synth --raw-imu`) and a
// 2 deg IMU attitude bias: the accelerometer and the pole observe gravity, and the fused
// poses' tilt, scored against the true poses (--truth-poses), is far below the prior's.
TEST_F(MapCli, TheGravityEstimatorObservesTheIMUBias) {
  std::string world = kWorld;
  world.replace(world.find("imu_bias: 0.3"), 13, "imu_bias: 2.0");
  std::ofstream(dir() / "world_imu.yaml") << world;
  const fs::path seq = dir() / "seq_imu";
  const CommandRun synth = Cairn("synth --world '" + (dir() / "world_imu.yaml").string() +
                                     "' --drive --raw-imu --out '" + seq.string() + "'",
                                 dir());
  ASSERT_EQ(synth.status, 0) << synth.err;
  json tilt[2];
  const char* modes[2] = {"prior", "gravity"};
  for (int m = 0; m < 2; ++m) {
    const fs::path out = dir() / (std::string("out_tilt_") + modes[m]);
    const CommandRun run = Cairn("map --rawlog '" + (seq / "sequence.rawlog").string() +
                                     "' --tilt " + modes[m] + " --truth-poses '" +
                                     (seq / "poses_sensor.tum").string() + "' --out '" +
                                     out.string() + "'",
                                 dir());
    ASSERT_EQ(run.status, 0) << run.err;
    const json summary = json::parse(ReadFile(out / "summary.json"));
    EXPECT_EQ(summary.at("tilt").at("mode"), modes[m]);
    EXPECT_GT(summary.at("input").at("imu_raw_samples").get<int>(), 400);  // 100 Hz
    tilt[m] = summary.at("truth_poses");
    EXPECT_NE(run.out.find("poses against"), std::string::npos) << run.out;
    if (m == 1) {
      // What the estimator could not observe: per frame in frames.csv (its last column), at
      // the end and counted in the summary.
      const json& t = summary.at("tilt");
      const int frames = summary.at("frames").get<int>();
      EXPECT_GE(t.at("vertical_cues").get<int>(), 0);
      EXPECT_LE(t.at("frames_not_observable").get<int>(), frames);
      std::istringstream csv(ReadFile(out / "frames.csv"));
      std::string line, last, header;
      std::getline(csv, header);
      const std::string columns = ",verticals,not_observable";
      EXPECT_EQ(header.rfind(columns), header.size() - columns.size()) << header;
      int rows = 0, flagged = 0;
      while (std::getline(csv, line)) {
        last = line.substr(line.rfind(',') + 1);
        flagged += last.empty() ? 0 : 1;
        ++rows;
      }
      EXPECT_EQ(rows, frames);
      EXPECT_EQ(flagged, t.at("frames_not_observable").get<int>());
      EXPECT_EQ(last, t.at("not_observable_at_end").get<std::string>());
      // The tilt error the estimator expects, stated: finite, and not below the error there is.
      ASSERT_TRUE(t.contains("tilt_sigma_median_deg")) << t.dump();
      EXPECT_GT(t.at("tilt_sigma_median_deg").get<double>(),
                summary.at("truth_poses").at("tilt_error_median_deg").get<double>());
      EXPECT_NE(run.out.find("stated tilt sigma"), std::string::npos) << run.out;
      EXPECT_NE(run.out.find(last.empty() ? "every state observed at the end"
                                          : "not observable at the end: " + last),
                std::string::npos)
          << run.out;
    }
  }
  EXPECT_GT(tilt[0].at("tilt_error_median_deg").get<double>(), 1.5);
  EXPECT_LT(tilt[1].at("tilt_error_median_deg").get<double>(), 0.5);
  EXPECT_LT(tilt[1].at("height_error_rms_m").get<double>(),
            tilt[0].at("height_error_rms_m").get<double>());
}

// `--smooth` on the demo drive: the gravity tilt's run solved again as a whole once it is
// read, and the map fused again at those poses (a second pass over the rawlog). Against the
// true poses its tilt is closer than the window's, the poses it wrote are the smoothed ones,
// and the summary says so. Without the gravity tilt it is refused, nothing written.
TEST_F(MapCli, SmoothingTheDemoDriveBringsItsPosesCloserToTheTruth) {
  const fs::path seq = fs::path(CAIRN_SOURCE_DIR) / "datasets" / "sequences" / "hill_drive";
  json truth[2];
  for (int m = 0; m < 2; ++m) {
    const fs::path out = dir() / (m == 0 ? "out_window" : "out_smoothed");
    const CommandRun run = Cairn("map --rawlog '" + (seq / "sequence.rawlog").string() +
                                     "' --config '" + (seq / "map.yaml").string() +
                                     "' --truth-poses '" + (seq / "poses_sensor.tum").string() +
                                     "' --out '" + out.string() + "'" + (m == 1 ? " --smooth" : ""),
                                 dir());
    ASSERT_EQ(run.status, 0) << run.err;
    const json summary = json::parse(ReadFile(out / "summary.json"));
    EXPECT_EQ(summary.at("tilt").at("mode"), "gravity");
    EXPECT_EQ(summary.at("tilt").at("smoothed").get<bool>(), m == 1);
    truth[m] = summary.at("truth_poses");
    EXPECT_TRUE(fs::exists(out / "map.bt"));
    if (m == 1) {
      EXPECT_NE(run.out.find("smoothed: every frame posed again"), std::string::npos) << run.out;
      EXPECT_NE(run.err.find("smoothed pass"), std::string::npos) << run.err;  // its progress
      EXPECT_EQ(summary.at("frames").get<int>(), 30);
    }
  }
  std::printf(
      "[ figures  ] demo drive: tilt %.3f / %.3f deg, height RMS %.4f m in the window; "
      "%.3f / %.3f deg, %.4f m smoothed\n",
      truth[0].at("tilt_error_median_deg").get<double>(),
      truth[0].at("tilt_error_p95_deg").get<double>(),
      truth[0].at("height_error_rms_m").get<double>(),
      truth[1].at("tilt_error_median_deg").get<double>(),
      truth[1].at("tilt_error_p95_deg").get<double>(),
      truth[1].at("height_error_rms_m").get<double>());
  EXPECT_LT(truth[1].at("tilt_error_p95_deg").get<double>(),
            0.5 * truth[0].at("tilt_error_p95_deg").get<double>());
  EXPECT_LT(truth[1].at("tilt_error_median_deg").get<double>(),
            truth[0].at("tilt_error_median_deg").get<double>());
  EXPECT_LT(truth[1].at("height_error_rms_m").get<double>(),
            truth[0].at("height_error_rms_m").get<double>());

  const fs::path refused = dir() / "out_refused";
  const CommandRun prior =
      Cairn("map --rawlog '" + (seq / "sequence.rawlog").string() + "' --tilt prior --smooth " +
                "--out '" + refused.string() + "'",
            dir());
  EXPECT_EQ(prior.status, 1);
  EXPECT_NE(prior.err.find("--smooth"), std::string::npos) << prior.err;
  EXPECT_FALSE(fs::exists(refused));
}

// The real sequence with poses (datasets/real/REPORT.md): KITTI 00, scans 0-10, fused along
// poses.txt. The road the car drove on stays free; the building fronts and parked cars
// beside it are lethal.
TEST(MapKitti, TheSharedSequenceLeavesTheRoadFreeAndItsSidesLethal) {
  const fs::path kitti = fs::path(CAIRN_SHARED_DATASETS) / "kitti-seq00-0-10";
  if (!fs::exists(kitti / "poses.txt")) {
    GTEST_SKIP() << kitti.string() << " not found (see ../shared/datasets/README.md)";
  }
  const fs::path dir = fs::temp_directory_path() / ("cairn_map_kitti_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const CommandRun run =
      Cairn("map --kitti '" + kitti.string() + "' --config '" +
                (fs::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "hdl-64e.yaml").string() +
                "' --out '" + (dir / "out").string() + "'",
            dir);
  ASSERT_EQ(run.status, 0) << run.err;
  const json summary = json::parse(ReadFile(dir / "out" / "summary.json"));
  EXPECT_EQ(summary.at("frames").get<int>(), 11);
  EXPECT_GE(summary.at("obstacles").at("live").get<int>(), 10);
  // The path: the sensor's positions as fused.
  std::vector<Eigen::Vector2d> path;
  std::istringstream poses(ReadFile(dir / "out" / "poses.tum"));
  for (std::string line; std::getline(poses, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double stamp = 0.0, x = 0.0, y = 0.0;
    fields >> stamp >> x >> y;
    path.emplace_back(x, y);
  }
  ASSERT_EQ(path.size(), 11u);
  const auto distance_to_path = [&](const Eigen::Vector2d& p) {
    double best = 1e9;
    for (std::size_t k = 0; k + 1 < path.size(); ++k) {
      const Eigen::Vector2d a = path[k], ab = path[k + 1] - a;
      const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
      best = std::min(best, (p - (a + t * ab)).norm());
    }
    return best;
  };
  Expected<map::OccupancyGrid> grid = map::ReadMapServerMap(dir / "out" / "cost.yaml");
  ASSERT_TRUE(grid) << grid.error().message;
  int lethal = 0, lethal_on_road = 0, road_known = 0;
  for (int row = 0; row < grid->height; ++row) {
    for (int col = 0; col < grid->width; ++col) {
      const Eigen::Vector2d xy(grid->origin.x() + (col + 0.5) * grid->resolution_m,
                               grid->origin.y() + (row + 0.5) * grid->resolution_m);
      const int v = grid->at(col, row);
      const bool on_road = distance_to_path(xy) < 1.5;  // the car's own lane
      lethal += v == 100 ? 1 : 0;
      if (on_road && v >= 0) ++road_known;
      if (on_road && v == 100) ++lethal_on_road;
    }
  }
  std::printf("KITTI map: %d lethal cells, %d on the road (%d road cells known)\n", lethal,
              lethal_on_road, road_known);
  EXPECT_GT(lethal, 1000);
  EXPECT_GT(road_known, 100);
  EXPECT_EQ(lethal_on_road, 0);
  fs::remove_all(dir);
}

// Nothing is skipped in silence: in the depth folder, one image without a single return and
// one pose 100 m off its neighbours (the frame after it jumps back) are named on stderr, the
// other frames are mapped, and the summary counts them by reason; --strict makes the first
// an error naming it, and writes nothing.
TEST_F(MapCli, FramesThatCannotBeUsedAreNamedAndCountedAndStrictRefusesThem) {
  const fs::path frames = dir() / "frames_bad";
  WriteDepthFrames(rawlog(), frames);
  const std::vector<fs::path> pngs = Pngs(frames);
  ASSERT_EQ(pngs.size(), 11u);
  Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(frames / "intrinsics.yaml");
  ASSERT_TRUE(camera) << camera.error().message;
  od::Grid<float> empty;
  empty.width = camera->model.width;
  empty.height = camera->model.height;
  empty.data.assign(static_cast<std::size_t>(empty.width) * empty.height, 0.0f);
  ASSERT_TRUE(od::io::WriteDepthPng(pngs[3], empty, 0.001));
  // The poses, the 8th (frame 7) moved 100 m along x.
  std::istringstream poses(ReadFile(dir() / "seq" / "poses_sensor.tum"));
  std::ostringstream jumped;
  int pose = 0;
  for (std::string line; std::getline(poses, line);) {
    if (line.empty() || line[0] == '#') {
      jumped << line << "\n";
      continue;
    }
    if (pose++ == 7) {
      std::istringstream fields(line);
      double v[8];
      for (double& x : v) fields >> x;
      v[1] += 100.0;
      jumped << std::setprecision(17);
      for (int k = 0; k < 8; ++k) jumped << (k ? " " : "") << v[k];
      jumped << "\n";
      continue;
    }
    jumped << line << "\n";
  }
  const fs::path tum = dir() / "poses_jumped.tum";
  std::ofstream(tum) << jumped.str();

  const std::string args = "map --frames '" + frames.string() + "' --poses '" + tum.string() + "'";
  const CommandRun run = Cairn(args + " --out '" + (dir() / "out_skips").string() + "'", dir());
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.err.find("skipped " + pngs[3].string() + ": no valid points"), std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("skipped " + pngs[7].string() + ": pose jump"), std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find("skipped " + pngs[8].string() + ": pose jump"), std::string::npos)
      << run.err;
  const json summary = json::parse(ReadFile(dir() / "out_skips" / "summary.json"));
  EXPECT_EQ(summary.at("frames").get<int>(), 8);
  EXPECT_EQ(summary.at("skipped").at("count").get<int>(), 3);
  EXPECT_EQ(summary.at("skipped").at("by_reason").at("no valid points").get<int>(), 1);
  EXPECT_EQ(summary.at("skipped").at("by_reason").at("pose jump").get<int>(), 2);
  EXPECT_NE(run.out.find("skipped: 3 frames not fused (no valid points 1, pose jump 2"),
            std::string::npos)
      << run.out;

  const fs::path strict_out = dir() / "out_strict";
  const CommandRun strict = Cairn(args + " --strict --out '" + strict_out.string() + "'", dir());
  EXPECT_EQ(strict.status, 1);
  EXPECT_NE(strict.err.find(pngs[3].string() + ": no valid points"), std::string::npos)
      << strict.err;
  EXPECT_NE(strict.err.find("--strict"), std::string::npos) << strict.err;
  EXPECT_FALSE(fs::exists(strict_out));
}

// A KITTI sequence (the shared scans 0-2) with scan 1 missing from velodyne/ and scan 2 cut
// short: both named and counted, scan 0 mapped; --strict refuses the missing one.
TEST(MapKitti, AMissingAndATruncatedScanAreNamedAndCounted) {
  const fs::path kitti = fs::path(CAIRN_SHARED_DATASETS) / "kitti-seq00-0-10";
  if (!fs::exists(kitti / "poses.txt")) {
    GTEST_SKIP() << kitti.string() << " not found (see ../shared/datasets/README.md)";
  }
  const fs::path dir =
      fs::temp_directory_path() / ("cairn_map_kitti_holes_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path seq = dir / "seq";
  fs::create_directories(seq / "velodyne");
  for (const char* name : {"calib.txt", "times.txt", "poses.txt"}) {
    fs::create_symlink(kitti / name, seq / name);
  }
  for (const char* scan : {"000000.bin", "000003.bin"}) {
    fs::create_symlink(kitti / "velodyne" / scan, seq / "velodyne" / scan);
  }
  std::ofstream(seq / "velodyne" / "000002.bin", std::ios::binary) << std::string(23, '\0');
  const std::string args = "map --kitti '" + seq.string() + "' --range 0:2 --config '" +
                           (fs::path(CAIRN_SOURCE_DIR) / "config" / "sensors" / "hdl-64e.yaml")
                               .string() +
                           "'";
  const CommandRun run = Cairn(args + " --out '" + (dir / "out").string() + "'", dir);
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string missing = (seq / "velodyne" / "000001.bin").string();
  const std::string truncated = (seq / "velodyne" / "000002.bin").string();
  EXPECT_NE(run.err.find("skipped " + missing + ": missing"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("skipped " + truncated + ": truncated (23 bytes"), std::string::npos)
      << run.err;
  const json summary = json::parse(ReadFile(dir / "out" / "summary.json"));
  EXPECT_EQ(summary.at("frames").get<int>(), 1);
  EXPECT_EQ(summary.at("skipped").at("by_reason").at("missing").get<int>(), 1);
  EXPECT_EQ(summary.at("skipped").at("by_reason").at("truncated").get<int>(), 1);
  const CommandRun strict = Cairn(args + " --strict --out '" + (dir / "strict").string() + "'", dir);
  EXPECT_EQ(strict.status, 1);
  EXPECT_NE(strict.err.find(missing + ": missing"), std::string::npos) << strict.err;
  EXPECT_FALSE(fs::exists(dir / "strict"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cairn
