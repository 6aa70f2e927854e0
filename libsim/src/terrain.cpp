#include "cairn/sim/terrain.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "cairn/od/units.hpp"

namespace cairn::sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bool SlopeOk(double a) { return std::isfinite(a) && a > 0.0 && a <= kMaxFeatureSlopeRad + 1e-12; }

// Parameters t where x0 + t dx lies in [lo, hi], intersected with [*t0, *t1].
bool ClipSlab(double x0, double dx, double lo, double hi, double* t0, double* t1) {
  if (std::abs(dx) < 1e-15) return x0 >= lo && x0 <= hi;
  double a = (lo - x0) / dx, b = (hi - x0) / dx;
  if (a > b) std::swap(a, b);
  *t0 = std::max(*t0, a);
  *t1 = std::min(*t1, b);
  return *t0 <= *t1;
}

}  // namespace

double Ditch::FloorWidth() const { return top_width_m - 2.0 * depth_m / std::tan(wall_slope_rad); }

double Bank::FaceWidth() const { return rise_m / std::tan(face_slope_rad); }

Status ValidateDitch(const Ditch& d) {
  if (!d.start.allFinite()) return Error{"start: must be finite"};
  if (!d.end.allFinite()) return Error{"end: must be finite"};
  if (!(d.end - d.start).allFinite() || (d.end - d.start).norm() <= 0.0) {
    return Error{"end: must differ from start"};
  }
  if (!(std::isfinite(d.depth_m) && d.depth_m > 0.0)) return Error{"depth_m: must be > 0"};
  if (!(std::isfinite(d.top_width_m) && d.top_width_m > 0.0)) {
    return Error{"top_width_m: must be > 0"};
  }
  if (!SlopeOk(d.wall_slope_rad)) return Error{"wall_slope_rad: must be in (0, 85 deg]"};
  if (d.FloorWidth() < -1e-9) {
    return Error{"top_width_m: too narrow for depth_m at wall_slope_rad (no floor): needs >= " +
                 std::to_string(2.0 * d.depth_m / std::tan(d.wall_slope_rad)) + " m"};
  }
  return Status::Ok();
}

Status ValidateBank(const Bank& b) {
  if (!b.centre.allFinite()) return Error{"centre: must be finite"};
  if (!std::isfinite(b.uphill_heading_rad)) return Error{"uphill_heading_rad: must be finite"};
  if (!(std::isfinite(b.rise_m) && b.rise_m > 0.0)) return Error{"rise_m: must be > 0"};
  if (!SlopeOk(b.face_slope_rad)) return Error{"face_slope_rad: must be in (0, 85 deg]"};
  return Status::Ok();
}

Terrain Terrain::Flat(double height_m) {
  Terrain t;
  t.height_m_ = height_m;
  return t;
}

Terrain Terrain::Plane(double height_m, const Eigen::Vector2d& gradient) {
  Terrain t;
  t.height_m_ = height_m;
  t.gradient_ = gradient;
  return t;
}

Terrain Terrain::Slope(double height_m, double slope_rad, double uphill_heading_rad) {
  const double g = std::tan(slope_rad);
  return Plane(height_m,
               Eigen::Vector2d(g * std::cos(uphill_heading_rad), g * std::sin(uphill_heading_rad)));
}

Terrain::Wave Terrain::Prepare(const SineWave& w) {
  const double k = (2.0 * kPi) / w.wavelength_m;
  return {w.amplitude_m, k * std::cos(w.direction_rad), k * std::sin(w.direction_rad), w.phase_rad};
}

Terrain Terrain::Hills(double height_m, std::vector<SineWave> waves) {
  Terrain t;
  t.height_m_ = height_m;
  for (const SineWave& w : waves) t.waves_.push_back(Prepare(w));
  return t;
}

