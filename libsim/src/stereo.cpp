#include "cairn/sim/stereo.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "cairn/od/parallel.hpp"
#include "sampling.hpp"

namespace cairn::sim {
namespace {

/// Lattice value in [-1, 1] of one octave's integer cell corner.
double LatticeValue(std::uint64_t octave_seed, std::int64_t ix, std::int64_t iy, std::int64_t iz) {
  std::uint64_t h = detail::Mix(octave_seed, static_cast<std::uint64_t>(ix));
  h = detail::Mix(h, static_cast<std::uint64_t>(iy));
  h = detail::Mix(h, static_cast<std::uint64_t>(iz));
  return static_cast<double>(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;  // 2^53
}

double Smooth(double t) { return t * t * (3.0 - 2.0 * t); }

/// Value noise in [-1, 1]: lattice values interpolated with a smoothstep per axis, so the
/// pattern is continuous (a surface point seen from two cameras gets one value).
double ValueNoise(std::uint64_t octave_seed, const Eigen::Vector3d& p) {
  const double fx = std::floor(p.x()), fy = std::floor(p.y()), fz = std::floor(p.z());
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy),
             iz = static_cast<std::int64_t>(fz);
  const double tx = Smooth(p.x() - fx), ty = Smooth(p.y() - fy), tz = Smooth(p.z() - fz);
  double v[2][2][2];
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      for (int c = 0; c < 2; ++c) v[a][b][c] = LatticeValue(octave_seed, ix + a, iy + b, iz + c);
    }
  }
  auto lerp = [](double lo, double hi, double t) { return lo + (hi - lo) * t; };
  const double x00 = lerp(v[0][0][0], v[1][0][0], tx), x10 = lerp(v[0][1][0], v[1][1][0], tx);
  const double x01 = lerp(v[0][0][1], v[1][0][1], tx), x11 = lerp(v[0][1][1], v[1][1][1], tx);
  return lerp(lerp(x00, x10, ty), lerp(x01, x11, ty), tz);
}

double Albedo(const SurfaceTexture& texture, const Eigen::Vector3d& p_world, int id) {
  if (std::find(texture.plain_ids.begin(), texture.plain_ids.end(), id) !=
      texture.plain_ids.end()) {
    return texture.albedo;
  }
  double sum = 0.0, weight_sum = 0.0, weight = 1.0, size = texture.feature_size_m;
  for (int k = 0; k < texture.octaves; ++k) {
    sum += weight *
           ValueNoise(detail::Mix(texture.seed, static_cast<std::uint64_t>(k)), p_world / size);
    weight_sum += weight;
    weight *= texture.persistence;
    size *= 0.5;
  }
  // A sum of value noises gathers near 0 (its spread is about a third of its range):
  // stretching it by 3 and clipping gives a pattern that uses the whole contrast, with
  // sharp patches like lichen on rock.
  const double n = std::clamp(3.0 * sum / weight_sum, -1.0, 1.0);
  return texture.albedo * (1.0 + texture.contrast * n);
}

Error Bad(const std::string& what, const std::string& field, const std::string& expected) {
  return Error{what + ": field '" + field + "' must be " + expected};
}

}  // namespace

Status SurfaceTexture::Validate() const {
  const std::string what = "surface texture";
  if (!std::isfinite(feature_size_m) || feature_size_m <= 0.0) {
    return Bad(what, "feature_size", "a positive length [m]");
  }
  if (octaves < 1 || octaves > 12) return Bad(what, "octaves", "1..12");
  if (!std::isfinite(persistence) || persistence <= 0.0 || persistence > 1.0) {
    return Bad(what, "persistence", "in (0, 1]");
  }
  if (!std::isfinite(albedo) || albedo <= 0.0 || albedo > 1.0)
    return Bad(what, "albedo", "in (0, 1]");
  if (!std::isfinite(contrast) || contrast < 0.0 || contrast > 1.0) {
    return Bad(what, "contrast", "in [0, 1]");
  }
  return Status::Ok();
}

Status TexturedImageSpec::Validate() const {
  if (Status s = texture.Validate(); !s) return s;
  const std::string what = "textured image";
  if (!sun_world.allFinite() || sun_world.norm() == 0.0) {
    return Bad(what, "sun", "a finite, non-zero direction");
  }
  if (!std::isfinite(ambient) || ambient < 0.0 || ambient > 1.0) {
    return Bad(what, "ambient", "in [0, 1]");
  }
  if (!std::isfinite(sky_grey) || sky_grey < 0.0 || sky_grey > 255.0) {
    return Bad(what, "sky_grey", "in [0, 255]");
  }
  if (supersampling < 1 || supersampling > 8) return Bad(what, "supersampling", "1..8");
  if (!std::isfinite(noise_sigma) || noise_sigma < 0.0) return Bad(what, "noise_sigma", ">= 0");
  if (!std::isfinite(max_range_m) || max_range_m <= 0.0) {
    return Bad(what, "max_range", "a positive range [m]");
  }
  return Status::Ok();
}

