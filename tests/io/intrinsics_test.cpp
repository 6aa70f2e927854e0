#include "cairn/od/io/intrinsics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"
#include "temp_dir.hpp"

namespace cairn::od::io {
namespace {

const std::string kSize =
    "width: 640\nheight: 480\nfx: 525.0\nfy: 520.0\ncx: 319.5\ncy: 239.5\n"
    "depth_scale: 0.0002\n";

TEST(Intrinsics, ReadsAGoodFileWithUp) {
  test::TempDir dir;
  const auto path = dir.Write("cam.yaml", kSize + "up: [0, -2, 0]\n");
  Expected<CameraIntrinsics> cam = LoadIntrinsics(path);
  ASSERT_TRUE(cam.ok()) << cam.error().message;
  EXPECT_EQ(cam->model.width, 640);
  EXPECT_EQ(cam->model.height, 480);
  EXPECT_DOUBLE_EQ(cam->model.fx, 525.0);
  EXPECT_DOUBLE_EQ(cam->model.fy, 520.0);
  EXPECT_DOUBLE_EQ(cam->model.cx, 319.5);
  EXPECT_DOUBLE_EQ(cam->model.cy, 239.5);
  EXPECT_DOUBLE_EQ(cam->depth_scale_m, 0.0002);
  // Normalised.
  EXPECT_TRUE(cam->up.isApprox(Eigen::Vector3d(0, -1, 0)));
}

TEST(Intrinsics, WrittenFilesReadBackToTheSameValues) {
  test::TempDir dir;
  CameraIntrinsics cam;
  cam.model = PinholeModel{320, 240, 261.3, 259.75, 159.5, 119.25};
  cam.depth_scale_m = 0.001;
  cam.up = CameraUpFromPitchRoll(0.1396, -0.0349);
  const auto path = dir.path() / "cam.yaml";
  ASSERT_TRUE(WriteIntrinsics(path, cam, "written by a test").ok());
  Expected<CameraIntrinsics> back = LoadIntrinsics(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->model.width, 320);
  EXPECT_EQ(back->model.height, 240);
  EXPECT_NEAR(back->model.fx, 261.3, 1e-9);
  EXPECT_NEAR(back->model.fy, 259.75, 1e-9);
  EXPECT_NEAR(back->model.cx, 159.5, 1e-9);
  EXPECT_NEAR(back->model.cy, 119.25, 1e-9);
  EXPECT_NEAR(back->depth_scale_m, 0.001, 1e-12);
  EXPECT_LT((back->up - cam.up).norm(), 1e-9);
  // An invalid model is refused, naming the file, and nothing is written.
  cam.model.fx = 0.0;
  const Status bad = WriteIntrinsics(dir.path() / "bad.yaml", cam, "bad");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.message().find("bad.yaml"), std::string::npos) << bad.message();
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "bad.yaml"));
}

TEST(Intrinsics, PitchAndRollGiveTheLevelingUpVector) {
  Expected<CameraIntrinsics> cam =
      ParseIntrinsics(kSize + "pitch_deg: 10\nroll_deg: -3.5\n", "cam.yaml");
  ASSERT_TRUE(cam.ok()) << cam.error().message;
  const Eigen::Vector3d expected = CameraUpFromPitchRoll(10 * kPi / 180, -3.5 * kPi / 180);
  EXPECT_TRUE(cam->up.isApprox(expected, 1e-12));
}

TEST(Intrinsics, RollDefaultsToZero) {
  Expected<CameraIntrinsics> cam = ParseIntrinsics(kSize + "pitch_deg: 10\n", "cam.yaml");
  ASSERT_TRUE(cam.ok()) << cam.error().message;
  EXPECT_TRUE(cam->up.isApprox(CameraUpFromPitchRoll(10 * kPi / 180, 0.0), 1e-12));
}

TEST(Intrinsics, MissingFileNamesThePath) {
  test::TempDir dir;
  Expected<CameraIntrinsics> cam = LoadIntrinsics(dir / "nope.yaml");
  ASSERT_FALSE(cam.ok());
  EXPECT_NE(cam.error().message.find((dir / "nope.yaml").string()), std::string::npos);
  EXPECT_NE(cam.error().message.find("no such file"), std::string::npos);
}

