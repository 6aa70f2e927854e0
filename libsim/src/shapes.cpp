#include "cairn/sim/shapes.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <string>

#include "cairn/od/units.hpp"
#include "cairn/sim/random_scene.hpp"

namespace cairn::sim {
namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

// Yaw rotation about the world vertical: local -> world.
Eigen::Matrix3d Yaw(double yaw_rad) {
  const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
  Eigen::Matrix3d r;
  r << c, -s, 0, s, c, 0, 0, 0, 1;
  return r;
}

bool Positive(double v) { return std::isfinite(v) && v > 0.0; }

// A convex solid as the intersection of half-spaces n . p <= d in a local frame.
struct HalfSpaces {
  Eigen::Vector3d origin;    // world position of the local origin
  Eigen::Matrix3d rotation;  // local -> world
  Eigen::Vector3d n[6];
  double d[6];
};

std::optional<RayHit> IntersectHalfSpaces(const HalfSpaces& solid, const Ray& ray, double t_min,
                                          double t_max) {
  const Eigen::Vector3d o = solid.rotation.transpose() * (ray.origin - solid.origin);
  const Eigen::Vector3d dir = solid.rotation.transpose() * ray.direction;
  double t_enter = -std::numeric_limits<double>::infinity();
  double t_exit = std::numeric_limits<double>::infinity();
  int enter_plane = -1;
  for (int i = 0; i < 6; ++i) {
    const double rate = solid.n[i].dot(dir);
    const double gap = solid.d[i] - solid.n[i].dot(o);  // >= 0 inside this half-space
    if (std::abs(rate) < 1e-15) {
      if (gap < 0.0) return std::nullopt;  // parallel and outside
      continue;
    }
    const double t = gap / rate;
    if (rate < 0.0) {
      if (t > t_enter) {
        t_enter = t;
        enter_plane = i;
      }
    } else {
      t_exit = std::min(t_exit, t);
    }
  }
  if (enter_plane < 0 || t_enter > t_exit || t_enter < t_min || t_enter > t_max) {
    return std::nullopt;
  }
  RayHit hit;
  hit.t = t_enter;
  hit.normal = solid.rotation * solid.n[enter_plane];
  return hit;
}

HalfSpaces BoxSolid(const Box& box) {
  HalfSpaces s;
  s.origin = box.centre;
  s.rotation = Yaw(box.yaw_rad);
  for (int axis = 0; axis < 3; ++axis) {
    s.n[2 * axis] = Eigen::Vector3d::Unit(axis);
    s.n[2 * axis + 1] = -Eigen::Vector3d::Unit(axis);
    s.d[2 * axis] = s.d[2 * axis + 1] = 0.5 * box.size[axis];
  }
  return s;
}

HalfSpaces RidgeSolid(const Ridge& ridge) {
  HalfSpaces s;
  s.origin = ridge.base_centre;
  s.rotation = Yaw(ridge.yaw_rad);
  const double h = ridge.height_m;
  // A side through the top edge at `half` from the axis, falling outwards at `slope`.
  auto side = [&](int i, const Eigen::Vector3d& outward, double half, double slope) {
    s.n[i] = std::sin(slope) * outward + std::cos(slope) * Eigen::Vector3d::UnitZ();
    s.d[i] = std::sin(slope) * half + std::cos(slope) * h;
  };
  side(0, Eigen::Vector3d::UnitX(), 0.5 * ridge.top_length_m, ridge.end_slope_rad);
  side(1, -Eigen::Vector3d::UnitX(), 0.5 * ridge.top_length_m, ridge.end_slope_rad);
  side(2, Eigen::Vector3d::UnitY(), 0.5 * ridge.top_width_m, ridge.left_slope_rad);
  side(3, -Eigen::Vector3d::UnitY(), 0.5 * ridge.top_width_m, ridge.right_slope_rad);
  s.n[4] = Eigen::Vector3d::UnitZ();
  s.d[4] = h;
  s.n[5] = -Eigen::Vector3d::UnitZ();
  s.d[5] = 0.0;
  return s;
}

// Smallest root of a t^2 + b t + c = 0 in [t_min, t_max], if any.
std::optional<double> FirstRoot(double a, double b, double c, double t_min, double t_max) {
  if (!(a > 0.0)) return std::nullopt;
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) return std::nullopt;
  // Stable form: q has the sign of b, so no cancellation.
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  double t0 = q / a;
  double t1 = q != 0.0 ? c / q : t0;
  if (t0 > t1) std::swap(t0, t1);
  if (t0 >= t_min && t0 <= t_max) return t0;
  if (t1 >= t_min && t1 <= t_max) return t1;
  return std::nullopt;
}

