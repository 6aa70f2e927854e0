// One frame's ground against another's where both saw the same terrain (the gravity tilt
// step's GroundRise): the earlier frame's ground points as local planes, and the height by
// which the later frame's points must move to lie on them.
//
// The earlier ground is kept as sums over square cells; the surface at (x, y) is the least
// squares plane through the points of the 3 x 3 cells around it, evaluated there (the
// terrain's curvature over 1.5 m is millimetres where a camera's ground rows are tens of
// centimetres apart). A place whose points do not span both horizontal directions (one
// row of a far scan line) has no plane. The fit is Huber-robust: an obstacle's base or a
// rock the detector did not flag does not pull it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

namespace cairn::map::internal {

struct GroundRiseFitConfig {
  double cell_m = 0.5;       ///< cell side [m]; a plane spans 3 x 3 cells
  int min_plane_points = 6;  ///< points a plane needs
  /// Least spread of a plane's points along its weakest horizontal direction [m] (a single
  /// scan line gives no slope across it).
  double min_spread_m = 0.1;
  double max_range_m = 25.0;  ///< points farther from their sensor are not used [m]
  int max_points = 1500;      ///< points per frame, thinned evenly by index (ThinGroundPoints)
  int min_points = 50;        ///< matched points a fit needs
  double huber_m = 0.05;      ///< Huber scale of a point's height residual [m]
  int max_iterations = 50;    ///< reweightings
};

/// ThinGroundPoints (ground_points.hpp) with the config's range and count.
std::vector<Eigen::Vector3f> ThinGroundPoints(const std::vector<Eigen::Vector3f>& points_sensor,
                                              const GroundRiseFitConfig& config);

/// A frame's ground, placed in the world at the pose it was fused at.
class GroundSurface {
 public:
  /// `points_sensor` as ThinGroundPoints gives them.
  GroundSurface(const std::vector<Eigen::Vector3f>& points_sensor,
                const Eigen::Isometry3d& T_world_sensor, const GroundRiseFitConfig& config);

  /// The plane through the points around (x, y): its height there [m] and its gradient
  /// (dz/dx, dz/dy); none where too few points or too little spread.
  struct Plane {
    double height_m = 0.0;
    Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
  };
  std::optional<Plane> PlaneAt(double x, double y) const;

  const Eigen::Isometry3d& T_world_sensor() const { return T_world_sensor_; }

 private:
  struct Sums {
    double n = 0, x = 0, y = 0, z = 0, xx = 0, xy = 0, yy = 0, xz = 0, yz = 0;
  };
  static std::uint64_t Key(std::int64_t i, std::int64_t j) {
    return (static_cast<std::uint64_t>(i) << 32) ^ static_cast<std::uint32_t>(j);
  }

  GroundRiseFitConfig config_;
  Eigen::Isometry3d T_world_sensor_;
  Eigen::Vector2d origin_;  // the sensor's x, y: sums are kept relative to it
  std::unordered_map<std::uint64_t, Sums> cells_;
};

/// The later frame's ground fitted to the earlier one's.
struct GroundRiseFit {
  double dz_m = 0.0;  ///< height to add to the later frame, as placed, to lie on the earlier [m]
  /// The matched places' mean offsets from each sensor (world axes), weighted as the fit
  /// weighs them [m].
  Eigen::Vector3d offset_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d offset_earlier_m = Eigen::Vector3d::Zero();
  /// The earlier ground's mean gradient at the matched places (dz/dx, dz/dy), weighted
  /// alike: a misplacement of the later frame by dxy moves dz_m by its dot product.
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();
  int points = 0;      ///< matched points
  double rms_m = 0.0;  ///< their height residual's RMS after the fit [m]
};

/// `points_sensor` (ThinGroundPoints) placed at T_world_sensor against `earlier`; none with
/// fewer than min_points over it.
std::optional<GroundRiseFit> FitGroundRise(const std::vector<Eigen::Vector3f>& points_sensor,
                                           const Eigen::Isometry3d& T_world_sensor,
                                           const GroundSurface& earlier,
                                           const GroundRiseFitConfig& config);

}  // namespace cairn::map::internal