Expected<Terrain> Terrain::FromGrid(HeightGrid grid) {
  if (grid.cols < 2 || grid.rows < 2) {
    return Error{"height grid: cols and rows must be >= 2, got " + std::to_string(grid.cols) +
                 " x " + std::to_string(grid.rows)};
  }
  if (!(grid.resolution_m > 0.0) || !std::isfinite(grid.resolution_m)) {
    return Error{"height grid: resolution_m must be finite and > 0"};
  }
  if (!grid.origin.allFinite()) return Error{"height grid: origin must be finite"};
  const std::size_t expected = static_cast<std::size_t>(grid.cols) * grid.rows;
  if (grid.heights.size() != expected) {
    return Error{"height grid: heights has " + std::to_string(grid.heights.size()) +
                 " values, expected rows * cols = " + std::to_string(expected)};
  }
  double max_dx = 0.0, max_dy = 0.0;
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const double h = grid.heights[r * grid.cols + c];
      if (!std::isfinite(h)) {
        return Error{"height grid: heights[" + std::to_string(r * grid.cols + c) +
                     "] is not finite"};
      }
      if (c + 1 < grid.cols)
        max_dx = std::max(max_dx, std::abs(grid.heights[r * grid.cols + c + 1] - h));
      if (r + 1 < grid.rows)
        max_dy = std::max(max_dy, std::abs(grid.heights[(r + 1) * grid.cols + c] - h));
    }
  }
  Terrain t;
  // Inside a bilinear cell each partial derivative is a convex mix of edge differences.
  t.grid_max_gradient_ = std::hypot(max_dx, max_dy) / grid.resolution_m;
  t.grid_max_slope_x_ = max_dx / grid.resolution_m;
  t.grid_max_slope_y_ = max_dy / grid.resolution_m;
  t.grid_ = std::move(grid);
  return t;
}

Terrain Terrain::FromFunction(std::function<double(double, double)> height, double max_gradient) {
  Terrain t;
  t.function_ = std::move(height);
  t.function_max_gradient_ = std::max(0.0, max_gradient);
  return t;
}

Terrain& Terrain::AddWave(const SineWave& wave) {
  waves_.push_back(Prepare(wave));
  return *this;
}

Terrain& Terrain::AddPlane(double height_m, const Eigen::Vector2d& gradient) {
  height_m_ += height_m;
  gradient_ += gradient;
  return *this;
}

Terrain& Terrain::AddDitch(const Ditch& ditch, int id) {
  assert(ValidateDitch(ditch).ok());
  Feature f;
  f.is_ditch = true;
  f.id = id;
  f.origin = ditch.start;
  f.length = (ditch.end - ditch.start).norm();
  f.u = (ditch.end - ditch.start) / f.length;
  f.v = Eigen::Vector2d(-f.u.y(), f.u.x());
  f.half_width = 0.5 * ditch.top_width_m;
  f.depth = ditch.depth_m;
  f.tan_slope = std::tan(ditch.wall_slope_rad);
  f.mark_inner = f.half_width - f.depth / f.tan_slope;
  features_.push_back(f);
  return *this;
}

Terrain& Terrain::AddBank(const Bank& bank, int id) {
  assert(ValidateBank(bank).ok());
  Feature f;
  f.is_ditch = false;
  f.id = id;
  f.origin = bank.centre;
  f.v = Eigen::Vector2d(std::cos(bank.uphill_heading_rad), std::sin(bank.uphill_heading_rad));
  f.u = Eigen::Vector2d(f.v.y(), -f.v.x());
  f.half_width = 0.5 * bank.FaceWidth();
  f.depth = bank.rise_m;
  f.tan_slope = std::tan(bank.face_slope_rad);
  features_.push_back(f);
  return *this;
}

double Terrain::FeatureCoordinate(const Feature& f, double x, double y) const {
  const Eigen::Vector2d q(x - f.origin.x(), y - f.origin.y());
  if (!f.is_ditch) return q.dot(f.v);
  const double a = std::clamp(q.dot(f.u), 0.0, f.length);
  return (q - a * f.u).norm();
}

double Terrain::FeatureHeight(const Feature& f, double x, double y) const {
  const double s = FeatureCoordinate(f, x, y);
  if (f.is_ditch) return -std::clamp((f.half_width - s) * f.tan_slope, 0.0, f.depth);
  if (f.half_width <= 0.0) return s >= 0.0 ? f.depth : 0.0;
  return f.depth * std::clamp(0.5 + 0.5 * s / f.half_width, 0.0, 1.0);
}

Eigen::Vector2d Terrain::FeatureGradient(const Feature& f, double x, double y) const {
  if (!FeatureMarks(f, x, y)) return Eigen::Vector2d::Zero();
  if (!f.is_ditch) return f.tan_slope * f.v;
  const Eigen::Vector2d q(x - f.origin.x(), y - f.origin.y());
  const double a = std::clamp(q.dot(f.u), 0.0, f.length);
  const Eigen::Vector2d out = q - a * f.u;
  const double s = out.norm();
  if (s <= 0.0) return Eigen::Vector2d::Zero();
  return f.tan_slope * out / s;  // rises outwards, towards the rim
}

bool Terrain::FeatureMarks(const Feature& f, double x, double y) const {
  const double s = FeatureCoordinate(f, x, y);
  if (f.is_ditch) return s < f.half_width && s > f.mark_inner;
  return std::abs(s) < f.half_width;
}

