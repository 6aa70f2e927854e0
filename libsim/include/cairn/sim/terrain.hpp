// Terrain: a heightfield z = h(x, y) in the world frame (z up) [m].
//
// h is a sum of parts, any of which may be absent: a plane (height at the origin plus a
// constant gradient), sine waves (rolling hills), a regular grid of heights (bilinear,
// clamped to its edge values outside) and a user function. Only the first two are known in
// closed form; the ray caster needs, for every part, a bound on |grad h| (a Lipschitz
// constant), which is what lets it march without stepping over a crossing.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sim/geometry.hpp"

namespace cairn::sim {

/// h += amplitude * sin(2 pi (x cos(direction) + y sin(direction)) / wavelength + phase).
struct SineWave {
  double amplitude_m = 0.0;
  double wavelength_m = 1.0;   ///< > 0
  double direction_rad = 0.0;  ///< direction of travel of the wave, from world +x
  double phase_rad = 0.0;
};

/// Heights on a regular grid: heights[row * cols + col] at
/// (origin.x + col * resolution, origin.y + row * resolution).
struct HeightGrid {
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< world xy of cell (0, 0) [m]
  double resolution_m = 1.0;                         ///< > 0
  int cols = 0;                                      ///< >= 2
  int rows = 0;                                      ///< >= 2
  std::vector<double> heights;                       ///< rows * cols values [m]
};

class Terrain {
 public:
  /// Flat ground at z = 0.
  Terrain() = default;

  static Terrain Flat(double height_m = 0.0);
  /// z = height_m + gradient . (x, y).
  static Terrain Plane(double height_m, const Eigen::Vector2d& gradient);
  /// A plane through (0, 0, height_m) rising at `slope_rad` from the horizontal towards the
  /// world heading `uphill_heading_rad` (0 = +x, counter-clockwise).
  static Terrain Slope(double height_m, double slope_rad, double uphill_heading_rad);
  /// Rolling hills on a flat base.
  static Terrain Hills(double height_m, std::vector<SineWave> waves);
  /// Fails (naming the field) on a size mismatch, a grid smaller than 2x2, a non-positive
  /// resolution or a non-finite height.
  static Expected<Terrain> FromGrid(HeightGrid grid);
  /// Any heightfield, given with a bound on its gradient's norm. An underestimated bound
  /// lets the ray caster step over thin crests.
  static Terrain FromFunction(std::function<double(double, double)> height, double max_gradient);

  /// Adds a part to this terrain (the parts sum).
  Terrain& AddWave(const SineWave& wave);
  Terrain& AddPlane(double height_m, const Eigen::Vector2d& gradient);

  double Height(double x, double y) const;
  double Height(const Eigen::Vector2d& xy) const { return Height(xy.x(), xy.y()); }
  /// Upward unit normal (analytic for plane and waves, central differences otherwise).
  Eigen::Vector3d Normal(double x, double y) const;
  /// Least height over a disc, sampled on a grid and lowered by what the gradient bound
  /// allows between samples: an object standing on the disc sunk to this height leaves no
  /// gap under it.
  double MinHeightOver(const Eigen::Vector2d& centre, double radius_m) const;

  /// Bound on |grad h| over the whole plane (the Lipschitz constant the ray caster uses).
  double MaxGradient() const;
  /// True when h is a plane (ray casting is then analytic).
  bool IsPlanar() const;

  /// First crossing of the ray with the surface from above, within (0, t_max]. A planar
  /// terrain is intersected in closed form; otherwise the ray marches with steps that cannot
  /// cross the surface twice (by the gradient bound) and the crossing is bisected to
  /// `tolerance_m` along the ray. A ray starting below the surface sees nothing.
  std::optional<RayHit> Intersect(const Ray& ray, double t_max, double tolerance_m) const;

 private:
  double GridHeight(double x, double y) const;

  double height_m_ = 0.0;
  Eigen::Vector2d gradient_ = Eigen::Vector2d::Zero();
  std::vector<SineWave> waves_;
  std::optional<HeightGrid> grid_;
  double grid_max_gradient_ = 0.0;
  std::function<double(double, double)> function_;
  double function_max_gradient_ = 0.0;
};

}  // namespace cairn::sim
