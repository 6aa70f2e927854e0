// The malformed-input corpus: hundreds of broken files across every format cairn reads,
// each fed to the built `cairn` command the way a user would. Every case must end with exit
// status 1 and a message that names the file and the field, key, line or offset at fault;
// never a crash, a hang (each run has a time limit), another status, or a sanitizer report
// (when the suite runs under ASan/UBSan, .ci/run).
//
// The cases are generated here from small valid inputs (made by the test or bundled in the
// repository) by one mutation each: a key removed, a value of the wrong type or outside its
// physical range, a file truncated or with bytes flipped. Inputs that fuzzing found are
// kept under tests/data/malformed/ (one file per finding, named by its format) and run
// too. Each format is one test; a case failing names itself.
#include <bzlib.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "io/temp_dir.hpp"
#include "io/cairn_command.hpp"

#ifndef CAIRN_EXE
#error "CAIRN_EXE must name the cairn executable"
#endif
#ifndef CAIRN_SOURCE_DIR
#error "CAIRN_SOURCE_DIR must name the source tree"
#endif

namespace cairn {
namespace {

namespace fs = std::filesystem;

const fs::path kSource = CAIRN_SOURCE_DIR;

using test::ReadFile;

void WriteFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

using test::ShellQuote;

struct RunResult {
  int status = -1;      ///< exit status; -1 when killed by a signal
  int signal = 0;       ///< the signal, when killed
  std::string output;   ///< stdout and stderr
};

/// Runs cairn with `args` under a 120 s limit (timeout(1) kills a hang: status 124/137).
RunResult Cairn(const std::vector<std::string>& args, const fs::path& scratch) {
  std::string command = "timeout -s KILL 120 " + ShellQuote(CAIRN_EXE);
  for (const std::string& a : args) command += " " + ShellQuote(a);
  const fs::path out = scratch / "output.txt";
  command += " >" + ShellQuote(out.string()) + " 2>&1";
  const int raw = std::system(command.c_str());
  RunResult run;
  if (WIFEXITED(raw)) run.status = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) run.signal = WTERMSIG(raw);
  run.output = ReadFile(out);
  return run;
}

/// Runs `cairn <args>` and interrupts it (SIGINT, as Ctrl-C does) as soon as `watched`
/// exists: a run stopped part-way.
RunResult CairnInterruptedOnceThere(const std::vector<std::string>& args, const fs::path& watched,
                                    const fs::path& scratch) {
  std::string command = ShellQuote(CAIRN_EXE);
  for (const std::string& a : args) command += " " + ShellQuote(a);
  const fs::path out = scratch / "output.txt";
  const std::string script = command + " >" + ShellQuote(out.string()) + " 2>&1 & pid=$!; " +
                             "while kill -0 $pid 2>/dev/null && [ ! -e " +
                             ShellQuote(watched.string()) + " ]; do sleep 0.01; done; " +
                             "kill -INT $pid 2>/dev/null; wait $pid";
  const int raw = std::system(("timeout -s KILL 120 bash -c " + ShellQuote(script)).c_str());
  RunResult run;
  if (WIFEXITED(raw)) run.status = WEXITSTATUS(raw);
  if (WIFSIGNALED(raw)) run.signal = WTERMSIG(raw);
  run.output = ReadFile(out);
  return run;
}

/// One malformed input: the files to write (relative to the case's folder; "@" in a name
/// or a value is the folder), the command line, and what the message must contain.
struct Case {
  std::string name;
  std::map<std::string, std::string> files;
  std::vector<std::string> args;
  std::vector<std::string> expect;  ///< substrings of the output ("@" = the folder)
};

std::string Expand(std::string s, const fs::path& dir) {
  for (std::size_t at = s.find('@'); at != std::string::npos; at = s.find('@', at)) {
    s.replace(at, 1, dir.string());
    at += dir.string().size();
  }
  return s;
}

class Corpus : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("cairn_corpus_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
  }
  void TearDown() override {
    if (std::getenv("CAIRN_KEEP_TEST_DIRS") == nullptr) fs::remove_all(root_);
  }

  /// Runs every case, each in a folder of its own; returns how many ran.
  /// With CAIRN_CORPUS_LIST set, lists the cases instead (the corpus's size, quickly).
  int RunAll(const std::vector<Case>& cases) {
    if (std::getenv("CAIRN_CORPUS_LIST") != nullptr) {
      for (const Case& c : cases) std::cout << c.name << "\n";
      std::cout << cases.size() << " malformed inputs\n";
      return static_cast<int>(cases.size());
    }
    int index = 0;
    for (const Case& c : cases) {
      const fs::path dir = root_ / ("case" + std::to_string(index++));
      fs::create_directories(dir);
      for (const auto& [name, bytes] : c.files) WriteFile(Expand(name, dir), bytes);
      std::vector<std::string> args;
      for (const std::string& a : c.args) args.push_back(Expand(a, dir));
      const RunResult run = Cairn(args, dir);
      std::string command;
      for (const std::string& a : args) command += " " + a;
      const std::string what = c.name + " (cairn" + command + ")";
      EXPECT_EQ(run.signal, 0) << what << ": killed by signal " << run.signal << "\n"
                               << run.output;
      EXPECT_EQ(run.status, 1) << what << ": exit status " << run.status << "\n" << run.output;
      EXPECT_EQ(run.output.find("Sanitizer"), std::string::npos) << what << "\n" << run.output;
      EXPECT_EQ(run.output.find("runtime error"), std::string::npos) << what << "\n"
                                                                     << run.output;
      for (const std::string& e : c.expect) {
        const std::string want = Expand(e, dir);
        EXPECT_NE(run.output.find(want), std::string::npos)
            << what << ": the message does not contain '" << want << "':\n"
            << run.output;
      }
      fs::remove_all(dir);
    }
    std::cout << index << " malformed inputs\n";
    return index;
  }

  fs::path root_;
};

// ---- valid inputs, made small -------------------------------------------------------------

constexpr int kW = 32, kH = 24;

std::string Intrinsics(const std::string& extra = "", const std::string& skip = "") {
  const std::vector<std::pair<std::string, std::string>> keys = {
      {"width", "32"}, {"height", "24"}, {"fx", "30"},          {"fy", "30"},
      {"cx", "15.5"},  {"cy", "11.5"},   {"depth_scale", "0.001"}, {"pitch_deg", "10"}};
  std::string text;
  for (const auto& [k, v] : keys) {
    if (k != skip) text += k + ": " + v + "\n";
  }
  return text + extra;
}

// PNGs are assembled here byte by byte (zlib "stored" blocks, which every decoder reads),
// so that their headers can lie: sizes, bit depths and CRCs are the mutations.
std::uint32_t Crc32(const std::string& bytes) {
  static std::uint32_t table[256];
  static bool made = false;
  if (!made) {
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = c & 1 ? 0xedb88320u ^ (c >> 1) : c >> 1;
      table[n] = c;
    }
    made = true;
  }
  std::uint32_t c = 0xffffffffu;
  for (const unsigned char b : bytes) c = table[(c ^ b) & 0xff] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

std::string Be32(std::uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8),
          static_cast<char>(v)};
}

std::string Chunk(const std::string& type, const std::string& data) {
  return Be32(static_cast<std::uint32_t>(data.size())) + type + data + Be32(Crc32(type + data));
}

