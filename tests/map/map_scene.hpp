// A small mapped scene for the file tests and the OctoMap tools check: a box and a pole on
// flat ground seen by two noiseless range cameras.
#pragma once

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/scene.hpp"
#include "sim_frames.hpp"

namespace cairn::test {

/// The scene: a 1 x 1 x 0.8 m box centred at (4, 0) and a pole of radius 0.1 m, 1.2 m tall,
/// at (6, 2), on flat ground.
inline sim::Scene SmallScene() {
  sim::Scene scene;
  scene.AddBox(4.0, 0.0, {1.0, 1.0, 0.8}, 0.0, true, "box");
  scene.AddPole(6.0, 2.0, 0.1, 1.2, true, "pole");
  return scene;
}

inline Expected<map::TerrainMap> SmallMappedScene(const map::MapConfig& config = {}) {
  const sim::Scene scene = SmallScene();
  Expected<od::io::DetectSettings> settings = DefaultDetectSettings();
  if (!settings) return settings.error();
  Expected<map::TerrainMap> map = map::TerrainMap::Create(config);
  if (!map) return map.error();
  const Eigen::Vector3d positions[] = {{1.0, 0.0, 2.0}, {1.5, 2.5, 2.0}};
  const double headings_deg[] = {0.0, -20.0};
  for (int k = 0; k < 2; ++k) {
    const Eigen::Isometry3d T =
        sim::Camera::FromAttitude(od::PinholeModel{}, positions[k], headings_deg[k] * kDegToRad,
                                  25.0 * kDegToRad, 0.0)
            .T_world_camera;
    Expected<SimFrame> frame =
        CameraFrame(scene, sim::RangeCameraSpec::Default().Scaled(160), T, 0.5 * k, k, *settings);
    if (!frame) return frame.error();
    if (Expected<map::FrameSummary> s = frame->IntegrateInto(*map); !s) return s.error();
  }
  return map;
}

}  // namespace cairn::test
