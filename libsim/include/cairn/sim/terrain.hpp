// Terrain: a heightfield z = h(x, y) in the world frame (z up) [m].
//
// h is a sum of parts, any of which may be absent: a plane (height at the origin plus a
// constant gradient), sine waves (rolling hills), a regular grid of heights (bilinear,
// clamped to its edge values outside), a user function, and local features: ditches cut
// into the ground and steep banks (steps). Only the plane and the waves are known in closed
// form; the ray caster needs, for every part, a bound on |grad h| (a Lipschitz constant),
// which is what lets it march without stepping over a crossing. A feature's bound holds only
// on its footprint (zero gradient elsewhere), so a steep feature slows the march only where
// a ray passes over it.
//
// A feature may carry an object id: a ray hit on its steep faces (a ditch's walls, a bank's
// face) reports that id instead of kTerrainId, so id images mark negative obstacles and banks
// as ground truth.
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

/// A ditch (negative obstacle): a trench cut `depth_m` into the ground along the segment
/// start-end, `top_width_m` wide from rim to rim, its walls falling at `wall_slope_rad` from
/// the horizontal to a flat floor. The depth at a point at horizontal distance s from the
/// segment is min(depth, max(0, (top_width / 2 - s) tan(wall_slope))): the ends are rounded,
/// sloped like the walls. Requires a floor: depth <= (top_width / 2) tan(wall_slope).
/// World xy [m], radians.
struct Ditch {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d end = Eigen::Vector2d(0.0, 1.0);
  double depth_m = 0.5;                        ///< floor below the surrounding ground, > 0
  double top_width_m = 2.0;                    ///< > 0
  double wall_slope_rad = 1.0471975511965976;  ///< in (0, 85 deg]; 60 deg by default

  /// Width of the flat floor [m].
  double FloorWidth() const;
};

/// A steep bank: the ground steps up by `rise_m` across a straight face through `centre`
/// (world xy), rising towards the heading `uphill_heading_rad` (0 = +x, counter-clockwise)
/// at `face_slope_rad` from the horizontal. The face runs without end across the world; the
/// ground beyond it is `rise_m` higher. The face is rise / tan(slope) wide, centred on
/// `centre`.
struct Bank {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double uphill_heading_rad = 0.0;
  double rise_m = 1.0;                         ///< > 0
  double face_slope_rad = 1.2217304763960306;  ///< in (0, 85 deg]; 70 deg by default

  /// Horizontal width of the face [m].
  double FaceWidth() const;
};

/// Steepest wall or face a feature may have: steeper ones make the march crawl over it.
inline constexpr double kMaxFeatureSlopeRad = 1.4835298641951802;  // 85 deg