/// zlib stream of `raw` in stored (uncompressed) blocks.
std::string ZlibStored(const std::string& raw) {
  std::string z = "\x78\x01";
  std::size_t at = 0;
  do {
    const std::size_t n = std::min<std::size_t>(65535, raw.size() - at);
    const bool last = at + n == raw.size();
    z += static_cast<char>(last ? 1 : 0);
    z += static_cast<char>(n & 0xff);
    z += static_cast<char>(n >> 8);
    z += static_cast<char>(~n & 0xff);
    z += static_cast<char>((~n >> 8) & 0xff);
    z += raw.substr(at, n);
    at += n;
  } while (at < raw.size());
  std::uint32_t a = 1, b = 0;
  for (const unsigned char ch : raw) {
    a = (a + ch) % 65521;
    b = (b + a) % 65521;
  }
  return z + Be32((b << 16) | a);
}

/// A PNG of `width` x `height`, `bits` per sample, `channels` 1 or 3, every sample `value`.
/// `header_width` / `header_height`, when >= 0, are what IHDR claims instead.
std::string Png(int width, int height, int bits = 16, int channels = 1, int value = 3000,
                std::int64_t header_width = -1, std::int64_t header_height = -1) {
  const std::string signature = "\x89PNG\r\n\x1a\n";
  std::string ihdr =
      Be32(static_cast<std::uint32_t>(header_width >= 0 ? header_width : width)) +
      Be32(static_cast<std::uint32_t>(header_height >= 0 ? header_height : height));
  ihdr += static_cast<char>(bits);
  ihdr += static_cast<char>(channels == 3 ? 2 : 0);
  ihdr += std::string(3, '\0');
  std::string raw;
  const int bytes_per_sample = bits / 8;
  for (int r = 0; r < height; ++r) {
    raw += '\0';  // filter: none
    for (int c = 0; c < width * channels; ++c) {
      if (bytes_per_sample == 2) {
        raw += static_cast<char>(value >> 8);
        raw += static_cast<char>(value & 0xff);
      } else {
        raw += static_cast<char>(value & 0xff);
      }
    }
  }
  return signature + Chunk("IHDR", ihdr) + Chunk("IDAT", ZlibStored(raw)) + Chunk("IEND", "");
}

std::string Le32f(float v) {
  std::string s(4, '\0');
  std::memcpy(s.data(), &v, 4);
  return s;
}

/// A small LiDAR scan, ring after ring: 16 rings from +15 to -15 deg, 360 columns; ground
/// 1.5 m below, a wall 12 m ahead. KITTI .bin bytes.
std::string Scan() {
  std::string bin;
  for (int ring = 0; ring < 16; ++ring) {
    const double e = (15.0 - 2.0 * ring) * M_PI / 180.0;
    for (int col = 0; col < 360; ++col) {
      const double a = M_PI - col * M_PI / 180.0;
      double r = 30.0;
      if (e < 0) r = std::min(r, 1.5 / std::sin(-e));
      r = std::min(r, 12.0 / std::max(1e-3, std::cos(e) * std::abs(std::cos(a))));
      bin += Le32f(static_cast<float>(r * std::cos(e) * std::cos(a)));
      bin += Le32f(static_cast<float>(r * std::cos(e) * std::sin(a)));
      bin += Le32f(static_cast<float>(r * std::sin(e)));
      bin += Le32f(0.5f);
    }
  }
  return bin;
}

std::size_t ScanPoints() { return Scan().size() / 16; }

std::string Bzip2(const std::string& text) {
  std::vector<char> out(text.size() + text.size() / 50 + 1024);
  unsigned int length = static_cast<unsigned int>(out.size());
  std::string in = text;
  if (BZ2_bzBuffToBuffCompress(out.data(), &length, in.data(),
                               static_cast<unsigned int>(in.size()), 9, 0, 0) != BZ_OK) {
    return {};
  }
  return std::string(out.data(), length);
}

std::string XyzText(int points = 200) {
  std::string text;
  for (int i = 0; i < points; ++i) {
    const double a = i * 2.0 * M_PI / points;
    text += std::to_string(8.0 * std::cos(a)) + " " + std::to_string(8.0 * std::sin(a)) +
            " -1.5\n";
  }
  return text;
}

std::string PlyAscii(const std::string& header_extra = "", int points = 100) {
  std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(points) +
                     "\nproperty float x\nproperty float y\nproperty float z\n" + header_extra +
                     "end_header\n";
  for (int i = 0; i < points; ++i) {
    const double a = i * 2.0 * M_PI / points;
    text += std::to_string(8.0 * std::cos(a)) + " " + std::to_string(8.0 * std::sin(a)) +
            " -1.5\n";
  }
  return text;
}

std::string PlyBinary(int points = 100) {
  std::string text = "ply\nformat binary_little_endian 1.0\nelement vertex " +
                     std::to_string(points) +
                     "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  for (int i = 0; i < points; ++i) {
    const double a = i * 2.0 * M_PI / points;
    text += Le32f(static_cast<float>(8.0 * std::cos(a))) +
            Le32f(static_cast<float>(8.0 * std::sin(a))) + Le32f(-1.5f);
  }
  return text;
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) return "REPLACE FAILED: '" + from + "' not found";
  return text.replace(at, from.size(), to);
}

// ---- the formats ----------------------------------------------------------------------------

std::vector<std::string> DetectDepth() {
  return {"detect", "--depth", "@/depth.png", "--intrinsics", "@/camera.yaml", "--out", "@/out"};
}

TEST_F(Corpus, DepthImages) {
  std::vector<Case> cases;
  const std::string good = Png(kW, kH);
  auto depth_case = [&](const std::string& name, const std::string& bytes,
                        const std::string& expect) {
    cases.push_back({"depth: " + name,
                     {{"@/depth.png", bytes}, {"@/camera.yaml", Intrinsics()}},
                     DetectDepth(),
                     {"@/depth.png", expect}});
  };
  depth_case("empty file", "", "");
  depth_case("text, not an image", "width: 32\n", "");
  for (std::size_t cut : {std::size_t{4}, std::size_t{8}, std::size_t{12}, std::size_t{20},
                          std::size_t{33}, std::size_t{40}, good.size() / 2, good.size() - 12,
                          good.size() - 1}) {
    depth_case("truncated at byte " + std::to_string(cut), good.substr(0, cut), "");
  }
  depth_case("8-bit", Png(kW, kH, 8), "16-bit");
  depth_case("3 channels", Png(kW, kH, 16, 3), "16-bit");
  depth_case("wrong size", Png(kW + 1, kH), "width");
  depth_case("huge IHDR", Png(kW, kH, 16, 1, 3000, 1u << 30, 1u << 30), "IHDR");
  depth_case("zero IHDR", Png(kW, kH, 16, 1, 3000, 0, kH), "");
  {
    std::string flipped = good;
    flipped[good.size() / 2] ^= 0x5a;  // a byte of the pixel data: the CRC no longer holds
    depth_case("IDAT byte flipped", flipped, "");
  }
  {
    std::string bad_crc = good;
    bad_crc[33 - 1] ^= 0x01;  // IHDR's CRC
    depth_case("IHDR CRC wrong", bad_crc, "");
  }
  depth_case("TIFF signature only", std::string("II*\0", 4), "TIFF");
  depth_case("TIFF truncated", std::string("II*\0\x08\0\0\0\x0a\0", 10), "TIFF");
  depth_case("big-endian TIFF signature only", std::string("MM\0*", 4), "TIFF");
  cases.push_back({"depth: missing file",
                   {{"@/camera.yaml", Intrinsics()}},
                   DetectDepth(),
                   {"@/depth.png", "no such file"}});
  cases.push_back({"depth: a directory",
                   {{"@/depth.png/x", ""}, {"@/camera.yaml", Intrinsics()}},
                   DetectDepth(),
                   {"@/depth.png", "directory"}});
  EXPECT_GE(RunAll(cases), 20);
}

