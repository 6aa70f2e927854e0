// Rays and ray hits, the vocabulary shared by every shape, the terrain and the sensors.
//
// World frame: z up along gravity, metres. A ray's direction is a unit vector, so its
// parameter t is a distance along the ray [m].
#pragma once

#include <Eigen/Core>

namespace cairn::sim {

/// Object id of a pixel that sees the terrain.
inline constexpr int kTerrainId = 0;
/// Object id of a pixel that sees nothing within range.
inline constexpr int kNoHitId = -1;

struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit length

  Eigen::Vector3d At(double t) const { return origin + t * direction; }
};

/// The first surface a ray meets.
struct RayHit {
  double t = 0.0;                                     ///< distance along the ray [m]
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< outward unit normal, world frame
  int id = kNoHitId;                                  ///< kTerrainId or the object's id
};

}  // namespace cairn::sim
