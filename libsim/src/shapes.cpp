#include "cairn/sim/shapes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace cairn::sim {
namespace {

constexpr double kHalfPi = 1.5707963267948966;

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

std::optional<RayHit> IntersectCylinder(const Cylinder& cyl, const Ray& ray, double t_min,
                                        double t_max) {
  const Eigen::Vector3d o = ray.origin - cyl.base_centre;
  const Eigen::Vector3d& d = ray.direction;
  const double r2 = cyl.radius_m * cyl.radius_m;
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
        if (p.z() >= 0.0 && p.z() <= cyl.height_m) {
          offer(t, Eigen::Vector3d(p.x(), p.y(), 0.0) / cyl.radius_m);
        }
      }
    }
  }
  // Caps.
  if (d.z() != 0.0) {
    for (double z : {0.0, cyl.height_m}) {
      const double t = (z - o.z()) / d.z();
      const Eigen::Vector3d p = o + t * d;
      if (p.x() * p.x() + p.y() * p.y() <= r2) {
        offer(t, Eigen::Vector3d(0.0, 0.0, z > 0.0 ? 1.0 : -1.0));
      }
    }
  }
  return best;
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

}  // namespace

Status ValidateShape(const Shape& shape) {
  return std::visit(Overloaded{
                        [](const Cylinder& c) -> Status {
                          if (!c.base_centre.allFinite())
                            return Error{"cylinder: base_centre must be finite"};
                          if (!Positive(c.radius_m))
                            return Error{"cylinder: radius_m must be finite and > 0"};
                          if (!Positive(c.height_m))
                            return Error{"cylinder: height_m must be finite and > 0"};
                          return Status::Ok();
                        },
                        [](const Ellipsoid& e) -> Status {
                          if (!e.centre.allFinite())
                            return Error{"ellipsoid: centre must be finite"};
                          if (!(e.radii.allFinite() && e.radii.minCoeff() > 0.0)) {
                            return Error{"ellipsoid: radii must be finite and > 0"};
                          }
                          if (!std::isfinite(e.yaw_rad))
                            return Error{"ellipsoid: yaw_rad must be finite"};
                          return Status::Ok();
                        },
                        [](const Box& b) -> Status {
                          if (!b.centre.allFinite()) return Error{"box: centre must be finite"};
                          if (!(b.size.allFinite() && b.size.minCoeff() > 0.0)) {
                            return Error{"box: size must be finite and > 0"};
                          }
                          if (!std::isfinite(b.yaw_rad))
                            return Error{"box: yaw_rad must be finite"};
                          return Status::Ok();
                        },
                        [](const Ridge& r) -> Status {
                          if (!r.base_centre.allFinite())
                            return Error{"ridge: base_centre must be finite"};
                          if (!std::isfinite(r.yaw_rad))
                            return Error{"ridge: yaw_rad must be finite"};
                          if (!Positive(r.top_length_m))
                            return Error{"ridge: top_length_m must be > 0"};
                          if (!Positive(r.top_width_m))
                            return Error{"ridge: top_width_m must be > 0"};
                          if (!Positive(r.height_m)) return Error{"ridge: height_m must be > 0"};
                          const auto slope_ok = [](double a) {
                            return a > 0.0 && a <= kHalfPi + 1e-12;
                          };
                          if (!slope_ok(r.left_slope_rad))
                            return Error{"ridge: left_slope_rad must be in (0, 90 deg]"};
                          if (!slope_ok(r.right_slope_rad))
                            return Error{"ridge: right_slope_rad must be in (0, 90 deg]"};
                          if (!slope_ok(r.end_slope_rad))
                            return Error{"ridge: end_slope_rad must be in (0, 90 deg]"};
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
      },
      shape);
}

double Bottom(const Shape& shape) {
  return std::visit(Overloaded{
                        [](const Cylinder& c) { return c.base_centre.z(); },
                        [](const Ellipsoid& e) { return e.centre.z() - e.radii.z(); },
                        [](const Box& b) { return b.centre.z() - 0.5 * b.size.z(); },
                        [](const Ridge& r) { return r.base_centre.z(); },
                    },
                    shape);
}

double Top(const Shape& shape) {
  return std::visit(Overloaded{
                        [](const Cylinder& c) { return c.base_centre.z() + c.height_m; },
                        [](const Ellipsoid& e) { return e.centre.z() + e.radii.z(); },
                        [](const Box& b) { return b.centre.z() + 0.5 * b.size.z(); },
                        [](const Ridge& r) { return r.base_centre.z() + r.height_m; },
                    },
                    shape);
}

}  // namespace cairn::sim
