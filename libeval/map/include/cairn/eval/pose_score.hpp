// Fused poses against true ones (`cairn map --truth-poses`): the tilt and the height that the
// map was fused at, the errors a tilt estimate exists to remove.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sources/trajectory.hpp"

namespace cairn::eval {

/// A frame's pose as it was fused.
struct FusedPose {
  int index = 0;  ///< the frame's, for messages
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};

struct PoseScore {
  int frames = 0;  ///< scored
  /// Angle between the fused and the true up vector of the sensor [deg].
  double tilt_median_deg = 0.0, tilt_p95_deg = 0.0, tilt_max_deg = 0.0;
  double height_rms_m = 0.0;  ///< fused minus true sensor height, RMS [m]
};

/// Scores each fused pose against the true sensor pose at its stamp (`truth` holds sensor
/// poses, interpolated). Fails, naming `source` and the frame, where the truth does not span
/// a stamp.
Expected<PoseScore> ScorePoses(const sources::Trajectory& truth,
                               const std::vector<FusedPose>& fused, const std::string& source);

}  // namespace cairn::eval