TEST_F(Corpus, IntrinsicsYaml) {
  std::vector<Case> cases;
  auto yaml_case = [&](const std::string& name, const std::string& yaml,
                       const std::string& field) {
    cases.push_back({"intrinsics: " + name,
                     {{"@/depth.png", Png(kW, kH)}, {"@/camera.yaml", yaml}},
                     DetectDepth(),
                     {"@/camera.yaml", field}});
  };
  for (const char* key : {"width", "height", "fx", "fy", "cx", "cy", "depth_scale"}) {
    yaml_case(std::string("missing ") + key, Intrinsics("", key), key);
    yaml_case(std::string(key) + " not a number",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": abc #"), key);
    yaml_case(std::string(key) + " a sequence",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": [1, 2] #"),
              key);
  }
  for (const char* key : {"fx", "fy", "depth_scale"}) {
    yaml_case(std::string(key) + " zero",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": 0 #"), key);
    yaml_case(std::string(key) + " negative",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": -3 #"), key);
    yaml_case(std::string(key) + " infinite",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": .inf #"), key);
    yaml_case(std::string(key) + " NaN",
              Replace(Intrinsics(), std::string(key) + ": ", std::string(key) + ": .nan #"), key);
  }
  yaml_case("width zero", Replace(Intrinsics(), "width: 32", "width: 0"), "width");
  yaml_case("width negative", Replace(Intrinsics(), "width: 32", "width: -32"), "width");
  yaml_case("width fractional", Replace(Intrinsics(), "width: 32", "width: 32.5"), "width");
  yaml_case("width beyond the limit", Replace(Intrinsics(), "width: 32", "width: 100000"),
            "width");
  yaml_case("height beyond int", Replace(Intrinsics(), "height: 24", "height: 99999999999"),
            "height");
  yaml_case("pixels beyond the limit",
            Replace(Replace(Intrinsics(), "width: 32", "width: 16000"), "height: 24",
                    "height: 16000"),
            "pixels");
  yaml_case("fx beyond 1e6 px", Replace(Intrinsics(), "fx: 30", "fx: 1e9"), "fx");
  yaml_case("cx far outside the image", Replace(Intrinsics(), "cx: 15.5", "cx: 3200"), "cx");
  yaml_case("cy far outside the image", Replace(Intrinsics(), "cy: 11.5", "cy: -240"), "cy");
  yaml_case("depth_scale in millimetres", Replace(Intrinsics(), "depth_scale: 0.001", "depth_scale: 5"),
            "depth_scale");
  yaml_case("pitch_deg 400", Replace(Intrinsics(), "pitch_deg: 10", "pitch_deg: 400"),
            "pitch_deg");
  yaml_case("pitch_deg -91", Replace(Intrinsics(), "pitch_deg: 10", "pitch_deg: -91"),
            "pitch_deg");
  yaml_case("roll_deg 200", Intrinsics("roll_deg: 200\n"), "roll_deg");
  yaml_case("roll_deg not a number", Intrinsics("roll_deg: left\n"), "roll_deg");
  yaml_case("roll without pitch", Intrinsics("roll_deg: 3\n", "pitch_deg"), "pitch_deg");
  yaml_case("no up and no pitch", Intrinsics("", "pitch_deg"), "up");
  yaml_case("up and pitch", Intrinsics("up: [0, -1, 0]\n"), "pitch_deg");
  yaml_case("up zero", Intrinsics("up: [0, 0, 0]\n", "pitch_deg"), "up");
  yaml_case("up of two", Intrinsics("up: [0, -1]\n", "pitch_deg"), "up");
  yaml_case("up not numbers", Intrinsics("up: [a, b, c]\n", "pitch_deg"), "up[0]");
  yaml_case("up a mapping", Intrinsics("up: {x: 1}\n", "pitch_deg"), "up");
  yaml_case("unknown key", Intrinsics("focal: 30\n"), "focal");
  yaml_case("key twice", Intrinsics("fx: 31\n"), "fx");
  yaml_case("YAML syntax error", Intrinsics("fy: [1, 2\n"), "camera.yaml:");
  yaml_case("tab indentation", "width: 32\n\theight: 24\n", "camera.yaml:");
  yaml_case("empty file", "", "camera.yaml");
  yaml_case("a sequence", "- 1\n- 2\n", "mapping");
  yaml_case("a scalar", "hello\n", "mapping");
  yaml_case("binary garbage", std::string("\x00\xff\xfe\x01", 4), "camera.yaml");
  cases.push_back({"intrinsics: missing file",
                   {{"@/depth.png", Png(kW, kH)}},
                   DetectDepth(),
                   {"@/camera.yaml", "no such file"}});
  EXPECT_GE(RunAll(cases), 60);
}

/// The settings file (--config): every section's keys, a wrong type and a value out of
/// range, through `cairn detect` on a valid depth frame.
TEST_F(Corpus, SettingsYaml) {
  std::vector<Case> cases;
  auto settings_case = [&](const std::string& name, const std::string& yaml,
                           const std::string& field) {
    std::vector<std::string> args = DetectDepth();
    args.insert(args.end(), {"--config", "@/settings.yaml"});
    cases.push_back({"settings: " + name,
                     {{"@/depth.png", Png(kW, kH)},
                      {"@/camera.yaml", Intrinsics()},
                      {"@/settings.yaml", yaml}},
                     args,
                     {"@/settings.yaml", field}});
  };
  const std::vector<std::pair<std::string, std::string>> out_of_range = {
      {"detector.min_height", "-0.3"},  {"detector.max_height", "0.1"},
      {"detector.max_height", "500"},   {"detector.min_slope", "0"},
      {"detector.min_slope", "90"},     {"detector.min_slope", "400"},
      {"detector.window_scale", "0"},   {"detector.window_scale", "1e6"},
      {"detector.region_slabs", "0"},   {"detector.region_slabs", "65"},
      {"detector.threads", "-1"},       {"detector.threads", "100000"},
      {"detector.min_range", "-1"},     {"detector.min_range", "1e5"},
      {"detector.search", "everywhere"}, {"rules.min_points", "-1"},
      {"rules.min_volume", "-0.1"},     {"rules.min_perimeter", "-2"},
      {"rules.min_slope_mean", "-5"},   {"rules.min_slope_mean", "120"},
      {"rules.min_slope_max", "400"},   {"rules.min_height_mean", "-1"},
      {"rules.min_height_max", ".nan"}, {"rules.min_raised", "-4"},
      {"column.min_blob_pixels", "-1"}, {"stereo.min_depth", "-1"},
      {"stereo.num_disparities", "7"},  {"stereo.block_size", "4"},
      {"stereo.block_size", "0"},       {"stereo.uniqueness", "-5"},
      {"stereo.mode", "fastest"},       {"stereo.disparity_sigma", "-1"},
      {"stereo.speckle_window", "-1"},  {"stereo.max_depth", "-3"},
  };
  for (const auto& [field, value] : out_of_range) {
    const std::string section = field.substr(0, field.find('.'));
    const std::string key = field.substr(field.find('.') + 1);
    settings_case(field + " = " + value, section + ":\n  " + key + ": " + value + "\n", key);
  }
  for (const char* field :
       {"detector.min_height", "detector.max_height", "detector.min_slope",
        "detector.window_scale", "detector.region_slabs", "detector.threads",
        "detector.min_range", "rules.min_points", "rules.min_volume", "rules.min_slope_mean",
        "rules.min_raised", "column.min_blob_pixels", "stereo.min_depth", "stereo.p1"}) {
    const std::string f = field;
    const std::string section = f.substr(0, f.find('.'));
    const std::string key = f.substr(f.find('.') + 1);
    settings_case(f + " not a number", section + ":\n  " + key + ": [1, 2]\n", key);
  }
  settings_case("unknown section", "detectr:\n  min_height: 0.3\n", "detectr");
  settings_case("unknown key", "detector:\n  min_hieght: 0.3\n", "min_hieght");
  settings_case("section a scalar", "detector: 3\n", "detector");
  settings_case("key twice", "detector:\n  min_height: 0.3\n  min_height: 0.4\n", "min_height");
  settings_case("YAML syntax error", "detector:\n  min_height: [0.3\n", "settings.yaml:");
  settings_case("a sequence", "- detector\n", "settings.yaml");
  settings_case("integer overflow", "detector:\n  threads: 99999999999999999999\n", "threads");
  EXPECT_GE(RunAll(cases), 50);
}

