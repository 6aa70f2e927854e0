// Stereo-like noise on rendered depth frames: mixed pixels at depth edges, depth error
// growing with the square of range, dropouts.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include "cairn/sim/world.hpp"
#include "sampling.hpp"

namespace cairn::sim {
namespace {

// Smears the jumps along one image line (a row or a column): `at(k)` is the frame index of
// the line's k-th pixel. Writes into `out` the pixels that are nearer to this jump than to
// any jump written before.
template <class At>
void SmearLine(const std::vector<float>& clean, int count, At at, int smear, double jump,
               std::vector<float>& out, std::vector<float>& nearest) {
  for (int k = 0; k + 1 < count; ++k) {
    const float near_side = clean[at(k)], far_side = clean[at(k + 1)];
    if (!(near_side > 0.0f && far_side > 0.0f)) continue;
    if (std::abs(near_side - far_side) <= jump) continue;
    // Pixels k - smear + 1 .. k + smear straddle the jump, which lies at k + 0.5.
    for (int p = std::max(0, k - smear + 1); p <= std::min(count - 1, k + smear); ++p) {
      const int i = at(p);
      if (!(clean[i] > 0.0f)) continue;  // no return stays no return
      const double offset = p - (k + 0.5);
      const double w = (offset + smear) / (2.0 * smear);
      if (std::abs(offset) >= nearest[i]) continue;
      nearest[i] = static_cast<float>(std::abs(offset));
      out[i] = static_cast<float>((1.0 - w) * near_side + w * far_side);
    }
  }
}

}  // namespace

DepthFrame ApplyStereoNoise(DepthFrame frame, const StereoNoise& noise, std::uint64_t seed) {
  assert(noise.Validate().ok());
  const int width = frame.width(), height = frame.height(), n = frame.size();
  if (noise.edge_smear_px > 0) {
    const std::vector<float> clean = frame.depth_m;
    std::vector<float> nearest(n, std::numeric_limits<float>::infinity());
    for (int row = 0; row < height; ++row) {
      SmearLine(
          clean, width, [&](int k) { return row * width + k; }, noise.edge_smear_px,
          noise.edge_jump_m, frame.depth_m, nearest);
    }
    for (int col = 0; col < width; ++col) {
      SmearLine(
          clean, height, [&](int k) { return k * width + col; }, noise.edge_smear_px,
          noise.edge_jump_m, frame.depth_m, nearest);
    }
  }
  Random rng(seed);
  const double k = noise.depth_sigma_per_m2;
  const double p = noise.dropout_probability;
  for (int i = 0; i < n; ++i) {
    double z = frame.depth_m[i];
    if (!(z > 0.0)) continue;
    if (k > 0.0) z += k * z * z * detail::StandardNormal(rng);
    const bool dropped = p > 0.0 && rng.Bernoulli(p);
    if (dropped || !(z > 0.0)) {
      frame.depth_m[i] = 0.0f;
      frame.object_id[i] = kNoHitId;
      frame.normal[i] = Eigen::Vector3f::Zero();
    } else {
      frame.depth_m[i] = static_cast<float>(z);
    }
  }
  return frame;
}

}  // namespace cairn::sim
