// Uses the installed cairn::od and cairn::map: a 1 m wall 6 m ahead of a level camera 1.5 m
// above flat ground is detected and fused into a lethal cell. Exits 0 only when it is.
#include <cmath>
#include <cstdio>
#include <vector>

#include "cairn/map/mapper.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"

int main() {
  cairn::od::PinholeModel model;
  model.width = 160;
  model.height = 120;
  model.fx = model.fy = 100.0;
  model.cx = 79.5;
  model.cy = 59.5;
  const double height = 1.5, wall_x = 6.0, wall_top = 1.0, wall_half_width = 2.0;
  std::vector<float> depth(model.width * model.height, 0.0f);
  for (int v = 0; v < model.height; ++v) {
    for (int u = 0; u < model.width; ++u) {
      // The ray (optical frame: x right, y down, z forward) at unit z-depth, in the world.
      const double right = (u - model.cx) / model.fx, down = (v - model.cy) / model.fy;
      double t = down > 0.0 ? height / down : INFINITY;  // the ground
      const double z_at_wall = height - wall_x * down;
      if (wall_x < t && z_at_wall >= 0.0 && z_at_wall <= wall_top &&
          std::abs(wall_x * right) <= wall_half_width) {
        t = wall_x;
      }
      if (t < 30.0) depth[v * model.width + u] = static_cast<float>(t);
    }
  }
  cairn::Expected<cairn::od::RangeImage> image =
      cairn::od::RangeImage::FromDepth(depth, model, Eigen::Vector3d(0.0, -1.0, 0.0));
  if (!image) {
    std::fprintf(stderr, "consumer: %s\n", image.error().message.c_str());
    return 1;
  }
  cairn::Expected<cairn::map::Mapper> mapper = cairn::map::Mapper::Create(cairn::map::MapperConfig{});
  if (!mapper) {
    std::fprintf(stderr, "consumer: %s\n", mapper.error().message.c_str());
    return 1;
  }
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  T_world_camera.linear() << 0, 0, 1,  //
      -1, 0, 0,                        //
      0, -1, 0;
  T_world_camera.translation() = Eigen::Vector3d(0.0, 0.0, height);
  cairn::Expected<cairn::map::MapperRecord> record =
      mapper->Process(std::move(*image), T_world_camera, 0.0);
  if (!record) {
    std::fprintf(stderr, "consumer: %s\n", record.error().message.c_str());
    return 1;
  }
  std::printf("consumer: %d segments, %d kept, %d lethal cells\n", record->segments,
              record->kept, record->fused.lethal_cells);
  return record->kept >= 1 && record->fused.lethal_cells > 0 ? 0 : 1;
}
