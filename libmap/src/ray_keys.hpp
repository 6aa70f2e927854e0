// Internal: the voxels a ray crosses, as OctoMap's OcTreeBaseImpl::computeRayKeys finds
// them, handed to a callback instead of stored.
//
// computeRayKeys writes every key into a KeyRay (a vector of 100,000 keys made per call
// site) and picks each step's axis with unpredictable branches; a frame's free space is
// ten million such steps. This walk is the same 3-D DDA (Amanatides & Woo) in the same
// float and double arithmetic, so it visits the same keys in the same order (checked
// against computeRayKeys on random rays in tests/map/terrain_map_test.cpp): the origin's
// voxel first, the end's voxel never. It only calls f(key) for each.
#pragma once

#include <octomap/OcTreeKey.h>
#include <octomap/octomap_types.h>

#include <cmath>
#include <limits>
#include <type_traits>

namespace cairn::map::internal {

/// Hands a key to f: as its three coordinates when f takes them (they stay in registers;
/// an OcTreeKey built in memory and read back whole stalls the walk on every step), else as
/// an OcTreeKey.
template <typename F>
void Visit(F& f, int k0, int k1, int k2) {
  if constexpr (std::is_invocable_v<F&, unsigned, unsigned, unsigned>) {
    f(static_cast<unsigned>(k0), static_cast<unsigned>(k1), static_cast<unsigned>(k2));
  } else {
    f(octomap::OcTreeKey(static_cast<octomap::key_type>(k0), static_cast<octomap::key_type>(k1),
                         static_cast<octomap::key_type>(k2)));
  }
}

/// Calls f(key) for every voxel computeRayKeys(origin, end) would put in its ray. Returns
/// false, calling nothing, when origin or end lies outside the tree (computeRayKeys' false).
template <typename Tree, typename F>
bool ForEachRayKey(const Tree& tree, const octomap::point3d& origin, const octomap::point3d& end,
                   F&& f) {
  octomap::OcTreeKey key, key_end;
  if (!tree.coordToKeyChecked(origin, key) || !tree.coordToKeyChecked(end, key_end)) {
    return false;
  }
  if (key == key_end) return true;
  Visit(f, key[0], key[1], key[2]);
  octomap::point3d direction = end - origin;
  const float length = static_cast<float>(direction.norm());
  direction /= length;
  const double resolution = tree.getResolution();
  int step[3];
  double t_max[3], t_delta[3];
  for (int i = 0; i < 3; ++i) {
    step[i] = direction(i) > 0.0f ? 1 : (direction(i) < 0.0f ? -1 : 0);
    if (step[i] != 0) {
      // The border of the voxel on the ray's side, where the ray first leaves it along i.
      double border = tree.keyToCoord(key[i]);
      border += static_cast<float>(step[i] * resolution * 0.5);
      t_max[i] = (border - origin(i)) / direction(i);
      t_delta[i] = resolution / std::fabs(direction(i));
    } else {
      t_max[i] = t_delta[i] = std::numeric_limits<double>::max();
    }
  }
  // The step's axis is the least t_max, ties as OctoMap breaks them (0 < 1, then < 2),
  // chosen without branches: which axis comes next is what the processor cannot guess.
  double t0 = t_max[0], t1 = t_max[1], t2 = t_max[2];
  int k0 = key[0], k1 = key[1], k2 = key[2];
  const int e0 = key_end[0], e1 = key_end[1], e2 = key_end[2];
  const double length_d = length;
  for (;;) {
    const bool first_01 = t0 < t1;
    const double t01 = first_01 ? t0 : t1;
    const int dim = t01 < t2 ? (first_01 ? 0 : 1) : 2;
    k0 += dim == 0 ? step[0] : 0;
    k1 += dim == 1 ? step[1] : 0;
    k2 += dim == 2 ? step[2] : 0;
    t0 += dim == 0 ? t_delta[0] : 0.0;
    t1 += dim == 1 ? t_delta[1] : 0.0;
    t2 += dim == 2 ? t_delta[2] : 0.0;
    if (k0 == e0 && k1 == e1 && k2 == e2) return true;
    // Past the end's distance without meeting its voxel (rounding): stop, as OctoMap does.
    const double t_least01 = t0 < t1 ? t0 : t1;  // by value: the t's stay in registers
    if ((t_least01 < t2 ? t_least01 : t2) > length_d) return true;
    Visit(f, k0, k1, k2);
  }
}

}  // namespace cairn::map::internal