// Capped cylinder in its own frame: axis along +z from z = 0 to z = height, ray (o, d).
// The normal is in that frame too.
std::optional<RayHit> IntersectUpright(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                       double radius, double height, double t_min, double t_max) {
  const double r2 = radius * radius;
  std::optional<RayHit> best;
  auto offer = [&](double t, const Eigen::Vector3d& normal) {
    if (t >= t_min && t <= t_max && (!best || t < best->t)) {
      best = RayHit{t, normal, kNoHitId};
    }
  };
  // Side: both roots, each kept when it lies between the caps.
  const double a = d.x() * d.x() + d.y() * d.y();
  const double b = 2.0 * (o.x() * d.x() + o.y() * d.y());
  const double c = o.x() * o.x() + o.y() * o.y() - r2;
  if (a > 0.0) {
    const double disc = b * b - 4.0 * a * c;
    if (disc >= 0.0) {
      const double root = std::sqrt(disc);
      for (double t : {(-b - root) / (2.0 * a), (-b + root) / (2.0 * a)}) {
        const Eigen::Vector3d p = o + t * d;
        if (p.z() >= 0.0 && p.z() <= height) {
          offer(t, Eigen::Vector3d(p.x(), p.y(), 0.0) / radius);
        }
      }
    }
  }
  // Caps.
  if (d.z() != 0.0) {
    for (double z : {0.0, height}) {
      const double t = (z - o.z()) / d.z();
      const Eigen::Vector3d p = o + t * d;
      if (p.x() * p.x() + p.y() * p.y() <= r2) {
        offer(t, Eigen::Vector3d(0.0, 0.0, z > 0.0 ? 1.0 : -1.0));
      }
    }
  }
  return best;
}

std::optional<RayHit> IntersectCylinder(const Cylinder& cyl, const Ray& ray, double t_min,
                                        double t_max) {
  return IntersectUpright(ray.origin - cyl.base_centre, ray.direction, cyl.radius_m, cyl.height_m,
                          t_min, t_max);
}