bool Terrain::FeatureSpan(const Feature& f, const Ray& ray, double* t0, double* t1) const {
  constexpr double kMargin = 1e-6;  // [m], against rounding at the footprint's edge
  const Eigen::Vector2d o(ray.origin.x() - f.origin.x(), ray.origin.y() - f.origin.y());
  const Eigen::Vector2d d(ray.direction.x(), ray.direction.y());
  *t0 = -kInf;
  *t1 = kInf;
  const double hw = f.half_width + kMargin;
  if (!ClipSlab(o.dot(f.v), d.dot(f.v), -hw, hw, t0, t1)) return false;
  if (f.is_ditch && !ClipSlab(o.dot(f.u), d.dot(f.u), -hw, f.length + hw, t0, t1)) return false;
  return true;
}

int Terrain::IdAt(double x, double y) const {
  for (const Feature& f : features_) {
    if (f.id != kTerrainId && FeatureMarks(f, x, y)) return f.id;
  }
  return kTerrainId;
}

double Terrain::GridHeight(double x, double y) const {
  const HeightGrid& g = *grid_;
  const double fx = std::clamp((x - g.origin.x()) / g.resolution_m, 0.0, g.cols - 1.0);
  const double fy = std::clamp((y - g.origin.y()) / g.resolution_m, 0.0, g.rows - 1.0);
  const int c = std::min(static_cast<int>(fx), g.cols - 2);
  const int r = std::min(static_cast<int>(fy), g.rows - 2);
  const double a = fx - c, b = fy - r;
  const double* row0 = &g.heights[r * g.cols + c];
  const double* row1 = row0 + g.cols;
  return (1 - b) * ((1 - a) * row0[0] + a * row0[1]) + b * ((1 - a) * row1[0] + a * row1[1]);
}

double Terrain::RestHeight(double x, double y) const {
  double h = height_m_ + gradient_.x() * x + gradient_.y() * y;
  for (const Wave& w : waves_) h += w.amplitude * std::sin(w.kx * x + w.ky * y + w.phase);
  if (grid_) h += GridHeight(x, y);
  if (function_) h += function_(x, y);
  return h;
}

double Terrain::Height(double x, double y) const {
  double h = RestHeight(x, y);
  for (const Feature& f : features_) h += FeatureHeight(f, x, y);
  return h;
}

Eigen::Vector3d Terrain::Normal(double x, double y) const {
  Eigen::Vector2d grad = gradient_;
  for (const Wave& w : waves_) {
    const double cos_arg = std::cos(w.kx * x + w.ky * y + w.phase);
    grad += w.amplitude * cos_arg * Eigen::Vector2d(w.kx, w.ky);
  }
  if (grid_ || function_) {
    const double e = 1e-4;
    auto rest = [&](double px, double py) {
      double h = 0.0;
      if (grid_) h += GridHeight(px, py);
      if (function_) h += function_(px, py);
      return h;
    };
    grad.x() += (rest(x + e, y) - rest(x - e, y)) / (2 * e);
    grad.y() += (rest(x, y + e) - rest(x, y - e)) / (2 * e);
  }
  for (const Feature& f : features_) grad += FeatureGradient(f, x, y);
  return Eigen::Vector3d(-grad.x(), -grad.y(), 1.0).normalized();
}

double Terrain::MinHeightOver(const Eigen::Vector2d& centre, double radius_m) const {
  constexpr int kSteps = 8;
  const double spacing = 2.0 * radius_m / kSteps;
  double lowest = Height(centre);
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; j <= kSteps; ++j) {
      lowest = std::min(
          lowest, Height(centre.x() - radius_m + i * spacing, centre.y() - radius_m + j * spacing));
    }
  }
  // Between samples the surface can dip at most this much below the nearest sample.
  return lowest - MaxGradientNear(centre, radius_m) * spacing * 0.7071067811865476;
}

double Terrain::SmoothGradient() const {
  double bound = grid_max_gradient_ + function_max_gradient_;
  for (const Wave& w : waves_) bound += std::abs(w.amplitude) * std::hypot(w.kx, w.ky);
  return bound;
}

double Terrain::SmoothRate(double dx, double dy) const {
  // Only the slope along the ray's horizontal direction can close the gap.
  double rate = function_max_gradient_ * std::hypot(dx, dy);
  if (grid_) rate += grid_max_slope_x_ * std::abs(dx) + grid_max_slope_y_ * std::abs(dy);
  for (const Wave& w : waves_) rate += std::abs(w.amplitude * (w.kx * dx + w.ky * dy));
  return rate;
}