/// Names the first bad field ("depth_m", "top_width_m", ...) of a feature.
Status ValidateDitch(const Ditch& ditch);
Status ValidateBank(const Bank& bank);

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
  /// Cuts a ditch / raises a bank; hits on its walls / face report `id` (kTerrainId: none).
  /// The feature must validate (asserted).
  Terrain& AddDitch(const Ditch& ditch, int id = kTerrainId);
  Terrain& AddBank(const Bank& bank, int id = kTerrainId);

  double Height(double x, double y) const;
  double Height(const Eigen::Vector2d& xy) const { return Height(xy.x(), xy.y()); }
  /// Upward unit normal (analytic for plane and waves, central differences otherwise).
  Eigen::Vector3d Normal(double x, double y) const;
  /// Least height over a disc, sampled on a grid and lowered by what the gradient bound
  /// allows between samples: an object standing on the disc sunk to this height leaves no
  /// gap under it.
  double MinHeightOver(const Eigen::Vector2d& centre, double radius_m) const;

  /// Id reported for a surface point above (x, y): the id of the first feature whose steep
  /// part (ditch walls, bank face) lies under it, else kTerrainId.
  int IdAt(double x, double y) const;

  /// Bound on |grad h| over the whole plane (the Lipschitz constant the ray caster uses).
  double MaxGradient() const;
  /// Bound on |grad h| over the square of half-side `radius_m` around `centre`: features
  /// count only where their footprint reaches it.
  double MaxGradientNear(const Eigen::Vector2d& centre, double radius_m) const;
  /// True when h is a plane (ray casting is then analytic).
  bool IsPlanar() const;
  /// True when the terrain has ditches or banks.
  bool HasFeatures() const { return !features_.empty(); }

  /// First crossing of the ray with the surface from above, within (0, t_max]. A planar
  /// terrain is intersected in closed form; otherwise the ray marches with steps that cannot
  /// cross the surface twice (by the gradient bound) and the crossing is bisected to
  /// `tolerance_m` along the ray. A ray starting below the surface sees nothing.
  std::optional<RayHit> Intersect(const Ray& ray, double t_max, double tolerance_m) const;

 private:
  // A ditch or a bank, in the frame of its footprint: u along its line, v across it.
  struct Feature {
    bool is_ditch = true;
    int id = kTerrainId;
    Eigen::Vector2d origin = Eigen::Vector2d::Zero();  // ditch start; bank centre
    Eigen::Vector2d u = Eigen::Vector2d::UnitX();      // ditch: start -> end; bank: along the face
    Eigen::Vector2d v = Eigen::Vector2d::UnitY();      // ditch: left; bank: uphill
    double length = 0.0;                               // ditch: |end - start|
    double half_width = 0.0;                           // ditch: top_width / 2; bank: face width / 2
    double depth = 0.0;                                // ditch depth; bank rise
    double tan_slope = 0.0;                            // the Lipschitz constant of the feature
    double mark_inner = 0.0;  // ditch: walls are where half_width - s in (0, depth/tan)

    // Its height at its highest: 0 at a ditch's rim, the rise at a bank's top.
    double Highest() const { return is_ditch ? 0.0 : depth; }
  };
  // A sine wave ready to evaluate: h += amplitude * sin(kx x + ky y + phase).
  struct Wave {
    double amplitude = 0.0, kx = 0.0, ky = 0.0, phase = 0.0;
  };
  static Wave Prepare(const SineWave& w);
  double GridHeight(double x, double y) const;
  double RestHeight(double x, double y) const;  // without the features
  double FeatureHeight(const Feature& f, double x, double y) const;
  Eigen::Vector2d FeatureGradient(const Feature& f, double x, double y) const;
  bool FeatureMarks(const Feature& f, double x, double y) const;
  // Closest segment point distance (ditch) or signed offset across the face (bank).
  double FeatureCoordinate(const Feature& f, double x, double y) const;
  // Ray-parameter interval over which the ray's xy lies on the feature's footprint.
  bool FeatureSpan(const Feature& f, const Ray& ray, double* t0, double* t1) const;
  double SmoothGradient() const;  // bound without the plane and the features
  // Bound on |d/ds h| along the horizontal direction (dx, dy) (not unit: scales with it),
  // without the plane and the features.
  double SmoothRate(double dx, double dy) const;
  // Intersect()'s parts.
  struct RaySpans;                  // the ray's pieces over feature footprints (terrain.cpp)
  RayHit PlaneHit(double t) const;  // a hit at t, with the plane part's normal
  // The ray's pieces over each feature's footprint within (0, t_max), with the rate each adds.
  void FindRaySpans(const Ray& ray, double t_max, RaySpans& spans) const;
  // Gap between the ray and the surface at t; updates each span's slack.
  double RayGap(const Ray& ray, double t, RaySpans& spans) const;
  // Safe steps from the ray's origin (gap `gap` there) to the first crossing (see Intersect).
  std::optional<RayHit> MarchRay(const Ray& ray, double t_max, double tolerance_m, double gap,
                                 double smooth_closing, RaySpans& spans) const;
  // The crossing bracketed by gap g_lo > 0 at lo and g_hi <= 0 at hi, to tolerance_m.
  RayHit RefineRayHit(const Ray& ray, RaySpans& spans, double lo, double g_lo, double hi,
                      double g_hi, double tolerance_m) const;

  double height_m_ = 0.0;
  Eigen::Vector2d gradient_ = Eigen::Vector2d::Zero();
  std::vector<Wave> waves_;
  std::optional<HeightGrid> grid_;
  double grid_max_gradient_ = 0.0;
  double grid_max_slope_x_ = 0.0;  // bounds on |dh/dx| and |dh/dy| of the grid
  double grid_max_slope_y_ = 0.0;
  std::function<double(double, double)> function_;
  double function_max_gradient_ = 0.0;
  std::vector<Feature> features_;
};

}  // namespace cairn::sim
