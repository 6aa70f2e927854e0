// Seeded random scenes for property tests and benchmarks: random terrain, random objects in
// front of a randomly placed and tilted camera.
//
// The same seed gives the same scene on every platform (the generator does not use the
// standard library's distributions, whose output is implementation-defined).
#pragma once

#include <cstdint>
#include <random>

#include "cairn/sim/camera.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::sim {

/// A 64-bit Mersenne twister (whose output the standard fixes) with portable draws.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  /// Uniform in [lo, hi).
  double Uniform(double lo, double hi);
  /// Uniform integer in [lo, hi].
  int UniformInt(int lo, int hi);
  bool Bernoulli(double p) { return Uniform(0.0, 1.0) < p; }

 private:
  std::mt19937_64 engine_;
};

struct RandomSceneOptions {
  int width = 80;            ///< image columns [px]
  int height = 60;           ///< image rows [px]
  double min_fov_rad = 0.7;  ///< horizontal field of view drawn in [min, max]
  double max_fov_rad = 1.6;
  double min_camera_height_m = 0.5;  ///< above the ground under the camera
  double max_camera_height_m = 3.0;
  double max_pitch_rad = 0.6;          ///< pitch drawn in [-0.1, max]
  double max_roll_rad = 0.3;           ///< roll drawn in [-max, max]
  double max_terrain_slope_rad = 0.7;  ///< steepest planar slope drawn
  int min_objects = 2;
  int max_objects = 10;
  double min_distance_m = 1.5;   ///< objects placed this far ahead (along the heading)..
  double max_distance_m = 15.0;  ///< ..up to this far
};

struct RandomView {
  Scene scene;
  Camera camera;
};

/// A random scene and a camera looking into it: terrain flat, sloped, hilly or a random
/// grid; poles, rocks, boxes and ridges inside the camera's field of view.
RandomView MakeRandomView(std::uint64_t seed, const RandomSceneOptions& options = {});

}  // namespace cairn::sim