/// The map section of the settings, through `cairn map` on the bundled drive.
TEST_F(Corpus, MapSettingsYaml) {
  std::vector<Case> cases;
  const std::string rawlog =
      (kSource / "datasets" / "sequences" / "hill_drive" / "sequence.rawlog").string();
  auto map_case = [&](const std::string& key, const std::string& value) {
    cases.push_back({"map settings: " + key + " = " + value,
                     {{"@/settings.yaml", "map:\n  " + key + ": " + value + "\n"}},
                     {"map", "--rawlog", rawlog, "--config", "@/settings.yaml", "--out", "@/out"},
                     {"@/settings.yaml", "map." + key}});
  };
  map_case("voxel_size", "0");
  map_case("voxel_size", "100");
  map_case("max_range", "-1");
  map_case("max_range", "1e7");
  map_case("voxel_hit", "0.3");
  map_case("voxel_miss", "0.7");
  map_case("cell_size", "0");
  map_case("cell_size", "1e-9");
  map_case("window_size", "0.1");
  map_case("window_size", "1e6");
  map_case("cell_hit", "1.5");
  map_case("obstacle_probability", "0.99");
  map_case("ground_max_slope", "90");
  map_case("slope_cost_max", "-10");
  map_case("plane_fit_radius", "1000");
  map_case("inflation_radius", "0.1");
  map_case("inflation_radius", "1000");
  map_case("robot_radius", "-0.5");
  map_case("cost_scaling_factor", "abc");
  map_case("voxel_size", ".nan");
  map_case("typo_key", "1");
  EXPECT_GE(RunAll(cases), 20);
}

std::vector<std::string> DetectPoints(const std::string& file) {
  return {"detect", "--points", "@/" + file, "--sensor", "VLP-16", "--out", "@/out"};
}

TEST_F(Corpus, PointFiles) {
  std::vector<Case> cases;
  auto points_case = [&](const std::string& name, const std::string& file,
                         const std::string& bytes, const std::string& expect) {
    cases.push_back({"points: " + name, {{"@/" + file, bytes}}, DetectPoints(file),
                     {"@/" + file, expect}});
  };
  const std::string bin = Scan();
  // KITTI .bin
  points_case("bin empty", "scan.bin", "", "empty");
  for (std::size_t cut : {std::size_t{1}, std::size_t{15}, std::size_t{17}, bin.size() - 1,
                          bin.size() - 5, bin.size() / 2 + 3}) {
    points_case("bin truncated to " + std::to_string(cut) + " bytes", "scan.bin",
                bin.substr(0, cut), "offset");
  }
  {
    std::string nan = bin;
    const float v = std::nanf("");
    std::memcpy(nan.data() + 16 * 7 + 4, &v, 4);  // y of point 7
    points_case("bin NaN coordinate", "scan.bin", nan, "point 7");
    std::string inf = bin;
    const float i = INFINITY;
    std::memcpy(inf.data() + 16 * 9 + 12, &i, 4);  // intensity of point 9
    points_case("bin infinite intensity", "scan.bin", inf, "point 9");
  }
  points_case("bin of text", "scan.bin", "1 2 3\n4 5 6\n", "multiple of 16");
  // PLY
  points_case("ply empty", "scan.ply", "", "");
  points_case("ply no magic", "scan.ply", Replace(PlyAscii(), "ply\n", "plx\n"), "");
  points_case("ply bad format", "scan.ply",
              Replace(PlyAscii(), "format ascii 1.0", "format ascii 2.0"), "line 2");
  points_case("ply unknown format", "scan.ply",
              Replace(PlyAscii(), "format ascii 1.0", "format utf8 1.0"), "line 2");
  points_case("ply big-endian", "scan.ply",
              Replace(PlyBinary(), "binary_little_endian", "binary_big_endian"), "big");
  points_case("ply no x", "scan.ply", Replace(PlyAscii(), "property float x\n", ""), "x");
  points_case("ply no z", "scan.ply", Replace(PlyAscii(), "property float z\n", ""), "z");
  points_case("ply no vertex element", "scan.ply",
              Replace(PlyAscii(), "element vertex 100", "element face 100"), "vertex");
  points_case("ply vertex count 0", "scan.ply",
              Replace(PlyAscii(), "element vertex 100", "element vertex 0"), "vertex");
  points_case("ply vertex count negative", "scan.ply",
              Replace(PlyAscii(), "element vertex 100", "element vertex -5"), "line 3");
  points_case("ply vertex count huge", "scan.ply",
              Replace(PlyAscii(), "element vertex 100", "element vertex 99999999999999"),
              "line 3");
  points_case("ply vertex count beyond the limit (binary)", "scan.ply",
              Replace(PlyBinary(), "element vertex 100", "element vertex 20000000"), "line 3");
  points_case("ply vertex count not a number", "scan.ply",
              Replace(PlyAscii(), "element vertex 100", "element vertex many"), "line 3");
  points_case("ply unknown property type", "scan.ply",
              Replace(PlyAscii(), "property float y", "property quaternion y"), "line 5");
  points_case("ply list in vertex", "scan.ply",
              Replace(PlyAscii(), "end_header", "property list uchar int idx\nend_header"),
              "list");
  points_case("ply no end_header", "scan.ply", Replace(PlyAscii(), "end_header\n", ""), "");
  points_case("ply ascii short line", "scan.ply", Replace(PlyAscii(), "-1.5\n", "\n"),
              "line 8");
  points_case("ply ascii not a number", "scan.ply", Replace(PlyAscii(), "-1.5\n", "zz\n"),
              "line 8");
  points_case("ply ascii fewer vertices", "scan.ply", PlyAscii().substr(0, PlyAscii().size() / 2),
              "vertices");
  points_case("ply ascii NaN", "scan.ply", Replace(PlyAscii(), "-1.5\n", "nan\n"), "line 8");
  points_case("ply ring out of range", "scan.ply",
              Replace(PlyAscii("property float ring\n", 1), "-1.5\n", "-1.5 70000\n"),
              "ring");
  const std::string ply_bin = PlyBinary();
  for (std::size_t cut : {ply_bin.size() - 1, ply_bin.size() - 12, ply_bin.size() - 700}) {
    points_case("ply binary truncated to " + std::to_string(cut), "scan.ply",
                ply_bin.substr(0, cut), "truncated");
  }
  {
    std::string nan = ply_bin;
    const float v = std::nanf("");
    std::memcpy(nan.data() + ply_bin.find("end_header\n") + 11 + 12 * 3, &v, 4);
    points_case("ply binary NaN x", "scan.ply", nan, "vertex 3");
  }
  // Text
  points_case("text empty", "scan.txt", "", "empty");
  points_case("text comments only", "scan.txt", "# nothing\n# here\n", "no points");
  points_case("text two values", "scan.txt", "1 2 3\n4 5\n", "line 2");
  points_case("text five values", "scan.txt", "1 2 3 4 5\n", "line 1");
  points_case("text not a number", "scan.txt", "1 2 3\n1 x 3\n", "line 2");
  points_case("text infinity", "scan.txt", "1 2 3\n1 inf 3\n", "line 2");
  points_case("text binary", "scan.txt", std::string("\x01\x02\x03\x00\xff", 5), "line 1");
  points_case("unknown extension", "scan.xyzw", XyzText(), "");
  // bzip2
  const std::string bz = Bzip2(XyzText());
  ASSERT_FALSE(bz.empty());
  points_case("bz2 not bzip2", "scan.txt.bz2", XyzText(), "bzip2");
  points_case("bz2 empty", "scan.txt.bz2", "", "empty");
  for (std::size_t cut : {std::size_t{3}, std::size_t{10}, bz.size() / 2, bz.size() - 1}) {
    points_case("bz2 truncated to " + std::to_string(cut), "scan.txt.bz2", bz.substr(0, cut),
                "bzip2");
  }
  {
    std::string flipped = bz;
    flipped[bz.size() / 2] ^= 0x55;
    points_case("bz2 byte flipped", "scan.txt.bz2", flipped, "bzip2");
  }
  points_case("bz2 of a bad text", "scan.txt.bz2", Bzip2("1 2 3\n1 2\n"), "line 2");
  points_case("bz2 then garbage", "scan.txt.bz2", bz + "garbage", "bzip2");
  cases.push_back({"points: missing file", {}, DetectPoints("nothing.bin"),
                   {"@/nothing.bin", "no such file"}});
  EXPECT_GE(RunAll(cases), 50);
}