Status StereoRigSpec::Validate() const {
  if (Status s = model.Validate(); !s) return Error{"stereo rig: " + s.message()};
  if (!std::isfinite(baseline_m) || baseline_m <= 0.0) {
    return Bad("stereo rig", "baseline", "a positive distance [m]");
  }
  return image.Validate();
}

Expected<GreyImage> RenderGrey(const Scene& scene, const Camera& camera,
                               const TexturedImageSpec& spec, std::uint64_t seed) {
  if (Status s = spec.Validate(); !s) return s.error();
  if (Status s = camera.model.Validate(); !s) return Error{"camera: " + s.message()};
  if (Status s = scene.Validate(); !s) return Error{"scene: " + s.message()};
  const od::PinholeModel& m = camera.model;
  GreyImage image;
  image.width = m.width;
  image.height = m.height;
  image.data.assign(static_cast<std::size_t>(m.width) * m.height, 0);
  std::vector<double> radiance(image.data.size(), 0.0);

  RenderOptions options;
  options.max_range_m = spec.max_range_m;
  const RayCaster caster(scene);
  const Eigen::Vector3d sun = spec.sun_world.normalized();
  const int s = spec.supersampling;
  od::ParallelFor(m.height, 0, [&](int row) {
    for (int col = 0; col < m.width; ++col) {
      double sum = 0.0;
      for (int i = 0; i < s; ++i) {
        for (int j = 0; j < s; ++j) {
          // Sub-pixel sample centres on an s x s grid over the pixel's square.
          const double u = col - 0.5 + (j + 0.5) / s;
          const double v = row - 0.5 + (i + 0.5) / s;
          const Ray ray = camera.PixelRay(u, v);
          const std::optional<RayHit> hit = caster.Cast(ray, options);
          if (!hit) {
            sum += spec.sky_grey;
            continue;
          }
          const double albedo = Albedo(spec.texture, ray.At(hit->t), hit->id);
          // Sky light from the whole upper hemisphere and the sun: a face turned away from
          // the sun is darker, never black.
          const double light =
              spec.ambient + (1.0 - spec.ambient) * 0.5 * (1.0 + hit->normal.dot(sun));
          sum += 255.0 * albedo * light;
        }
      }
      radiance[static_cast<std::size_t>(row) * m.width + col] = sum / (s * s);
    }
  });
  // Noise after the parallel part, in pixel order: the same image for a seed on any
  // number of threads.
  Random rng(seed);
  for (std::size_t i = 0; i < radiance.size(); ++i) {
    double grey = radiance[i];
    if (spec.noise_sigma > 0.0) grey += spec.noise_sigma * detail::StandardNormal(rng);
    image.data[i] = static_cast<std::uint8_t>(std::clamp(std::round(grey), 0.0, 255.0));
  }
  return image;
}

Expected<StereoFrame> RenderStereoPair(const Scene& scene, const Camera& left_camera,
                                       const StereoRigSpec& rig, std::uint64_t seed) {
  if (Status s = rig.Validate(); !s) return s.error();
  StereoFrame frame;
  frame.baseline_m = rig.baseline_m;
  frame.left_camera = left_camera;
  frame.left_camera.model = rig.model;
  frame.right_camera = frame.left_camera;
  frame.right_camera.T_world_camera.translation() +=
      frame.left_camera.T_world_camera.linear() * Eigen::Vector3d(rig.baseline_m, 0.0, 0.0);

  Expected<GreyImage> left = RenderGrey(scene, frame.left_camera, rig.image, detail::Mix(seed, 0));
  if (!left) return left.error();
  Expected<GreyImage> right =
      RenderGrey(scene, frame.right_camera, rig.image, detail::Mix(seed, 1));
  if (!right) return right.error();
  RenderOptions options;
  options.max_range_m = rig.image.max_range_m;
  Expected<DepthFrame> truth = RenderDepth(scene, frame.left_camera, options);
  if (!truth) return truth.error();
  frame.left = std::move(*left);
  frame.right = std::move(*right);
  frame.left_truth = std::move(*truth);
  return frame;
}

}  // namespace cairn::sim
