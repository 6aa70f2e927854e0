#include "cairn/eval/pose_score.hpp"

#include <cmath>

#include "cairn/eval/drift_run.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/quantile.hpp"

namespace cairn::eval {

Expected<PoseScore> ScorePoses(const sources::Trajectory& truth,
                               const std::vector<FusedPose>& fused, const std::string& source) {
  PoseScore out;
  std::vector<double> tilt_deg;
  double sum2 = 0.0;
  for (const FusedPose& f : fused) {
    Expected<sources::BodyPose> pose = truth.PoseAt(f.stamp_s);
    if (!pose) {
      return Error{source + ": frame " + std::to_string(f.index) + ": " + pose.error().message};
    }
    tilt_deg.push_back(TiltBetween(f.T_world_sensor.linear(), pose->T_world_body.linear()) *
                       kRadToDeg);
    const double dz = f.T_world_sensor.translation().z() - pose->T_world_body.translation().z();
    sum2 += dz * dz;
  }
  if (tilt_deg.empty()) return out;
  out.frames = static_cast<int>(tilt_deg.size());
  out.tilt_median_deg = util::Quantile(tilt_deg, 0.5);
  out.tilt_p95_deg = util::Quantile(tilt_deg, 0.95);
  out.tilt_max_deg = util::Quantile(tilt_deg, 1.0);
  out.height_rms_m = std::sqrt(sum2 / out.frames);
  return out;
}

}  // namespace cairn::eval
