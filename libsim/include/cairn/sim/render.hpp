// Exact ray casting: one ray per pixel centre, ground truth per pixel.
//
// Shapes are intersected in closed form and the terrain to `terrain_tolerance_m` along the
// ray, so a rendered depth image is the scene up to float rounding: tests compare detector
// outputs against it. The LiDAR (world.hpp) casts through RayCaster too; stereo noise is
// applied to a rendered frame afterwards. Rows are rendered in parallel; the result does
// not depend on the number of threads.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/geometry.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::sim {

struct RenderOptions {
  double max_range_m = 100.0;         ///< farther hits are no hit (distance along the ray) [m]
  double terrain_tolerance_m = 1e-6;  ///< heightfield crossings bisected to this [m]
  /// Worker threads; 0 uses every hardware thread. The result does not depend on it.
  int threads = 0;
};

/// Casts rays into one scene. Holds a reference to the scene, which must outlive it.
class RayCaster {
 public:
  explicit RayCaster(const Scene& scene);

  /// The first surface within (0, max_range] along the ray (unit direction), or nothing.
  std::optional<RayHit> Cast(const Ray& ray, const RenderOptions& options) const;

 private:
  struct Prepared {  // a solid (terrain features are in the terrain)
    const Shape* shape;
    int id;
    BoundingSphere bound;
  };
  const Scene& scene_;
  std::vector<Prepared> prepared_;
};

/// One rendered camera frame, row-major (index = row * width + col).
struct DepthFrame {
  od::PinholeModel model;
  std::vector<float> depth_m;           ///< z-depth [m]; 0 = no hit within range
  std::vector<std::int32_t> object_id;  ///< kTerrainId, an object id, or kNoHitId
  std::vector<Eigen::Vector3f> normal;  ///< surface normal, world frame; zero when no hit
  Eigen::Vector3d up_optical = Eigen::Vector3d(0.0, -1.0, 0.0);  ///< for RangeImage::FromDepth

  int width() const { return model.width; }
  int height() const { return model.height; }
  int size() const { return model.width * model.height; }
};

/// Renders the scene as seen by the camera. Fails when the camera model or the scene does
/// not validate.
Expected<DepthFrame> RenderDepth(const Scene& scene, const Camera& camera,
                                 const RenderOptions& options = {});

}  // namespace cairn::sim