// Rows: two unit vectors across the rod's axis, then the axis: world -> rod frame.
Eigen::Matrix3d RodFrame(const Rod& rod) {
  const Eigen::Vector3d axis = (rod.end - rod.start).normalized();
  const Eigen::Vector3d helper =
      std::abs(axis.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d e1 = axis.cross(helper).normalized();
  Eigen::Matrix3d r;
  r.row(0) = e1.transpose();
  r.row(1) = axis.cross(e1).transpose();
  r.row(2) = axis.transpose();
  return r;
}

std::optional<RayHit> IntersectRod(const Rod& rod, const Ray& ray, double t_min, double t_max) {
  const Eigen::Matrix3d r = RodFrame(rod);
  auto hit = IntersectUpright(r * (ray.origin - rod.start), r * ray.direction, rod.radius_m,
                              (rod.end - rod.start).norm(), t_min, t_max);
  if (hit) hit->normal = r.transpose() * hit->normal;
  return hit;
}

std::optional<RayHit> IntersectEllipsoid(const Ellipsoid& e, const Ray& ray, double t_min,
                                         double t_max) {
  const Eigen::Matrix3d rot = Yaw(e.yaw_rad);
  const Eigen::Vector3d inv_r = e.radii.cwiseInverse();
  // In the frame where the ellipsoid is the unit sphere.
  const Eigen::Vector3d o = (rot.transpose() * (ray.origin - e.centre)).cwiseProduct(inv_r);
  const Eigen::Vector3d d = (rot.transpose() * ray.direction).cwiseProduct(inv_r);
  const auto t = FirstRoot(d.squaredNorm(), 2.0 * o.dot(d), o.squaredNorm() - 1.0, t_min, t_max);
  if (!t) return std::nullopt;
  const Eigen::Vector3d unit_sphere_point = o + *t * d;
  RayHit hit;
  hit.t = *t;
  hit.normal = (rot * unit_sphere_point.cwiseProduct(inv_r)).normalized();
  return hit;
}

std::optional<RayHit> IntersectCluster(const Cluster& cluster, const Ray& ray, double t_min,
                                       double t_max) {
  std::optional<RayHit> best;
  for (const Ellipsoid& e : cluster.parts) {
    if (auto hit = IntersectEllipsoid(e, ray, t_min, best ? best->t : t_max)) best = hit;
  }
  return best;
}

Status ValidateEllipsoid(const Ellipsoid& e, const std::string& what) {
  if (!e.centre.allFinite()) return Error{what + ": centre must be finite"};
  if (!(e.radii.allFinite() && e.radii.minCoeff() > 0.0)) {
    return Error{what + ": radii must be finite and > 0"};
  }
  if (!std::isfinite(e.yaw_rad)) return Error{what + ": yaw_rad must be finite"};
  return Status::Ok();
}

// Extent of an ellipsoid along the world vertical from its centre (yaw keeps z vertical).
double HalfHeight(const Ellipsoid& e) { return e.radii.z(); }

}  // namespace

Cluster MakeBush(double x, double y, double top_z, const Eigen::Vector3d& radii, double yaw_rad,
                 int lumps, double lump_scale, std::uint64_t seed) {
  assert(radii.minCoeff() > 0.0 && lumps >= 0 && lump_scale > 0.0 && lump_scale <= 1.0);
  Random rng(seed);
  Cluster bush;
  bush.parts.push_back(Ellipsoid{Eigen::Vector3d::Zero(), radii, yaw_rad});
  const Eigen::Matrix3d yaw = Yaw(yaw_rad);
  const double lump = lump_scale * radii.minCoeff();
  for (int k = 0; k < lumps; ++k) {
    // One draw per statement: the order of evaluation of arguments is unspecified.
    const double azimuth = rng.Uniform(-3.141592653589793, 3.141592653589793);
    const double elevation = rng.Uniform(-0.3, 1.3);
    const double sx = rng.Uniform(0.8, 1.2);
    const double sy = rng.Uniform(0.8, 1.2);
    const double sz = rng.Uniform(0.6, 1.0);
    const double lump_yaw = rng.Uniform(-3.141592653589793, 3.141592653589793);
    const Eigen::Vector3d on_core(radii.x() * std::cos(elevation) * std::cos(azimuth),
                                  radii.y() * std::cos(elevation) * std::sin(azimuth),
                                  radii.z() * std::sin(elevation));
    bush.parts.push_back(
        Ellipsoid{yaw * on_core, Eigen::Vector3d(sx * lump, sy * lump, sz * lump), lump_yaw});
  }
  double top = -std::numeric_limits<double>::infinity();
  for (const Ellipsoid& e : bush.parts) top = std::max(top, e.centre.z() + HalfHeight(e));
  const Eigen::Vector3d shift(x, y, top_z - top);
  for (Ellipsoid& e : bush.parts) e.centre += shift;
  return bush;
}

bool IsTerrainFeature(const Shape& shape) {
  return std::holds_alternative<Ditch>(shape) || std::holds_alternative<Bank>(shape);
}