double Terrain::MaxGradient() const {
  double bound = gradient_.norm() + SmoothGradient();
  for (const Feature& f : features_) bound += f.tan_slope;
  return bound;
}

double Terrain::MaxGradientNear(const Eigen::Vector2d& centre, double radius_m) const {
  double bound = gradient_.norm() + SmoothGradient();
  const double reach = radius_m * 1.4142135623730951;  // the square's half-diagonal
  for (const Feature& f : features_) {
    const double s = FeatureCoordinate(f, centre.x(), centre.y());
    if (std::abs(s) <= f.half_width + reach) bound += f.tan_slope;
  }
  return bound;
}

bool Terrain::IsPlanar() const {
  return waves_.empty() && !grid_ && !function_ && features_.empty();
}

// A ray's pieces over the features' footprints, in feature order; a few held inline.
struct Terrain::RaySpans {
  struct Span {
    double t0, t1, rate;
    std::size_t feature;
    double slack;  // the feature's height below its highest at the last point evaluated
  };
  static constexpr std::size_t kInline = 8;

  RaySpans() = default;
  RaySpans(const RaySpans&) = delete;  // `spans` may point into the object
  RaySpans& operator=(const RaySpans&) = delete;

  // Appends a span (all of them onto the heap past kInline).
  void Add(const Span& span) {
    if (count < kInline) {
      inline_spans[count] = span;
    } else {
      if (more_spans.empty()) more_spans.assign(inline_spans, inline_spans + kInline);
      more_spans.push_back(span);
      spans = more_spans.data();
    }
    ++count;
  }

  Span inline_spans[kInline];
  std::vector<Span> more_spans;
  Span* spans = inline_spans;
  std::size_t count = 0;
};

std::optional<RayHit> Terrain::Intersect(const Ray& ray, double t_max, double tolerance_m) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  // The plane part is exact along the ray; only the rest needs the gradient bound.
  const double plane_rise = gradient_.x() * d.x() + gradient_.y() * d.y();

  const double g = o.z() - Height(o.x(), o.y());
  if (!(g > 0.0)) return std::nullopt;  // starts on or below the surface

  if (IsPlanar()) {
    const double closing = plane_rise - d.z();  // rate at which the gap shrinks
    if (!(closing > 0.0)) return std::nullopt;
    const double t = g / closing;
    if (t > t_max) return std::nullopt;
    return PlaneHit(t);
  }

  // March: the gap g(t) shrinks at most at rate `closing`, so a step of g / closing cannot
  // reach the surface, let alone cross it twice. A floor on the step keeps grazing rays
  // finite; it can only miss slivers thinner than the gradient bound times the floor.
  // Features add to the rate only over their footprint, so the ray is cut into pieces at
  // their footprints' edges and each piece is marched with its own rate; a piece that sees
  // only the plane is solved in closed form. Over a footprint a second, often longer, safe
  // step exists: the surface stays under the envelope that lifts each feature there to its
  // highest (a ditch filled in, a bank at its top), which has no feature slope, so a ray
  // above the envelope may step by its gap to it over the rate without features.
  const double smooth_closing = SmoothRate(d.x(), d.y()) + plane_rise - d.z();
  if (!(smooth_closing > 0.0)) {
    // The gap to the envelope of every feature never shrinks: if it is open now, the ray
    // never comes down to the surface.
    double envelope_gap = g;
    for (const Feature& f : features_) {
      envelope_gap += FeatureHeight(f, o.x(), o.y()) - f.Highest();
    }
    if (envelope_gap > 0.0) return std::nullopt;
  }
  RaySpans spans;
  FindRaySpans(ray, t_max, spans);
  return MarchRay(ray, t_max, tolerance_m, g, smooth_closing, spans);
}

RayHit Terrain::PlaneHit(double t) const {
  RayHit hit;
  hit.id = kTerrainId;
  hit.t = t;
  hit.normal = Eigen::Vector3d(-gradient_.x(), -gradient_.y(), 1.0).normalized();
  return hit;
}

void Terrain::FindRaySpans(const Ray& ray, double t_max, RaySpans& spans) const {
  const Eigen::Vector3d& d = ray.direction;
  const double horizontal = std::hypot(d.x(), d.y());
  for (std::size_t i = 0; i < features_.size(); ++i) {
    const Feature& f = features_[i];
    double t0 = 0.0, t1 = 0.0;
    if (!(FeatureSpan(f, ray, &t0, &t1) && t1 > 0.0 && t0 < t_max)) continue;
    // A bank's slope is all across its face; a ditch's turns round its ends.
    const double along = f.is_ditch ? horizontal : std::abs(f.v.x() * d.x() + f.v.y() * d.y());
    spans.Add({t0, t1, f.tan_slope * along, i, 0.0});
  }
}