TEST_F(Corpus, SemanticKittiLabels) {
  std::vector<Case> cases;
  const std::string classes = (kSource / "config" / "classes" / "rellis3d.yaml").string();
  const std::size_t n = ScanPoints();
  auto labels_case = [&](const std::string& name, const std::string& labels,
                         const std::string& expect) {
    cases.push_back({"labels: " + name,
                     {{"@/scan.bin", Scan()}, {"@/scan.label", labels}},
                     {"eval", "--points", "@/scan.bin", "--labels", "@/scan.label", "--classes",
                      classes, "--sensor", "VLP-16", "--report", "@/report"},
                     {"@/scan.label", expect}});
  };
  std::string good(n * 4, '\0');
  for (std::size_t i = 0; i < n; ++i) good[i * 4] = 1;  // class 1
  labels_case("empty", "", "");
  labels_case("one label short", good.substr(0, good.size() - 4), "");
  labels_case("one label more", good + std::string(4, '\0'), "");
  labels_case("size not a multiple of 4", good.substr(0, good.size() - 2), "multiple of 4");
  {
    std::string unknown = good;
    unknown[40] = static_cast<char>(0xee);  // class 238 of point 10: not in the mapping
    unknown[41] = static_cast<char>(0x7e);
    labels_case("unlisted class", unknown, "");
  }
  // The class mapping itself.
  auto classes_case = [&](const std::string& name, const std::string& yaml,
                          const std::string& expect) {
    cases.push_back({"classes: " + name,
                     {{"@/scan.bin", Scan()}, {"@/scan.label", good}, {"@/classes.yaml", yaml}},
                     {"eval", "--points", "@/scan.bin", "--labels", "@/scan.label", "--classes",
                      "@/classes.yaml", "--sensor", "VLP-16", "--report", "@/report"},
                     {"@/classes.yaml", expect}});
  };
  classes_case("empty", "", "");
  classes_case("no classes", "dataset: test\n", "classes");
  classes_case("bad role",
               "classes:\n  0: {name: void, role: ignored}\n  1: {name: dirt, role: drivable}\n",
               "role");
  classes_case("id not a number", "classes:\n  zero: {name: void, role: ignored}\n", "zero");
  classes_case("id negative", "classes:\n  -1: {name: void, role: ignored}\n", "-1");
  classes_case("colour of two", "classes:\n  1: {name: dirt, role: ground, color: [1, 2]}\n",
               "color");
  classes_case("colour beyond 255",
               "classes:\n  1: {name: dirt, role: ground, color: [1, 2, 300]}\n", "color");
  classes_case("unknown key in a class",
               "classes:\n  1: {name: dirt, role: ground, colour: [1, 2, 3]}\n", "colour");
  classes_case("YAML syntax error", "classes:\n  1: {name: dirt, role: ground\n",
               "classes.yaml:");
  EXPECT_GE(RunAll(cases), 10);
}

std::string KittiCalib() {
  std::string calib;
  for (const char* key : {"P0", "P1", "P2", "P3"}) {
    calib += std::string(key) + ": 700 0 600 0 0 700 180 0 0 0 1 0\n";
  }
  return calib + "Tr: 0 -1 0 0 0 0 -1 -0.08 1 0 0 -0.27\n";
}

std::string KittiPoses(int frames) {
  std::string poses;
  for (int i = 0; i < frames; ++i) {
    poses += "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(0.8 * i) + "\n";
  }
  return poses;
}

std::string KittiTimes(int frames) {
  std::string times;
  for (int i = 0; i < frames; ++i) times += std::to_string(0.1 * i) + "\n";
  return times;
}

