// Faults around `cairn map`, driven from outside as they happen to users: an output folder
// that cannot be written (read-only) or that fills up (a small tmpfs), and SIGKILL at random
// points of a run followed by --resume. The last good map must stay as it was, the error
// must name the folder, and a killed-and-resumed run must end with the map of a run that
// was never interrupted, byte for byte.
//
// Read-only as root needs more than chmod (root writes anyway): the folder is made
// immutable (chattr +i); the full disk is a 256 kB tmpfs mount. Both need privileges the
// test may not have, and skip, saying so, when they are missing.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "io/temp_dir.hpp"

#ifndef CAIRN_EXE
#error "CAIRN_EXE must name the cairn executable"
#endif
#ifndef CAIRN_SOURCE_DIR
#error "CAIRN_SOURCE_DIR must name the source tree"
#endif

namespace cairn {
namespace {

namespace fs = std::filesystem;

const fs::path kDrive = fs::path(CAIRN_SOURCE_DIR) / "datasets" / "sequences" / "hill_drive";

using test::ReadFile;

/// Every regular file directly in `dir`, by name, with its bytes.
std::map<std::string, std::string> Files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file()) files[e.path().filename().string()] = ReadFile(e.path());
  }
  return files;
}

struct RunResult {
  int status = -1;
  int signal = 0;
  std::string output;
};

/// Starts `cairn args...` with stdout and stderr into `log`; returns its pid.
pid_t Start(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::FILE* out = std::freopen(log.c_str(), "w", stdout);
    if (out == nullptr) ::_exit(126);
    ::dup2(::fileno(stdout), 2);
    std::vector<char*> argv;
    std::string exe = CAIRN_EXE;
    argv.push_back(exe.data());
    std::vector<std::string> copy = args;
    for (std::string& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  return pid;
}

RunResult Wait(pid_t pid, const fs::path& log) {
  int raw = 0;
  ::waitpid(pid, &raw, 0);
  RunResult run;
  if (WIFEXITED(raw)) run.status = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) run.signal = WTERMSIG(raw);
  run.output = ReadFile(log);
  return run;
}

RunResult Cairn(const std::vector<std::string>& args, const fs::path& log) {
  return Wait(Start(args, log), log);
}

class MapFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("cairn_faults_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override {
    for (const std::string& command : cleanup_) (void)std::system(command.c_str());
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  /// `cairn map` on the first `frames` frames of the bundled drive into `out`.
  std::vector<std::string> MapArgs(const fs::path& out, int frames) const {
    return {"map",          "--rawlog",
            (kDrive / "sequence.rawlog").string(),
            "--config",     (kDrive / "map.yaml").string(),
            "--max-frames", std::to_string(frames),
            "--out",        out.string()};
  }

  fs::path root_;
  std::vector<std::string> cleanup_;  ///< shell commands TearDown runs (unmount, chattr -i)
};

TEST_F(MapFaults, AReadOnlyOutputFolderFailsNamingItAndKeepsTheLastGoodMap) {
  const fs::path out = root_ / "out";
  const RunResult first = Cairn(MapArgs(out, 3), root_ / "first.log");
  ASSERT_EQ(first.status, 0) << first.output;
  const std::map<std::string, std::string> good = Files(out);
  ASSERT_TRUE(good.count("map.bt") && good.count("cost.pgm")) << first.output;

  if (::geteuid() == 0) {
    if (std::system(("chattr +i '" + out.string() + "' 2>/dev/null").c_str()) != 0) {
      GTEST_SKIP() << "running as root and chattr +i is not permitted here: a read-only "
                      "folder cannot be made";
    }
    cleanup_.push_back("chattr -i '" + out.string() + "'");
  } else {
    fs::permissions(out, fs::perms::owner_read | fs::perms::owner_exec);
  }
  // Another run into it (more frames: its map would differ) must fail and change nothing.
  const RunResult second = Cairn(MapArgs(out, 4), root_ / "second.log");
  EXPECT_EQ(second.signal, 0) << second.output;
  EXPECT_EQ(second.status, 1) << second.output;
  EXPECT_NE(second.output.find(out.string()), std::string::npos) << second.output;
  EXPECT_TRUE(Files(out) == good) << "the last good map changed";
  if (::geteuid() == 0) {
    (void)std::system(("chattr -i '" + out.string() + "'").c_str());
    cleanup_.clear();
  } else {
    fs::permissions(out, fs::perms::owner_all);
  }
}

