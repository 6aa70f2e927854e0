#include "cairn/map/frame_imu.hpp"

#include <algorithm>

namespace cairn::map {

std::vector<ImuSample> ImuSamplesOf(const sources::SequenceFrame& frame) {
  std::vector<ImuSample> samples;
  for (const sources::ImuAttitude& a : frame.imu) {
    ImuSample s;
    s.stamp_s = a.stamp_s;
    s.roll_rad = a.roll_rad;
    s.pitch_rad = a.pitch_rad;
    s.has_attitude = true;
    samples.push_back(s);
  }
  for (const sources::ImuSample& r : frame.imu_raw) {
    if (!r.specific_force_mps2 || !r.angular_rate_radps) continue;
    ImuSample s;
    s.stamp_s = r.stamp_s;
    s.specific_force_mps2 = r.T_body_imu.linear() * *r.specific_force_mps2;
    s.angular_rate_radps = r.T_body_imu.linear() * *r.angular_rate_radps;
    s.has_raw = true;
    samples.push_back(s);
  }
  std::stable_sort(samples.begin(), samples.end(),
                   [](const ImuSample& a, const ImuSample& b) { return a.stamp_s < b.stamp_s; });
  return samples;
}

}  // namespace cairn::map