TEST_F(Corpus, KittiSequences) {
  std::vector<Case> cases;
  auto kitti_case = [&](const std::string& name, std::map<std::string, std::string> files,
                        const std::string& file, const std::string& expect) {
    std::map<std::string, std::string> all = {{"@/seq/velodyne/000000.bin", Scan()},
                                              {"@/seq/velodyne/000001.bin", Scan()},
                                              {"@/seq/calib.txt", KittiCalib()},
                                              {"@/seq/times.txt", KittiTimes(2)},
                                              {"@/seq/poses.txt", KittiPoses(2)}};
    for (auto& [k, v] : files) all[k] = v;
    for (auto it = all.begin(); it != all.end();) {
      it = it->second == "<none>" ? all.erase(it) : std::next(it);
    }
    cases.push_back({"kitti: " + name, all,
                     {"detect", "--kitti", "@/seq", "--sensor", "VLP-16", "--out", "@/out"},
                     {"@/seq/" + file, expect}});
  };
  kitti_case("calib missing", {{"@/seq/calib.txt", "<none>"}}, "calib.txt", "");
  kitti_case("calib empty", {{"@/seq/calib.txt", ""}}, "calib.txt", "P0");
  for (const char* key : {"P0", "P1", "P2", "P3", "Tr"}) {
    std::string calib;
    std::istringstream in(KittiCalib());
    for (std::string line; std::getline(in, line);) {
      if (line.rfind(std::string(key) + ":", 0) != 0) calib += line + "\n";
    }
    kitti_case(std::string("calib without ") + key, {{"@/seq/calib.txt", calib}}, "calib.txt",
               key);
    kitti_case(std::string("calib ") + key + " of 11 numbers",
               {{"@/seq/calib.txt",
                 Replace(KittiCalib(), std::string(key) + (key[0] == 'T' ? ": 0 " : ": 700 "),
                         std::string(key) + ": ")}},
               "calib.txt", key);
  }
  kitti_case("calib Tr not a rotation",
             {{"@/seq/calib.txt", Replace(KittiCalib(), "Tr: 0 -1 0", "Tr: 0 -2 0")}},
             "calib.txt", "Tr");
  kitti_case("calib a number is text",
             {{"@/seq/calib.txt", Replace(KittiCalib(), "P1: 700", "P1: seven")}}, "calib.txt",
             "P1");
  kitti_case("calib line without key",
             {{"@/seq/calib.txt", KittiCalib() + "1 2 3\n"}}, "calib.txt", "line 6");
  kitti_case("times missing", {{"@/seq/times.txt", "<none>"}}, "times.txt", "");
  kitti_case("times empty", {{"@/seq/times.txt", ""}}, "times.txt", "");
  kitti_case("times one line short", {{"@/seq/times.txt", KittiTimes(1)}}, "times.txt", "");
  kitti_case("times not a number", {{"@/seq/times.txt", "0.0\nsoon\n"}}, "times.txt", "line 2");
  kitti_case("times going back", {{"@/seq/times.txt", "0.5\n0.1\n"}}, "times.txt", "line 2");
  kitti_case("times two per line", {{"@/seq/times.txt", "0.0 0.1\n0.2\n"}}, "times.txt",
             "line 1");
  kitti_case("times infinite", {{"@/seq/times.txt", "0.0\ninf\n"}}, "times.txt", "line 2");
  kitti_case("poses empty", {{"@/seq/poses.txt", ""}}, "poses.txt", "");
  kitti_case("poses one line short", {{"@/seq/poses.txt", KittiPoses(1)}}, "poses.txt", "");
  kitti_case("poses 11 numbers", {{"@/seq/poses.txt", "1 0 0 0 0 1 0 0 0 0 1\n" + KittiPoses(1)}},
             "poses.txt", "line 1");
  kitti_case("poses 13 numbers",
             {{"@/seq/poses.txt", KittiPoses(1) + "1 0 0 0 0 1 0 0 0 0 1 0 5\n"}}, "poses.txt",
             "line 2");
  kitti_case("poses not a rotation",
             {{"@/seq/poses.txt", KittiPoses(1) + "2 0 0 0 0 1 0 0 0 0 1 0\n"}}, "poses.txt",
             "line 2");
  kitti_case("poses text", {{"@/seq/poses.txt", KittiPoses(1) + "identity\n"}}, "poses.txt",
             "line 2");
  kitti_case("poses NaN", {{"@/seq/poses.txt", KittiPoses(1) + "1 0 0 nan 0 1 0 0 0 0 1 0\n"}},
             "poses.txt", "line 2");
  kitti_case("scan truncated",
             {{"@/seq/velodyne/000001.bin", Scan().substr(0, 16 * 100 + 7)}},
             "velodyne/000001.bin", "offset");
  kitti_case("scan empty", {{"@/seq/velodyne/000001.bin", ""}}, "velodyne/000001.bin", "empty");
  kitti_case("no velodyne folder",
             {{"@/seq/velodyne/000000.bin", "<none>"}, {"@/seq/velodyne/000001.bin", "<none>"},
              {"@/seq/velodyne.txt", ""}},
             "velodyne", "");
  kitti_case("scan name not a number",
             {{"@/seq/velodyne/00000a.bin", Scan()}}, "velodyne/00000a.bin", "");
  EXPECT_GE(RunAll(cases), 30);
}

/// World files: `cairn synth --world` on a bundled world with one value broken.
TEST_F(Corpus, WorldYaml) {
  std::vector<Case> cases;
  const std::string base = ReadFile(kSource / "datasets" / "worlds" / "poles_and_rocks.yaml");
  const std::string drive = ReadFile(kSource / "datasets" / "sequences" / "hill_drive" / "world.yaml");
  auto world_case = [&](const std::string& name, const std::string& yaml,
                        const std::string& field) {
    cases.push_back({"world: " + name,
                     {{"@/world.yaml", yaml}},
                     {"synth", "--world", "@/world.yaml", "--out", "@/out"},
                     {"@/world.yaml", field}});
  };
  world_case("empty", "", "");
  world_case("a sequence", "- 1\n", "");
  world_case("YAML syntax error", base + "objects: [\n", "world.yaml:");
  world_case("unknown key", base + "weather: rain\n", "weather");
  world_case("seed text", Replace(base, "seed: 2", "seed: two"), "seed");
  world_case("terrain height text", Replace(base, "height: 0.0", "height: low"), "height");
  world_case("wave wavelength 0", Replace(base, "wavelength: 25", "wavelength: 0"),
             "wavelength");
  world_case("wave direction 1e9", Replace(base, "direction: 20", "direction: 1e9"),
             "direction");
  world_case("wave amplitude a list", Replace(base, "amplitude: 0.15", "amplitude: [1]"),
             "amplitude");
  world_case("view pitch 400", Replace(base, "pitch: 8}", "pitch: 400}"), "pitch");
  world_case("view pitch 90", Replace(base, "pitch: 8}", "pitch: 90}"), "pitch");
  world_case("view height 0", Replace(base, "height: 1.6, heading: 0", "height: 0, heading: 0"),
             "height");
  world_case("view heading 1000", Replace(base, "heading: 25", "heading: 1000"), "heading");
  world_case("view x missing",
             Replace(base, "{x: 0, y: 0, height: 1.6, heading: 0,", "{y: 0, height: 1.6, heading: 0,"),
             "views[0].x");
  world_case("views empty", Replace(base, "views:\n", "views: []\nviews_old:\n"), "");
  world_case("object kind unknown", Replace(base, "kind: pole, name: pole1", "kind: tower, name: pole1"),
             "kind");
  world_case("pole radius negative", Replace(base, "radius: 0.06", "radius: -0.06"), "radius");
  world_case("pole height text", Replace(base, "height: 1.6}", "height: tall}"), "height");
  world_case("rock radii of two", Replace(base, "radii: [0.2, 0.15, 0.12]", "radii: [0.2, 0.15]"),
             "radii");
  world_case("rock yaw 720", Replace(base, "yaw: 30", "yaw: 720"), "yaw");
  world_case("object obstacle not a bool", Replace(base, "obstacle: true, x: 6.0", "obstacle: maybe, x: 6.0"),
             "obstacle");
  world_case("object unknown key", Replace(base, "radius: 0.06", "radius: 0.06, colour: red"),
             "colour");
  world_case("object x infinite", Replace(base, "x: 6.0", "x: .inf"), "x");
  world_case("terrain slope 85", Replace(base, "height: 0.0\n", "height: 0.0\n  slope: 85\n"),
             "slope");
  world_case("camera width 1", "camera: {width: 1}\n" + base, "width");
  world_case("camera width 100000", "camera: {width: 100000}\n" + base, "width");
  world_case("camera hfov 180", "camera: {hfov: 180}\n" + base, "hfov");
  world_case("camera fx and hfov", "camera: {hfov: 60, fx: 100}\n" + base, "hfov");
  world_case("camera max_range 0", "camera: {max_range: 0}\n" + base, "max_range");
  world_case("camera noise dropout 1", "camera: {noise: {dropout_probability: 1}}\n" + base,
             "dropout_probability");
  world_case("lidar preset unknown", "lidar: {preset: HDL-128}\n" + base, "preset");
  world_case("lidar elevations rising", "lidar: {elevations: [-10, 0, 10]}\n" + base,
             "elevations");
  world_case("lidar azimuth_steps 0", "lidar: {preset: VLP-16, azimuth_steps: 0}\n" + base,
             "azimuth_steps");
  // The drive of the bundled sequence.
  world_case("drive frame_rate 0", Replace(drive, "frame_rate:", "frame_rate: 0 #"), "frame_rate");
  world_case("drive speed negative", Replace(drive, "speed:", "speed: -1 #"), "speed");
  world_case("drive sensor_pitch 95", Replace(drive, "sensor_pitch:", "sensor_pitch: 95 #"),
             "sensor_pitch");
  world_case("drive waypoint of three", Replace(drive, "waypoints: [", "waypoints: [[1, 2, 3], "),
             "waypoints[0]");
  world_case("drive imu_sigma negative", Replace(drive, "imu_sigma:", "imu_sigma: -1 #"),
             "imu_sigma");
  EXPECT_GE(RunAll(cases), 30);
}