double Terrain::RayGap(const Ray& ray, double t, RaySpans& spans) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
  double h = RestHeight(x, y);
  std::size_t k = 0;
  for (std::size_t i = 0; i < features_.size(); ++i) {
    const double c = FeatureHeight(features_[i], x, y);
    h += c;
    if (k < spans.count && spans.spans[k].feature == i) {
      spans.spans[k++].slack = c - features_[i].Highest();
    }
  }
  return o.z() + t * d.z() - h;
}

std::optional<RayHit> Terrain::MarchRay(const Ray& ray, double t_max, double tolerance_m,
                                        double gap, double smooth_closing, RaySpans& spans) const {
  const bool smooth = !waves_.empty() || grid_ || function_;
  double t = 0.0;
  double g = spans.count > 0 ? RayGap(ray, 0.0, spans) : gap;  // the slacks at the start
  constexpr int kMaxSteps = 1000000;
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  for (int step = 0; step < kMaxSteps && t < t_max; ++step) {
    // The rates hold up to the next footprint edge.
    double closing = smooth_closing;
    double envelope_gap = g;
    double piece_end = t_max;
    bool on_feature = false;
    for (std::size_t k = 0; k < spans.count; ++k) {
      const RaySpans::Span& s = spans.spans[k];
      if (s.t0 > t) {
        piece_end = std::min(piece_end, s.t0);
      } else if (s.t1 > t) {
        closing += s.rate;
        envelope_gap += s.slack;
        piece_end = std::min(piece_end, s.t1);
        on_feature = true;
      }
    }
    double reach = closing > 0.0 ? g / closing : kInfinity;
    if (!smooth && !on_feature && reach <= piece_end - t) {
      // Only the plane (and constant offsets) here: the crossing in closed form.
      if (t + reach > t_max) return std::nullopt;
      return PlaneHit(t + reach);
    }
    if (on_feature && envelope_gap > 0.0) {
      reach = std::max(reach, smooth_closing > 0.0 ? envelope_gap / smooth_closing : kInfinity);
    }
    double t_next;
    if (reach == kInfinity) {
      if (piece_end >= t_max) return std::nullopt;  // cannot come down to the surface
      t_next = piece_end;                           // the gap cannot close before it
    } else {
      const double min_step = 1e-4 * std::max(1.0, t);
      t_next = std::min(t + std::max(reach, min_step), piece_end);
    }
    const double g_next = RayGap(ray, t_next, spans);
    if (g_next <= 0.0) return RefineRayHit(ray, spans, t, g, t_next, g_next, tolerance_m);
    t = t_next;
    g = g_next;
  }
  return std::nullopt;
}

RayHit Terrain::RefineRayHit(const Ray& ray, RaySpans& spans, double lo, double g_lo, double hi,
                             double g_hi, double tolerance_m) const {
  int side = 0;  // which end moved last: -1 lo, +1 hi
  auto update = [&](double t_new, double g_new, bool illinois) {
    if (g_new > 0.0) {
      lo = t_new;
      g_lo = g_new;
      if (illinois && side == -1) g_hi *= 0.5;
      side = -1;
    } else {
      hi = t_new;
      g_hi = g_new;
      if (illinois && side == 1) g_lo *= 0.5;
      side = 1;
    }
  };
  for (int iteration = 0; iteration < 200 && hi - lo > tolerance_m; ++iteration) {
    double t_new = g_lo - g_hi > 0.0 ? lo + (hi - lo) * g_lo / (g_lo - g_hi) : 0.5 * (lo + hi);
    if (iteration % 8 == 7 || !(t_new > lo && t_new < hi)) t_new = 0.5 * (lo + hi);
    const double slope = (g_lo - g_hi) / (hi - lo);  // secant rate of the bracket
    const double g_new = RayGap(ray, t_new, spans);
    update(t_new, g_new, true);
    if (hi - lo > tolerance_m && std::abs(g_new) < slope * tolerance_m) {
      const double probe = g_new > 0.0 ? t_new + tolerance_m : t_new - tolerance_m;
      if (probe > lo && probe < hi) update(probe, RayGap(ray, probe, spans), false);
    }
  }
  RayHit hit;
  hit.t = 0.5 * (lo + hi);
  const Eigen::Vector3d p = ray.At(hit.t);
  hit.normal = Normal(p.x(), p.y());
  hit.id = features_.empty() ? kTerrainId : IdAt(p.x(), p.y());
  return hit;
}

}  // namespace cairn::sim
