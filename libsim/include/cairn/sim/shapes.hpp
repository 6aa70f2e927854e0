// Solid shapes that stand on the terrain, each intersected by a ray in closed form, and the
// terrain features (ditches, banks) that objects may also be.
//
// World frame, z up, metres, radians. Yaw turns a shape about the vertical through its
// centre, counter-clockwise seen from above; its local x axis then points along heading
// `yaw_rad`. Rays are assumed to start outside every solid.
//
// Ditch and Bank are not solids: they reshape the terrain (see terrain.hpp), which is where
// a ray meets them. A Scene carves them into its terrain when they are added as objects, so
// that they have an id, a name and an is_obstacle flag like any other object; Intersect()
// of one returns nothing and the ray caster skips them.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <variant>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sim/geometry.hpp"
#include "cairn/sim/terrain.hpp"

namespace cairn::sim {

/// Vertical capped cylinder: poles, trunks.
struct Cylinder {
  Eigen::Vector3d base_centre = Eigen::Vector3d::Zero();  ///< centre of the bottom disc
  double radius_m = 0.1;
  double height_m = 1.0;
};

/// Ellipsoid with radii along its local axes (x, y after yaw; z vertical): rocks, mounds,
/// bushes. A sphere has three equal radii.
struct Ellipsoid {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d radii = Eigen::Vector3d::Ones();
  double yaw_rad = 0.0;
};

/// Box with vertical sides: walls, blocks. `size` = (length along local x, width along
/// local y, height).
struct Box {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d size = Eigen::Vector3d::Ones();
  double yaw_rad = 0.0;
};

/// A ridge or mound: a flat rectangular top (length along local x, width along local y)
/// `height_m` above its base, each side falling to the base at its own slope from the
/// horizontal (90 deg = a vertical face). Left is the local +y side, right the local -y
/// side, the ends face local +x and -x. A steep left or right side is a steep face whose
/// normal points sideways when the ridge runs along the line of sight.
struct Ridge {
  Eigen::Vector3d base_centre = Eigen::Vector3d::Zero();  ///< centre of the base [m]
  double yaw_rad = 0.0;
  double top_length_m = 2.0;
  double top_width_m = 0.2;
  double height_m = 0.5;
  double left_slope_rad = 1.0471975511965976;   ///< local +y side (60 deg)
  double right_slope_rad = 1.0471975511965976;  ///< local -y side (60 deg)
  double end_slope_rad = 0.5235987755982988;    ///< both ends (30 deg)
};

/// A capped cylinder with any axis, from `start` to `end` (centres of its end discs):
/// overhanging branches, wires and cables, fallen logs, rails.
struct Rod {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d end = Eigen::Vector3d::UnitX();  ///< must differ from start
  double radius_m = 0.05;
};

/// A union of ellipsoids: a lumpy bush, a pile of rocks. The first surface a ray meets is
/// that of the nearest part.
struct Cluster {
  std::vector<Ellipsoid> parts;  ///< at least one
};

/// A bush: a core ellipsoid with `lumps` smaller ellipsoids (each `lump_scale` times the
/// core's smallest radius, randomly squashed) centred on its upper surface, drawn from
/// `seed`. The result is translated so that its top is `top_z` and its axis through (x, y).
/// lumps = 0 gives the core alone. Requires radii > 0, lumps >= 0, lump_scale in (0, 1].
Cluster MakeBush(double x, double y, double top_z, const Eigen::Vector3d& radii, double yaw_rad,
                 int lumps, double lump_scale, std::uint64_t seed);

using Shape = std::variant<Cylinder, Ellipsoid, Box, Ridge, Rod, Cluster, Ditch, Bank>;

/// True for the shapes that reshape the terrain instead of standing on it (Ditch, Bank).
bool IsTerrainFeature(const Shape& shape);

/// Names the first bad parameter of a shape (non-finite, non-positive size, slope outside
/// (0, 90 deg], or outside (0, 85 deg] for ditch walls and bank faces).
Status ValidateShape(const Shape& shape);

/// First entry of the ray into the shape within [t_min, t_max]; the hit's id is left as
/// kNoHitId for the caller to fill. Terrain features give nothing (the terrain has them).
std::optional<RayHit> Intersect(const Shape& shape, const Ray& ray, double t_min, double t_max);

/// A sphere that contains the shape: centre and radius [m]. Terrain features are relative
/// to the terrain: their sphere is centred at z = 0 and contains the footprint (a bank's,
/// which has no end, is infinite).
struct BoundingSphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};
BoundingSphere Bound(const Shape& shape);

/// Lowest z of the shape [m]. For terrain features: relative to the surrounding ground
/// (-depth for a ditch, 0 for a bank).
double Bottom(const Shape& shape);
/// Highest z of the shape [m]. For terrain features: relative to the ground at the foot
/// (0 for a ditch, the rise for a bank).
double Top(const Shape& shape);

}  // namespace cairn::sim