TEST_F(Corpus, StereoCalibration) {
  std::vector<Case> cases;
  const std::string yaml =
      "width: 32\nheight: 24\nfx: 30\ncx: 15.5\ncy: 11.5\nbaseline: 0.12\npitch_deg: 5\n";
  auto stereo_case = [&](const std::string& name, const std::string& file,
                         const std::string& text, const std::string& expect) {
    cases.push_back({"stereo: " + name,
                     {{"@/left.png", Png(kW, kH, 8, 1, 100)},
                      {"@/right.png", Png(kW, kH, 8, 1, 100)},
                      {"@/" + file, text}},
                     {"detect", "--left", "@/left.png", "--right", "@/right.png",
                      "--stereo-calib", "@/" + file, "--out", "@/out"},
                     {"@/" + file, expect}});
  };
  stereo_case("yaml baseline 0", "rig.yaml", Replace(yaml, "baseline: 0.12", "baseline: 0"),
              "baseline");
  stereo_case("yaml baseline in mm", "rig.yaml",
              Replace(yaml, "baseline: 0.12", "baseline: 120"), "baseline");
  stereo_case("yaml baseline missing", "rig.yaml", Replace(yaml, "baseline: 0.12\n", ""),
              "baseline");
  stereo_case("yaml pitch 400", "rig.yaml", Replace(yaml, "pitch_deg: 5", "pitch_deg: 400"),
              "pitch_deg");
  stereo_case("yaml roll -100", "rig.yaml", yaml + "roll_deg: -100\n", "roll_deg");
  stereo_case("yaml fx missing", "rig.yaml", Replace(yaml, "fx: 30\n", ""), "fx");
  stereo_case("yaml fx negative", "rig.yaml", Replace(yaml, "fx: 30", "fx: -30"), "fx");
  stereo_case("yaml cx far out", "rig.yaml", Replace(yaml, "cx: 15.5", "cx: 9999"), "cx");
  stereo_case("yaml width 0", "rig.yaml", Replace(yaml, "width: 32", "width: 0"), "width");
  stereo_case("yaml unknown key", "rig.yaml", yaml + "focal: 3\n", "focal");
  stereo_case("yaml up and pitch", "rig.yaml", yaml + "up: [0, -1, 0]\n", "pitch_deg");
  cases.push_back({"stereo: yaml size differs from the images",
                   {{"@/left.png", Png(kW, kH, 8, 1, 100)},
                    {"@/right.png", Png(kW, kH, 8, 1, 100)},
                    {"@/rig.yaml", Replace(yaml, "width: 32", "width: 64")}},
                   {"detect", "--left", "@/left.png", "--right", "@/right.png", "--stereo-calib",
                    "@/rig.yaml", "--out", "@/out"},
                   {"@/left.png", "64x24"}});
  stereo_case("K.txt of 8 numbers", "K.txt", "30 0 15.5 0 30 11.5 0 0\n0.12\n", "");
  stereo_case("K.txt without baseline", "K.txt", "30 0 15.5 0 30 11.5 0 0 1\n", "");
  stereo_case("K.txt negative baseline", "K.txt", "30 0 15.5 0 30 11.5 0 0 1\n-0.12\n",
              "baseline");
  stereo_case("K.txt text", "K.txt", "30 0 15.5 0 thirty 11.5 0 0 1\n0.12\n",
              "not a stereo calibration");
  const std::string opencv =
      "%YAML:1.0\n---\nimage_width: 32\nimage_height: 24\n"
      "M1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [30, 0, 15.5, 0, 30, "
      "11.5, 0, 0, 1]\n"
      "D1: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [0, 0, 0, 0, 0]\n"
      "M2: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [30, 0, 15.5, 0, 30, "
      "11.5, 0, 0, 1]\n"
      "D2: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [0, 0, 0, 0, 0]\n"
      "R: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1, 0, 0, 0, 1, 0, 0, 0, "
      "1]\n"
      "T: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [-0.12, 0, 0]\n";
  stereo_case("opencv without M2", "rig_cv.yaml", Replace(opencv, "M2:", "X2:"), "M2");
  stereo_case("opencv without T", "rig_cv.yaml", Replace(opencv, "T:", "U:"), "T");
  stereo_case("opencv M1 of 2x2", "rig_cv.yaml",
              Replace(opencv, "   rows: 3\n   cols: 3\n   dt: d\n   data: [30, 0, 15.5, 0, 30, "
                              "11.5, 0, 0, 1]\nD1",
                      "   rows: 2\n   cols: 2\n   dt: d\n   data: [30, 0, 0, 30]\nD1"),
              "M1");
  stereo_case("opencv R not a rotation", "rig_cv.yaml",
              Replace(opencv, "data: [1, 0, 0, 0, 1, 0, 0, 0, 1]", "data: [2, 0, 0, 0, 1, 0, 0, 0, 1]"),
              "R");
  stereo_case("opencv no image size", "rig_cv.yaml",
              Replace(Replace(opencv, "image_width: 32\n", ""), "image_height: 24\n", ""),
              "image_width");
  stereo_case("opencv truncated", "rig_cv.yaml", opencv.substr(0, opencv.size() / 2), "");
  cases.push_back({"stereo: right image corrupt",
                   {{"@/left.png", Png(kW, kH, 8, 1, 100)},
                    {"@/right.png", Png(kW, kH, 8, 1, 100).substr(0, 50)},
                    {"@/rig.yaml", yaml}},
                   {"detect", "--left", "@/left.png", "--right", "@/right.png", "--stereo-calib",
                    "@/rig.yaml", "--out", "@/out"},
                   {"@/right.png"}});
  cases.push_back({"stereo: right image of another size",
                   {{"@/left.png", Png(kW, kH, 8, 1, 100)},
                    {"@/right.png", Png(kW + 2, kH, 8, 1, 100)},
                    {"@/rig.yaml", yaml}},
                   {"detect", "--left", "@/left.png", "--right", "@/right.png", "--stereo-calib",
                    "@/rig.yaml", "--out", "@/out"},
                   {"@/right.png"}});
  EXPECT_GE(RunAll(cases), 20);
}

