// Solid shapes that stand on the terrain, each intersected by a ray in closed form.
//
// World frame, z up, metres, radians. Yaw turns a shape about the vertical through its
// centre, counter-clockwise seen from above; its local x axis then points along heading
// `yaw_rad`. Rays are assumed to start outside every solid.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <variant>

#include "cairn/od/expected.hpp"
#include "cairn/sim/geometry.hpp"

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

using Shape = std::variant<Cylinder, Ellipsoid, Box, Ridge>;

/// Names the first bad parameter of a shape (non-finite, non-positive size, slope outside
/// (0, 90 deg]).
Status ValidateShape(const Shape& shape);

/// First entry of the ray into the shape within [t_min, t_max]; the hit's id is left as
/// kNoHitId for the caller to fill.
std::optional<RayHit> Intersect(const Shape& shape, const Ray& ray, double t_min, double t_max);

/// A sphere that contains the shape: centre and radius [m].
struct BoundingSphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};
BoundingSphere Bound(const Shape& shape);

/// Lowest z of the shape [m].
double Bottom(const Shape& shape);
/// Highest z of the shape [m].
double Top(const Shape& shape);

}  // namespace cairn::sim
