// Rendered stereo pairs: grey images of a textured scene seen by a rectified camera pair,
// with the left view's true depth, for testing stereo matching against ground truth.
//
// Surfaces carry a procedural texture that is a function of the world-space hit point (a
// fractal of 3-D value noise), so both cameras see the same pattern on the same surface,
// as with real paint, bark or soil. Shading is Lambertian (view-independent: a surface
// point has the same grey in both views) under one distant light plus ambient light. Each
// pixel averages supersampling^2 rays over its square, like a sensor pixel integrating
// light; independent Gaussian noise is added per image. Rays that meet nothing see a
// uniform sky, and surfaces listed as plain have a uniform albedo: neither has texture to
// match, which is what a matcher must leave as holes.
//
// Frames: world z up; the right camera sits baseline_m along the left camera's optical +x
// axis with the same orientation and model (an ideal rectified rig), so a point at z-depth
// z [m] has disparity fx * baseline / z [px].
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::sim {

/// The surface pattern: albedo(p) = albedo * (1 + contrast * n(p)), n in [-1, 1] a fractal
/// of value noise over world points p, octave k of feature size feature_size_m / 2^k and
/// weight persistence^k (normalised).
struct SurfaceTexture {
  double feature_size_m = 0.4;  ///< feature size of the coarsest octave [m], > 0
  int octaves = 6;              ///< 1..12
  double persistence = 0.8;     ///< weight ratio of successive octaves, (0, 1]
  double albedo = 0.5;          ///< mean reflectance, (0, 1]
  double contrast = 0.6;        ///< relative albedo variation, [0, 1]
  std::vector<int> plain_ids;   ///< ids (objects, kTerrainId) painted uniformly: no texture
  std::uint64_t seed = 1;       ///< the pattern
  /// Names the first bad field (key = member name without unit suffix).
  Status Validate() const;
};

/// How a grey image of the scene is made.
struct TexturedImageSpec {
  SurfaceTexture texture;
  /// Direction towards the light, world frame (need not be unit length, not zero).
  Eigen::Vector3d sun_world = Eigen::Vector3d(0.4, 0.3, 0.85);
  double ambient = 0.35;      ///< share of light independent of the normal, [0, 1]
  double sky_grey = 200.0;    ///< grey of rays that meet nothing, [0, 255]
  int supersampling = 3;      ///< rays per pixel along each axis, 1..8
  double noise_sigma = 1.0;   ///< Gaussian image noise [grey levels], >= 0
  double max_range_m = 80.0;  ///< farther surfaces are sky (distance along the ray) [m]
  Status Validate() const;
};

/// An ideal rectified stereo rig.
struct StereoRigSpec {
  od::PinholeModel model;   ///< both cameras
  double baseline_m = 0.3;  ///< right camera along the left's +x [m], > 0
  TexturedImageSpec image;
  Status Validate() const;
};

/// 8-bit grey image, row-major (data[row * width + col]).
struct GreyImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> data;
  std::uint8_t at(int row, int col) const {
    return data[static_cast<std::size_t>(row) * width + col];
  }
};

/// Renders the grey image `camera` sees (its own model), noise drawn from `seed`. Fails
/// when the spec, the camera model or the scene does not validate.
Expected<GreyImage> RenderGrey(const Scene& scene, const Camera& camera,
                               const TexturedImageSpec& spec, std::uint64_t seed);

/// A rendered rectified pair and the truth of the left view.
struct StereoFrame {
  GreyImage left;
  GreyImage right;
  /// Depth, object ids and normals at the left pixel centres (RenderDepth), up to the
  /// spec's max range; up_optical is gravity's up in the left optical frame.
  DepthFrame left_truth;
  Camera left_camera;   ///< with the rig's model
  Camera right_camera;  ///< left_camera moved baseline_m along its optical +x
  double baseline_m = 0.0;
};

/// Renders the pair from `left_camera`'s pose (the rig's model is used, camera.model
/// ignored); image noise seeded from `seed` (independent in each image).
Expected<StereoFrame> RenderStereoPair(const Scene& scene, const Camera& left_camera,
                                       const StereoRigSpec& rig, std::uint64_t seed);

}  // namespace cairn::sim