Status ValidateShape(const Shape& shape) {
  return std::visit(
      Overloaded{
          [](const Cylinder& c) -> Status {
            if (!c.base_centre.allFinite()) return Error{"cylinder: base_centre must be finite"};
            if (!Positive(c.radius_m)) return Error{"cylinder: radius_m must be finite and > 0"};
            if (!Positive(c.height_m)) return Error{"cylinder: height_m must be finite and > 0"};
            return Status::Ok();
          },
          [](const Ellipsoid& e) -> Status { return ValidateEllipsoid(e, "ellipsoid"); },
          [](const Box& b) -> Status {
            if (!b.centre.allFinite()) return Error{"box: centre must be finite"};
            if (!(b.size.allFinite() && b.size.minCoeff() > 0.0)) {
              return Error{"box: size must be finite and > 0"};
            }
            if (!std::isfinite(b.yaw_rad)) return Error{"box: yaw_rad must be finite"};
            return Status::Ok();
          },
          [](const Ridge& r) -> Status {
            if (!r.base_centre.allFinite()) return Error{"ridge: base_centre must be finite"};
            if (!std::isfinite(r.yaw_rad)) return Error{"ridge: yaw_rad must be finite"};
            if (!Positive(r.top_length_m)) return Error{"ridge: top_length_m must be > 0"};
            if (!Positive(r.top_width_m)) return Error{"ridge: top_width_m must be > 0"};
            if (!Positive(r.height_m)) return Error{"ridge: height_m must be > 0"};
            const auto slope_ok = [](double a) { return a > 0.0 && a <= (0.5 * kPi) + 1e-12; };
            if (!slope_ok(r.left_slope_rad))
              return Error{"ridge: left_slope_rad must be in (0, 90 deg]"};
            if (!slope_ok(r.right_slope_rad))
              return Error{"ridge: right_slope_rad must be in (0, 90 deg]"};
            if (!slope_ok(r.end_slope_rad))
              return Error{"ridge: end_slope_rad must be in (0, 90 deg]"};
            return Status::Ok();
          },
          [](const Rod& r) -> Status {
            if (!r.start.allFinite()) return Error{"rod: start must be finite"};
            if (!r.end.allFinite()) return Error{"rod: end must be finite"};
            if (!((r.end - r.start).norm() > 0.0)) return Error{"rod: end must differ from start"};
            if (!Positive(r.radius_m)) return Error{"rod: radius_m must be finite and > 0"};
            return Status::Ok();
          },
          [](const Cluster& c) -> Status {
            if (c.parts.empty()) return Error{"cluster: parts must not be empty"};
            for (std::size_t i = 0; i < c.parts.size(); ++i) {
              const std::string what = "cluster: parts[" + std::to_string(i) + "]";
              if (Status s = ValidateEllipsoid(c.parts[i], what); !s.ok()) return s;
            }
            return Status::Ok();
          },
          [](const Ditch& d) -> Status {
            if (Status s = ValidateDitch(d); !s.ok()) return Error{"ditch: " + s.message()};
            return Status::Ok();
          },
          [](const Bank& b) -> Status {
            if (Status s = ValidateBank(b); !s.ok()) return Error{"bank: " + s.message()};
            return Status::Ok();
          },
      },
      shape);
}

std::optional<RayHit> Intersect(const Shape& shape, const Ray& ray, double t_min, double t_max) {
  return std::visit(
      Overloaded{
          [&](const Cylinder& c) { return IntersectCylinder(c, ray, t_min, t_max); },
          [&](const Ellipsoid& e) { return IntersectEllipsoid(e, ray, t_min, t_max); },
          [&](const Box& b) { return IntersectHalfSpaces(BoxSolid(b), ray, t_min, t_max); },
          [&](const Ridge& r) { return IntersectHalfSpaces(RidgeSolid(r), ray, t_min, t_max); },
          [&](const Rod& r) { return IntersectRod(r, ray, t_min, t_max); },
          [&](const Cluster& c) { return IntersectCluster(c, ray, t_min, t_max); },
          [](const Ditch&) { return std::optional<RayHit>(); },
          [](const Bank&) { return std::optional<RayHit>(); },
      },
      shape);
}

