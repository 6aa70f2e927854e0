// Vertical structure as a gravity cue: which of a frame's detected segments are trunks, poles
// or walls, and the direction each says is up (or horizontal), in the sensor frame.
//
// A kept segment is measured by the principal axes of its points (sensor frame), with
// eigenvalues l1 >= l2 >= l3 of their covariance:
//   - a trunk or pole is tall and thin: its height above its ground (the detector's
//     height_max) at least min_height_m, sqrt(l1 / l2) >= min_elongation and sqrt(l2) <=
//     max_radius_m; its cue is the first axis, pointing up;
//   - a wall is a tall plane: height as above, sqrt(l2) >= min_wall_width_m and sqrt(l2 / l3)
//     >= min_flatness; its cue is the third axis (its normal), which should be horizontal.
// A segment is measured above its foot (where it meets the ground) and below the lowest of its
// points in the image's top row, when that row cuts it; a trunk the image's left or right edge
// cuts is no cue (edges of a pitched or rolled camera's image are not vertical or level in the
// world: what they leave of a trunk leans).
// Either is kept only within max_angle_rad of what the prior says (the axis from the prior's
// up, the normal from horizontal): a gross check, since the estimator weighs the cues with a
// robust loss and a leaning tree is expected. Slopes, mounds and rocks fail the shape or
// the angle test.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "cairn/map/gravity_estimator.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/units.hpp"

namespace cairn::map {

struct VerticalCueConfig {
  double min_height_m = 1.2;      ///< segment height above its ground [m]
  int min_points = 40;            ///< points in the segment
  double min_elongation = 3.0;    ///< trunk: sqrt(l1 / l2)
  double max_radius_m = 0.35;     ///< trunk: sqrt(l2) [m]
  double min_wall_width_m = 0.4;  ///< wall: sqrt(l2) [m]
  double min_flatness = 6.0;      ///< wall: sqrt(l2 / l3)
  double max_angle_rad = 12.0 * kDegToRad;  ///< from the prior's vertical [rad]
  double max_range_m = 25.0;      ///< segments farther (mean range) are left out [m]
  bool walls = true;              ///< use wall normals
  /// Names the first bad field ("tilt.verticals.min_height: ...").
  Status Validate() const;
};

/// The vertical cues among the kept segments of `detection` (`image` holds its points in
/// the sensor frame; `up_sensor` is the prior's up, unit).
std::vector<VerticalCue> FindVerticalCues(const od::RangeImage& image,
                                          const od::Detection& detection,
                                          const od::Classification& classification,
                                          const Eigen::Vector3d& up_sensor,
                                          const VerticalCueConfig& config);

}  // namespace cairn::map