/// MRPT rawlogs, truncated or with bytes flipped, through `cairn info` and `cairn detect`.
TEST_F(Corpus, Rawlogs) {
  std::vector<Case> cases;
  const std::string good =
      ReadFile(kSource / "datasets" / "sequences" / "hill_drive" / "sequence.rawlog");
  ASSERT_GT(good.size(), 100000u);
  // The first 600 kB hold a few frames: enough for every cut, small enough to be quick.
  const std::string head = good.substr(0, 600000);
  auto rawlog_case = [&](const std::string& name, const std::string& bytes) {
    cases.push_back({"rawlog (info): " + name,
                     {{"@/log.rawlog", bytes}},
                     {"info", "@/log.rawlog"},
                     {"@/log.rawlog"}});
    cases.push_back({"rawlog (detect): " + name,
                     {{"@/log.rawlog", bytes}},
                     {"detect", "--rawlog", "@/log.rawlog", "--max-frames", "1", "--out",
                      "@/out"},
                     {"@/log.rawlog"}});
  };
  rawlog_case("empty", "");
  rawlog_case("text", "this is not a rawlog\n");
  rawlog_case("zeros", std::string(4096, '\0'));
  for (std::size_t cut : {std::size_t{1}, std::size_t{5}, std::size_t{40}, std::size_t{300}}) {
    rawlog_case("truncated to " + std::to_string(cut) + " bytes", good.substr(0, cut));
  }
  EXPECT_GE(RunAll(cases), 14);
}

/// Checkpoints: a real one (an interrupted `cairn map` run), then truncated or with a byte
/// flipped, must be refused by `--resume` naming the file, and left as they were.
TEST_F(Corpus, Checkpoints) {
  const std::string rawlog =
      (kSource / "datasets" / "sequences" / "hill_drive" / "sequence.rawlog").string();
  const fs::path made = root_ / "made";
  const RunResult cut = CairnInterruptedOnceThere(
      {"map", "--rawlog", rawlog, "--config",
       (kSource / "datasets" / "sequences" / "hill_drive" / "map.yaml").string(),
       "--checkpoint-every", "1", "--out", made.string()},
      made / "map.checkpoint", root_);
  ASSERT_EQ(cut.status, 130) << cut.output;
  const std::string good = ReadFile(made / "map.checkpoint");
  ASSERT_GT(good.size(), 64u) << cut.output;
  std::vector<Case> cases;
  auto checkpoint_case = [&](const std::string& name, const std::string& bytes) {
    cases.push_back({"checkpoint: " + name,
                     {{"@/out/map.checkpoint", bytes}},
                     {"map", "--rawlog", rawlog, "--config",
                      (kSource / "datasets" / "sequences" / "hill_drive" / "map.yaml").string(),
                      "--max-frames", "3", "--resume", "--out", "@/out"},
                     {"@/out/map.checkpoint"}});
  };
  checkpoint_case("empty", "");
  for (std::size_t at : {std::size_t{4}, std::size_t{8}, std::size_t{12}, std::size_t{20},
                         std::size_t{31}, std::size_t{32}, std::size_t{40}, good.size() / 3,
                         good.size() / 2, good.size() - 100, good.size() - 1}) {
    checkpoint_case("truncated to " + std::to_string(at), good.substr(0, at));
  }
  for (std::size_t at : {std::size_t{0}, std::size_t{9}, std::size_t{13}, std::size_t{17},
                         std::size_t{25}, std::size_t{33}, std::size_t{60}, good.size() / 4,
                         good.size() / 2, good.size() - 2}) {
    std::string flipped = good;
    flipped[at] ^= 0x20;
    checkpoint_case("byte " + std::to_string(at) + " flipped", flipped);
  }
  checkpoint_case("a byte more", good + "x");
  checkpoint_case("text", "CAIRNMCK not really");
  EXPECT_GE(RunAll(cases), 20);
}

/// Inputs the fuzzers found (tools/fuzz.sh), kept under tests/data/malformed/<format>/: each
/// runs through the command for its format.
TEST_F(Corpus, FuzzerFindings) {
  const fs::path kept = kSource / "tests" / "data" / "malformed";
  if (!fs::exists(kept)) GTEST_SKIP() << kept << " holds no findings";
  std::vector<Case> cases;
  for (const fs::directory_entry& format : fs::directory_iterator(kept)) {
    if (!format.is_directory()) continue;
    const std::string kind = format.path().filename().string();
    for (const fs::directory_entry& file : fs::directory_iterator(format.path())) {
      const std::string bytes = ReadFile(file.path());
      const std::string name = kind + "/" + file.path().filename().string();
      if (kind == "intrinsics") {
        cases.push_back({name, {{"@/depth.png", Png(kW, kH)}, {"@/camera.yaml", bytes}},
                         DetectDepth(), {"@/camera.yaml"}});
      } else if (kind == "depth") {
        cases.push_back({name, {{"@/depth.png", bytes}, {"@/camera.yaml", Intrinsics()}},
                         DetectDepth(), {"@/depth.png"}});
      } else if (kind == "ply" || kind == "bin" || kind == "txt") {
        cases.push_back({name, {{"@/scan." + kind, bytes}}, DetectPoints("scan." + kind),
                         {"@/scan." + kind}});
      } else if (kind == "settings") {
        std::vector<std::string> args = DetectDepth();
        args.insert(args.end(), {"--config", "@/settings.yaml"});
        cases.push_back({name,
                         {{"@/depth.png", Png(kW, kH)},
                          {"@/camera.yaml", Intrinsics()},
                          {"@/settings.yaml", bytes}},
                         args,
                         {"@/settings.yaml"}});
      } else if (kind == "world") {
        cases.push_back({name, {{"@/world.yaml", bytes}},
                         {"synth", "--world", "@/world.yaml", "--out", "@/out"},
                         {"@/world.yaml"}});
      } else if (kind == "stereo") {
        cases.push_back({name,
                         {{"@/left.png", Png(kW, kH, 8, 1, 100)},
                          {"@/right.png", Png(kW, kH, 8, 1, 100)},
                          {"@/rig.yaml", bytes}},
                         {"detect", "--left", "@/left.png", "--right", "@/right.png",
                          "--stereo-calib", "@/rig.yaml", "--out", "@/out"},
                         {"@/rig.yaml"}});
      } else if (kind == "rawlog") {
        cases.push_back({name, {{"@/log.rawlog", bytes}}, {"info", "@/log.rawlog"},
                         {"@/log.rawlog"}});
      } else if (kind == "kitti_poses") {
        cases.push_back({name,
                         {{"@/seq/velodyne/000000.bin", Scan()},
                          {"@/seq/calib.txt", KittiCalib()},
                          {"@/seq/times.txt", KittiTimes(1)},
                          {"@/seq/poses.txt", bytes}},
                         {"detect", "--kitti", "@/seq", "--sensor", "VLP-16", "--out", "@/out"},
                         {"@/seq/poses.txt"}});
      } else {
        ADD_FAILURE() << kept / kind << ": no command for this format";
      }
    }
  }
  RunAll(cases);
}

}  // namespace
}  // namespace cairn
