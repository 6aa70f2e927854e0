// Gravity from the map: Ceres refines a frame's roll and pitch (and height) so that its ground
// points lie on the terrain already fused, with the IMU / odometry attitude as a prior.
//
// Why: the detector measures heights along the up vector. On a slope, 2-D odometry gives no
// attitude and an IMU drifts or is biased; a tilt error of delta makes ground at range d
// appear d * delta too high or too low, and at 10 m one degree is 17 cm -- half an obstacle.
// Matching the new frame's ground to the elevation fused from earlier frames observes its
// tilt and height *relative to the map*: frames stay consistent with one another, and the
// map is gravity-aligned as far as its first frames were (a bias present from the start is
// a rotation of the whole map that heights cannot reveal; a level or static start, or an
// IMU without bias, anchors it). Yaw and the horizontal position are not observable from
// heights and stay as the prior gives them; on a slope a large yaw error is absorbed as a
// false tilt. The prior bounds each frame's correction, not the sum carried across frames.
//
// The correction is a rotation about the world x and y axes through the sensor's origin and
// a vertical offset:  p' = c + Ry(pitch) Rx(roll) (p - c) + dz e_z,  p = T_world_sensor_prior q,
// c = the sensor origin in the world. Residuals: the height of p' above the elevation
// (bicubic in the patch, Huber-robust, so obstacles and map errors do not pull), and the
// prior on (roll, pitch, dz).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/expected.hpp"

namespace cairn::map {

/// A gravity-aligned elevation patch: z(row, col) is the terrain height [m] at the centre of
/// cell (row, col), x = origin.x + (col + 0.5) * resolution, y = origin.y + (row + 0.5) *
/// resolution. NaN where unknown.
struct ElevationPatch {
  Eigen::MatrixXd z;
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  ///< world x, y of the patch corner [m]
  double resolution_m = 0.1;                          ///< cell side [m]
};

struct TiltRefinerConfig {
  double prior_sigma_rad = 0.035;   ///< prior on the roll and pitch corrections (2 deg) [rad]
  double prior_sigma_z_m = 0.5;     ///< prior on the height correction [m]
  double huber_m = 0.05;            ///< robust loss scale of the height residuals [m]
  double max_range_m = 25.0;        ///< ground points farther from the sensor are not used [m]
  int max_points = 1500;            ///< ground points sampled per frame (evenly, by index)
  int min_points = 50;              ///< fewer usable points: the prior is kept (not usable)
  int max_iterations = 50;          ///< Ceres iterations (RefineHeight: reweightings)

  /// Fails naming the first field out of range.
  Status Validate() const;
};

/// The refined pose with diagnostics, in the manner of ceres::Solver::Summary.
struct TiltEstimate {
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();  ///< refined
  double roll_rad = 0.0;   ///< correction about world x applied to the prior [rad]
  double pitch_rad = 0.0;  ///< correction about world y [rad]
  double dz_m = 0.0;       ///< vertical correction [m]
  int points_used = 0;     ///< ground points over known terrain
  double rms_before_m = 0.0;  ///< RMS height residual with the prior pose [m]
  double rms_after_m = 0.0;   ///< with the refined pose [m]
  bool usable = false;     ///< false: too few points or Ceres failed; T_world_sensor = prior
  std::string report;  ///< Ceres' brief report (RefineHeight: its own), or why the prior was kept
};

/// The patch of `terrain`'s fused elevation within half_size_m of `centre` (world x, y [m]),
/// as RefineTilt reads it.
ElevationPatch ElevationPatchAround(const TerrainMap& terrain, const Eigen::Vector2d& centre,
                                    double half_size_m);

/// `T_world_sensor` corrected as above: rotated by Ry(pitch) Rx(roll) about the world x and y
/// axes through its origin, and raised by dz. A TiltEstimate's T_world_sensor is its prior
/// corrected by its roll_rad, pitch_rad and dz_m.
Eigen::Isometry3d ApplyTiltCorrection(const Eigen::Isometry3d& T_world_sensor, double roll_rad,
                                      double pitch_rad, double dz_m);

/// Refines T_world_sensor_prior from `ground_points_sensor` (points the detector did not flag,
/// in the sensor frame [m]) against `terrain`. Fails only on an invalid config; too little
/// overlap comes back as an estimate with usable = false and the prior unchanged.
Expected<TiltEstimate> RefineTilt(const std::vector<Eigen::Vector3f>& ground_points_sensor,
                                  const Eigen::Isometry3d& T_world_sensor_prior,
                                  const ElevationPatch& terrain, const TiltRefinerConfig& config);

/// RefineTilt with the tilt held at the prior's: the same ground points, terrain, Huber loss
/// and height prior, the height correction dz the only unknown. A point's height over the
/// terrain is then linear in dz, and the fit is solved directly (iteratively reweighted
/// least squares on the one unknown, until a step is under 1e-9 m or after
/// config.max_iterations reweightings, each of which lowers the cost) instead of by Ceres
/// over three unknowns. roll_rad and pitch_rad are 0.
Expected<TiltEstimate> RefineHeight(const std::vector<Eigen::Vector3f>& ground_points_sensor,
                                    const Eigen::Isometry3d& T_world_sensor_prior,
                                    const ElevationPatch& terrain, const TiltRefinerConfig& config);

}  // namespace cairn::map
