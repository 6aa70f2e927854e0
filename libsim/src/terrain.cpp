#include "cairn/sim/terrain.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace cairn::sim {
namespace {

constexpr double kTwoPi = 6.283185307179586;

double WaveArgument(const SineWave& w, double x, double y) {
  return kTwoPi * (x * std::cos(w.direction_rad) + y * std::sin(w.direction_rad)) / w.wavelength_m +
         w.phase_rad;
}

}  // namespace

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

Terrain Terrain::Hills(double height_m, std::vector<SineWave> waves) {
  Terrain t;
  t.height_m_ = height_m;
  t.waves_ = std::move(waves);
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
  waves_.push_back(wave);
  return *this;
}

Terrain& Terrain::AddPlane(double height_m, const Eigen::Vector2d& gradient) {
  height_m_ += height_m;
  gradient_ += gradient;
  return *this;
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

double Terrain::Height(double x, double y) const {
  double h = height_m_ + gradient_.x() * x + gradient_.y() * y;
  for (const SineWave& w : waves_) h += w.amplitude_m * std::sin(WaveArgument(w, x, y));
  if (grid_) h += GridHeight(x, y);
  if (function_) h += function_(x, y);
  return h;
}

Eigen::Vector3d Terrain::Normal(double x, double y) const {
  Eigen::Vector2d grad = gradient_;
  for (const SineWave& w : waves_) {
    const double k = kTwoPi / w.wavelength_m;
    grad += w.amplitude_m * k * std::cos(WaveArgument(w, x, y)) *
            Eigen::Vector2d(std::cos(w.direction_rad), std::sin(w.direction_rad));
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
  return lowest - MaxGradient() * spacing * 0.7071067811865476;
}

double Terrain::MaxGradient() const {
  double bound = gradient_.norm() + grid_max_gradient_ + function_max_gradient_;
  for (const SineWave& w : waves_) bound += kTwoPi * std::abs(w.amplitude_m) / w.wavelength_m;
  return bound;
}

bool Terrain::IsPlanar() const { return waves_.empty() && !grid_ && !function_; }

std::optional<RayHit> Terrain::Intersect(const Ray& ray, double t_max, double tolerance_m) const {
  const Eigen::Vector3d& o = ray.origin;
  const Eigen::Vector3d& d = ray.direction;
  // The plane part is exact along the ray; only the rest needs the gradient bound.
  const double plane_rise = gradient_.x() * d.x() + gradient_.y() * d.y();
  auto above = [&](double t) {  // height of the ray above the surface at t
    return o.z() + t * d.z() - Height(o.x() + t * d.x(), o.y() + t * d.y());
  };
  RayHit hit;
  hit.id = kTerrainId;

  double g = above(0.0);
  if (!(g > 0.0)) return std::nullopt;  // starts on or below the surface

  if (IsPlanar()) {
    const double closing = plane_rise - d.z();  // rate at which the gap shrinks
    if (!(closing > 0.0)) return std::nullopt;
    const double t = g / closing;
    if (t > t_max) return std::nullopt;
    hit.t = t;
    hit.normal = Eigen::Vector3d(-gradient_.x(), -gradient_.y(), 1.0).normalized();
    return hit;
  }

  // March: the gap g(t) shrinks at most at rate `closing`, so a step of g / closing cannot
  // reach the surface, let alone cross it twice. A floor on the step keeps grazing rays
  // finite; it can only miss slivers thinner than the gradient bound times the floor.
  const double rest_gradient = MaxGradient() - gradient_.norm();
  const double closing = rest_gradient * std::hypot(d.x(), d.y()) + plane_rise - d.z();
  if (!(closing > 0.0)) return std::nullopt;  // rises faster than any hill
  double t = 0.0;
  constexpr int kMaxSteps = 1000000;
  for (int step = 0; step < kMaxSteps && t < t_max; ++step) {
    const double min_step = 1e-4 * std::max(1.0, t);
    const double t_next = std::min(t + std::max(g / closing, min_step), t_max);
    const double g_next = above(t_next);
    if (g_next <= 0.0) {
      double lo = t, hi = t_next;
      for (int halving = 0; halving < 200 && hi - lo > tolerance_m; ++halving) {
        const double mid = 0.5 * (lo + hi);
        (above(mid) > 0.0 ? lo : hi) = mid;
      }
      hit.t = 0.5 * (lo + hi);
      const Eigen::Vector3d p = ray.At(hit.t);
      hit.normal = Normal(p.x(), p.y());
      return hit;
    }
    t = t_next;
    g = g_next;
  }
  return std::nullopt;
}

}  // namespace cairn::sim