TEST(Intrinsics, ErrorsNameTheFileOfALoadedFile) {
  test::TempDir dir;
  const auto path = dir.Write("bad.yaml", kSize + "up: [0, 0, 0]\n");
  Expected<CameraIntrinsics> cam = LoadIntrinsics(path);
  ASSERT_FALSE(cam.ok());
  EXPECT_EQ(cam.error().message.rfind(path.string() + ": up: ", 0), 0u) << cam.error().message;
}

struct BadCase {
  const char* what;
  std::string yaml;
  const char* field;  ///< the message must start with "cam.yaml: <field>"
};

class IntrinsicsBad : public ::testing::TestWithParam<BadCase> {};

TEST_P(IntrinsicsBad, NamesTheField) {
  const BadCase& c = GetParam();
  Expected<CameraIntrinsics> cam = ParseIntrinsics(c.yaml, "cam.yaml");
  ASSERT_FALSE(cam.ok()) << c.what;
  const std::string prefix = std::string("cam.yaml: ") + c.field;
  EXPECT_EQ(cam.error().message.rfind(prefix, 0), 0u)
      << c.what << ": got \"" << cam.error().message << "\", expected it to start with \"" << prefix
      << "\"";
}

std::string Without(const std::string& key) {
  std::string text = kSize;
  const std::size_t at = text.find(key + ":");
  text.erase(at, text.find('\n', at) - at + 1);
  return text;
}

std::string With(const std::string& key, const std::string& value) {
  return Without(key) + key + ": " + value + "\n";
}

const std::string kUp = "up: [0, -1, 0]\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, IntrinsicsBad,
    ::testing::Values(BadCase{"missing fx", Without("fx") + kUp, "fx"},
                      BadCase{"missing depth_scale", Without("depth_scale") + kUp, "depth_scale"},
                      BadCase{"missing height", Without("height") + kUp, "height"},
                      BadCase{"nan fx", With("fx", ".nan") + kUp, "fx"},
                      BadCase{"inf cy", With("cy", ".inf") + kUp, "cy"},
                      BadCase{"text fy", With("fy", "wide") + kUp, "fy"},
                      BadCase{"sequence cx", With("cx", "[1, 2]") + kUp, "cx"},
                      BadCase{"negative fx", With("fx", "-525") + kUp, "fx"},
                      BadCase{"fractional width", With("width", "640.5") + kUp, "width"},
                      BadCase{"zero height", With("height", "0") + kUp, "height"},
                      BadCase{"zero depth_scale", With("depth_scale", "0") + kUp, "depth_scale"},
                      BadCase{"zero up", kSize + "up: [0, 0, 0]\n", "up"},
                      BadCase{"short up", kSize + "up: [0, -1]\n", "up"},
                      BadCase{"non-finite up", kSize + "up: [0, .nan, 0]\n", "up[1]"},
                      BadCase{"up as text", kSize + "up: down\n", "up"},
                      BadCase{"no tilt at all", kSize, "up"},
                      BadCase{"up and pitch", kSize + kUp + "pitch_deg: 10\n", "pitch_deg"},
                      BadCase{"up and roll", kSize + kUp + "roll_deg: 1\n", "roll_deg"},
                      BadCase{"roll without pitch", kSize + "roll_deg: 1\n", "pitch_deg"},
                      BadCase{"nan pitch", kSize + "pitch_deg: .nan\n", "pitch_deg"},
                      BadCase{"unknown key", kSize + kUp + "fz: 3\n", "fz"},
                      BadCase{"duplicate key", kSize + kUp + "fx: 500\n", "fx"}));

TEST(Intrinsics, SyntaxErrorsGiveTheLine) {
  Expected<CameraIntrinsics> cam = ParseIntrinsics("width: 640\nheight: [480\n", "cam.yaml");
  ASSERT_FALSE(cam.ok());
  EXPECT_EQ(cam.error().message.rfind("cam.yaml:", 0), 0u) << cam.error().message;
  EXPECT_NE(cam.error().message.find("invalid YAML"), std::string::npos);
}

TEST(Intrinsics, AnEmptyFileIsAnError) {
  Expected<CameraIntrinsics> cam = ParseIntrinsics("", "cam.yaml");
  ASSERT_FALSE(cam.ok());
  EXPECT_NE(cam.error().message.find("expected a mapping"), std::string::npos);
}

}  // namespace
}  // namespace cairn::od::io
