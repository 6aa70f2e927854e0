#include "cairn/sim/render.hpp"

#include <cmath>
#include <string>

#include "cairn/od/parallel.hpp"

namespace cairn::sim {

RayCaster::RayCaster(const Scene& scene) : scene_(scene) {
  prepared_.reserve(scene.objects().size());
  for (const Object& o : scene.objects()) {
    if (!IsTerrainFeature(o.shape)) prepared_.push_back({&o.shape, o.id, Bound(o.shape)});
  }
}

std::optional<RayHit> RayCaster::Cast(const Ray& ray, const RenderOptions& options) const {
  std::optional<RayHit> best;
  double t_max = options.max_range_m;
  // Objects first: a near object shortens the terrain march.
  for (std::size_t i = 0; i < prepared_.size(); ++i) {
    const BoundingSphere& b = prepared_[i].bound;
    const Eigen::Vector3d oc = b.centre - ray.origin;
    const double along = oc.dot(ray.direction);
    const double r2 = b.radius_m * b.radius_m;
    if (oc.squaredNorm() - along * along > r2) continue;                   // passes beside
    if (along + b.radius_m < 0.0 || along - b.radius_m > t_max) continue;  // behind, beyond
    if (auto hit = Intersect(*prepared_[i].shape, ray, 0.0, t_max)) {
      hit->id = prepared_[i].id;
      t_max = hit->t;
      best = hit;
    }
  }
  if (auto hit = scene_.terrain().Intersect(ray, t_max, options.terrain_tolerance_m)) {
    if (!best || hit->t < best->t) best = hit;
  }
  return best;
}

Expected<DepthFrame> RenderDepth(const Scene& scene, const Camera& camera,
                                 const RenderOptions& options) {
  if (Status s = camera.model.Validate(); !s.ok()) return Error{"camera: " + s.message()};
  if (Status s = scene.Validate(); !s.ok()) return Error{"scene: " + s.message()};
  if (!(options.max_range_m > 0.0) || !(options.terrain_tolerance_m > 0.0)) {
    return Error{"render options: max_range_m and terrain_tolerance_m must be > 0"};
  }
  const od::PinholeModel& m = camera.model;
  DepthFrame frame;
  frame.model = m;
  frame.up_optical = camera.UpOptical();
  const int n = m.width * m.height;
  frame.depth_m.assign(n, 0.0f);
  frame.object_id.assign(n, kNoHitId);
  frame.normal.assign(n, Eigen::Vector3f::Zero());

  const RayCaster caster(scene);
  const Eigen::Matrix3d& rotation = camera.T_world_camera.linear();
  od::ParallelFor(m.height, options.threads, [&](int row) {
    Ray ray;
    ray.origin = camera.T_world_camera.translation();
    for (int col = 0; col < m.width; ++col) {
      const Eigen::Vector3d d((col - m.cx) / m.fx, (row - m.cy) / m.fy, 1.0);
      const double length = d.norm();
      ray.direction = rotation * (d / length);
      const auto hit = caster.Cast(ray, options);
      if (!hit) continue;
      const int i = row * m.width + col;
      frame.depth_m[i] = static_cast<float>(hit->t / length);  // z-depth
      frame.object_id[i] = hit->id;
      frame.normal[i] = hit->normal.cast<float>();
    }
  });
  return frame;
}

}  // namespace cairn::sim
