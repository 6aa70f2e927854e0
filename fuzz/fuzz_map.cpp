// The Mapper on short sequences of small arbitrary range images and poses: the first byte
// gives the frame count (1..4), then each frame takes 8 bytes of pose (x, y, z in steps of
// 0.25 m, yaw, pitch, roll in steps of 1.4 deg, a stamp step, the camera's pitch) and a
// 12x12 depth image (16-bit millimetres, 0 = no return). A small rolling window keeps the
// grid moving. Every frame must give a record or an error, and what the map answers
// afterwards (costs, a patch, a line, the obstacles) must stay finite and in range.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <vector>

#include "cairn/map/mapper.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/range_image.hpp"

namespace {

constexpr int kSide = 12;
constexpr std::size_t kPoseBytes = 8;
constexpr std::size_t kFrameBytes = kPoseBytes + 2 * kSide * kSide;

double Signed(std::uint8_t b) { return static_cast<int>(b) - 128; }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 + kPoseBytes) return 0;
  cairn::map::MapperConfig config;
  config.detector.threads = 1;
  // Short rays through coarse voxels: a few hundred keys per frame, so that the fuzzer
  // runs many sequences a second under its instrumentation.
  config.map.max_range_m = 5.0;
  config.map.window_size_m = 8.0;
  config.map.voxel_size_m = 0.4;
  config.map.cell_size_m = 0.4;
  auto mapper = cairn::map::Mapper::Create(config);
  if (!mapper) std::abort();  // the default config must validate

  const int frames = 1 + data[0] % 4;
  double stamp = 0.0;
  for (int f = 0; f < frames; ++f) {
    const std::size_t at = 1 + f * kFrameBytes;
    if (at + kPoseBytes > size) break;
    const std::uint8_t* p = data + at;
    const double deg = M_PI / 180.0 * 1.4;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = 0.25 * Eigen::Vector3d(Signed(p[0]), Signed(p[1]), Signed(p[2]) / 8.0);
    T.linear() = (Eigen::AngleAxisd(Signed(p[3]) * deg, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(Signed(p[4]) * deg / 4.0, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(Signed(p[5]) * deg / 4.0, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    stamp += 0.01 * p[6];
    std::vector<float> depth(kSide * kSide, 0.0f);
    for (std::size_t i = 0; i < depth.size(); ++i) {
      const std::size_t b = at + kPoseBytes + 2 * i;
      if (b + 1 < size) depth[i] = (data[b] | (data[b + 1] << 8)) * 0.001f;
    }
    cairn::od::PinholeModel model;
    model.width = model.height = kSide;
    model.fx = model.fy = 10.0;
    model.cx = model.cy = 0.5 * (kSide - 1);
    // Optical frame: x right, y down, z forward; the mount pitched by p[7].
    const double pitch = Signed(p[7]) * deg / 4.0;
    auto image = cairn::od::RangeImage::FromDepth(depth, model,
                                                  cairn::od::CameraUpFromPitchRoll(pitch, 0.0));
    if (!image) continue;
    auto record = mapper->Process(std::move(*image), T, stamp);
    if (record && record->used() && record->fused.points_in_range > record->valid_points) {
      std::abort();
    }
  }

  const cairn::map::TerrainMap& map = mapper->map();
  const Eigen::Vector2d a(0.0, 0.0), b(3.0, -2.0);
  (void)map.CostAt(a);
  const auto line = map.CostAlongLine(a, b);
  for (auto c : line.costs) (void)c;
  const auto patch = map.PatchAround(a, 2.0);
  for (Eigen::Index i = 0; i < patch.elevation_m.size(); ++i) {
    const float e = patch.elevation_m.data()[i];
    if (std::isinf(e)) std::abort();
  }
  for (const auto& o : map.obstacles()) {
    if (!std::isfinite(o.height_m)) std::abort();
  }
  (void)map.Memory();
  return 0;
}