BoundingSphere Bound(const Shape& shape) {
  return std::visit(
      Overloaded{
          [](const Cylinder& c) {
            return BoundingSphere{c.base_centre + Eigen::Vector3d(0, 0, 0.5 * c.height_m),
                                  std::hypot(c.radius_m, 0.5 * c.height_m)};
          },
          [](const Ellipsoid& e) {
            return BoundingSphere{e.centre, e.radii.maxCoeff()};
          },
          [](const Box& b) {
            return BoundingSphere{b.centre, 0.5 * b.size.norm()};
          },
          [](const Ridge& r) {
            const double h = r.height_m;
            const double half_length = 0.5 * r.top_length_m + h / std::tan(r.end_slope_rad);
            const double half_width =
                0.5 * r.top_width_m + h / std::tan(std::min(r.left_slope_rad, r.right_slope_rad));
            return BoundingSphere{r.base_centre + Eigen::Vector3d(0, 0, 0.5 * h),
                                  Eigen::Vector3d(half_length, half_width, 0.5 * h).norm()};
          },
          [](const Rod& r) {
            return BoundingSphere{0.5 * (r.start + r.end),
                                  std::hypot(r.radius_m, 0.5 * (r.end - r.start).norm())};
          },
          [](const Cluster& c) {
            if (c.parts.empty()) return BoundingSphere{};
            Eigen::Vector3d centre = Eigen::Vector3d::Zero();
            for (const Ellipsoid& e : c.parts) centre += e.centre;
            centre /= static_cast<double>(c.parts.size());
            double radius = 0.0;
            for (const Ellipsoid& e : c.parts) {
              radius = std::max(radius, (e.centre - centre).norm() + e.radii.maxCoeff());
            }
            return BoundingSphere{centre, radius};
          },
          [](const Ditch& d) {
            const Eigen::Vector2d mid = 0.5 * (d.start + d.end);
            return BoundingSphere{Eigen::Vector3d(mid.x(), mid.y(), 0.0),
                                  0.5 * (d.end - d.start).norm() + 0.5 * d.top_width_m + d.depth_m};
          },
          [](const Bank& b) {
            return BoundingSphere{Eigen::Vector3d(b.centre.x(), b.centre.y(), 0.0),
                                  std::numeric_limits<double>::infinity()};
          },
      },
      shape);
}

double Bottom(const Shape& shape) {
  return std::visit(Overloaded{
                        [](const Cylinder& c) { return c.base_centre.z(); },
                        [](const Ellipsoid& e) { return e.centre.z() - e.radii.z(); },
                        [](const Box& b) { return b.centre.z() - 0.5 * b.size.z(); },
                        [](const Ridge& r) { return r.base_centre.z(); },
                        [](const Rod& r) {
                          const Eigen::Vector3d axis = (r.end - r.start).normalized();
                          const double reach =
                              r.radius_m * std::sqrt(std::max(0.0, 1.0 - axis.z() * axis.z()));
                          return std::min(r.start.z(), r.end.z()) - reach;
                        },
                        [](const Cluster& c) {
                          double z = std::numeric_limits<double>::infinity();
                          for (const Ellipsoid& e : c.parts)
                            z = std::min(z, e.centre.z() - e.radii.z());
                          return z;
                        },
                        [](const Ditch& d) { return -d.depth_m; },
                        [](const Bank&) { return 0.0; },
                    },
                    shape);
}

double Top(const Shape& shape) {
  return std::visit(Overloaded{
                        [](const Cylinder& c) { return c.base_centre.z() + c.height_m; },
                        [](const Ellipsoid& e) { return e.centre.z() + e.radii.z(); },
                        [](const Box& b) { return b.centre.z() + 0.5 * b.size.z(); },
                        [](const Ridge& r) { return r.base_centre.z() + r.height_m; },
                        [](const Rod& r) {
                          const Eigen::Vector3d axis = (r.end - r.start).normalized();
                          const double reach =
                              r.radius_m * std::sqrt(std::max(0.0, 1.0 - axis.z() * axis.z()));
                          return std::max(r.start.z(), r.end.z()) + reach;
                        },
                        [](const Cluster& c) {
                          double z = -std::numeric_limits<double>::infinity();
                          for (const Ellipsoid& e : c.parts)
                            z = std::max(z, e.centre.z() + e.radii.z());
                          return z;
                        },
                        [](const Ditch&) { return 0.0; },
                        [](const Bank& b) { return b.rise_m; },
                    },
                    shape);
}

}  // namespace cairn::sim