TEST_F(MapFaults, AFullOutputFolderFailsNamingItAndKeepsTheLastGoodMap) {
  // First the map's size, then a tmpfs that holds it once but not twice (a second run
  // stages all its files before it renames them over the first).
  const fs::path probe = root_ / "probe";
  const RunResult sized = Cairn(MapArgs(probe, 3), root_ / "probe.log");
  ASSERT_EQ(sized.status, 0) << sized.output;
  std::uintmax_t bytes = 0;
  for (const auto& [name, data] : Files(probe)) bytes += data.size();
  const fs::path mount = root_ / "small";
  fs::create_directories(mount);
  const std::uintmax_t size_kb = (bytes * 3 / 2) / 1024 + 16;
  const std::string command = "mount -t tmpfs -o size=" + std::to_string(size_kb) + "k tmpfs '" +
                              mount.string() + "' 2>/dev/null";
  if (std::system(command.c_str()) != 0) {
    GTEST_SKIP() << "cannot mount a small tmpfs here (needs root): no full disk to test with";
  }
  cleanup_.push_back("umount '" + mount.string() + "'");
  const fs::path out = mount / "out";
  const RunResult first = Cairn(MapArgs(out, 3), root_ / "first.log");
  ASSERT_EQ(first.status, 0) << first.output;
  const std::map<std::string, std::string> good = Files(out);

  const RunResult second = Cairn(MapArgs(out, 4), root_ / "second.log");
  EXPECT_EQ(second.signal, 0) << second.output;
  EXPECT_EQ(second.status, 1) << second.output;
  EXPECT_NE(second.output.find(out.string()), std::string::npos) << second.output;
  EXPECT_NE(second.output.find("No space left"), std::string::npos) << second.output;
  EXPECT_TRUE(Files(out) == good) << "the last good map changed";
  // Nothing of the failed run is left behind: the space is free again.
  std::vector<std::string> left;
  for (const fs::directory_entry& e : fs::directory_iterator(out)) {
    left.push_back(e.path().filename().string());
  }
  EXPECT_EQ(left.size(), good.size()) << "the failed run left files behind";
}

TEST_F(MapFaults, SigkillAtRandomPointsThenResumeGivesTheUninterruptedMap) {
  constexpr int kFrames = 8;
  const fs::path whole = root_ / "whole";
  std::vector<std::string> args = MapArgs(whole, kFrames);
  args.insert(args.end(), {"--checkpoint-every", "1"});
  const auto t0 = std::chrono::steady_clock::now();
  const RunResult once = Cairn(args, root_ / "whole.log");
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(once.status, 0) << once.output;
  const std::map<std::string, std::string> reference = Files(whole);

  // Kill points drawn uniformly over the run's length (seeded: the same points every time),
  // each run resuming from whatever the one before it saved.
  std::mt19937 random(13);
  std::uniform_real_distribution<double> when(0.1, 0.6);
  const fs::path parts = root_ / "parts";
  int kills = 0, resumes = 0;
  for (int attempt = 0; attempt < 40; ++attempt) {
    std::vector<std::string> run = MapArgs(parts, kFrames);
    run.insert(run.end(), {"--checkpoint-every", "1"});
    const bool resume = fs::exists(parts / "map.checkpoint");
    if (resume) {
      run.push_back("--resume");
      ++resumes;
    }
    const fs::path log = root_ / ("run" + std::to_string(attempt) + ".log");
    const pid_t pid = Start(run, log);
    if (kills < 6) {
      std::this_thread::sleep_for(std::chrono::duration<double>(when(random) * run_s));
      ::kill(pid, SIGKILL);
    }
    const RunResult r = Wait(pid, log);
    if (r.signal == SIGKILL) {
      ++kills;
      continue;
    }
    ASSERT_EQ(r.status, 0) << "attempt " << attempt << (resume ? " (--resume)" : "") << "\n"
                           << r.output;
    break;  // finished before the kill, or not killed
  }
  EXPECT_GT(kills, 0);
  ASSERT_TRUE(fs::exists(parts / "map.bt"));
  EXPECT_FALSE(fs::exists(parts / "map.checkpoint"));
  EXPECT_FALSE(fs::exists(parts / "map.checkpoint.records"));
  const std::map<std::string, std::string> resumed = Files(parts);
  for (const char* name : {"map.bt", "map.ot", "obstacles.ot", "cost.pgm", "cost.yaml",
                           "elevation.tiff", "obstacles.json", "poses.tum"}) {
    ASSERT_TRUE(reference.count(name)) << name;
    EXPECT_TRUE(resumed.count(name) && resumed.at(name) == reference.at(name))
        << name << " differs after " << kills << " kills and " << resumes << " resumes";
  }
  std::cout << kills << " kills, " << resumes << " resumes\n";
}

}  // namespace
}  // namespace cairn
