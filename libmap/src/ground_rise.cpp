#include "ground_rise.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "ground_points.hpp"

namespace cairn::map::internal {

std::vector<Eigen::Vector3f> ThinGroundPoints(const std::vector<Eigen::Vector3f>& points_sensor,
                                              const GroundRiseFitConfig& config) {
  return ThinGroundPoints(points_sensor, config.max_range_m, config.max_points);
}

GroundSurface::GroundSurface(const std::vector<Eigen::Vector3f>& points_sensor,
                             const Eigen::Isometry3d& T_world_sensor,
                             const GroundRiseFitConfig& config)
    : config_(config),
      T_world_sensor_(T_world_sensor),
      origin_(T_world_sensor.translation().head<2>()) {
  for (const Eigen::Vector3f& q : points_sensor) {
    const Eigen::Vector3d p = T_world_sensor * q.cast<double>();
    const double x = p.x() - origin_.x(), y = p.y() - origin_.y(), z = p.z();
    const auto i = static_cast<std::int64_t>(std::floor(x / config_.cell_m));
    const auto j = static_cast<std::int64_t>(std::floor(y / config_.cell_m));
    Sums& s = cells_[Key(i, j)];
    s.n += 1;
    s.x += x;
    s.y += y;
    s.z += z;
    s.xx += x * x;
    s.xy += x * y;
    s.yy += y * y;
    s.xz += x * z;
    s.yz += y * z;
  }
}

std::optional<GroundSurface::Plane> GroundSurface::PlaneAt(double x_world, double y_world) const {
  const double qx = x_world - origin_.x(), qy = y_world - origin_.y();
  const auto ci = static_cast<std::int64_t>(std::floor(qx / config_.cell_m));
  const auto cj = static_cast<std::int64_t>(std::floor(qy / config_.cell_m));
  Sums s;
  for (std::int64_t i = ci - 1; i <= ci + 1; ++i) {
    for (std::int64_t j = cj - 1; j <= cj + 1; ++j) {
      const auto it = cells_.find(Key(i, j));
      if (it == cells_.end()) continue;
      const Sums& c = it->second;
      s.n += c.n;
      s.x += c.x;
      s.y += c.y;
      s.z += c.z;
      s.xx += c.xx;
      s.xy += c.xy;
      s.yy += c.yy;
      s.xz += c.xz;
      s.yz += c.yz;
    }
  }
  if (s.n < config_.min_plane_points) return std::nullopt;
  // The plane z = a + b (x - mx) + c (y - my) through the points' centroid (mx, my, a).
  const double n = s.n;
  const double mx = s.x / n, my = s.y / n, mz = s.z / n;
  Eigen::Matrix2d C;
  C << s.xx / n - mx * mx, s.xy / n - mx * my, s.xy / n - mx * my, s.yy / n - my * my;
  const Eigen::Vector2d cz(s.xz / n - mx * mz, s.yz / n - my * mz);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(C);
  if (!(eig.eigenvalues()(0) >= config_.min_spread_m * config_.min_spread_m)) return std::nullopt;
  Plane plane;
  plane.gradient = C.ldlt().solve(cz);
  plane.height_m = mz + plane.gradient.x() * (qx - mx) + plane.gradient.y() * (qy - my);
  return plane;
}

std::optional<GroundRiseFit> FitGroundRise(const std::vector<Eigen::Vector3f>& points_sensor,
                                           const Eigen::Isometry3d& T_world_sensor,
                                           const GroundSurface& earlier,
                                           const GroundRiseFitConfig& config) {
  // Each matched point: its height above the earlier ground (a), its place (p) and the
  // earlier ground's height there.
  std::vector<double> a, ground;
  std::vector<Eigen::Vector3d> p;
  std::vector<Eigen::Vector2d> gradient;
  for (const Eigen::Vector3f& q : points_sensor) {
    const Eigen::Vector3d w = T_world_sensor * q.cast<double>();
    const std::optional<GroundSurface::Plane> plane = earlier.PlaneAt(w.x(), w.y());
    if (!plane) continue;
    a.push_back(w.z() - plane->height_m);
    ground.push_back(plane->height_m);
    gradient.push_back(plane->gradient);
    p.push_back(w);
  }
  if (static_cast<int>(a.size()) < config.min_points) return std::nullopt;
  // Huber IRLS on the one unknown: minimise sum rho(a_i + dz), from the median.
  std::vector<double> sorted = a;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  double dz = -sorted[sorted.size() / 2];
  std::vector<double> w(a.size(), 1.0);
  const double h = config.huber_m;
  for (int it = 0; it < config.max_iterations; ++it) {
    double num = 0.0, den = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const double e = std::abs(a[i] + dz);
      w[i] = e <= h ? 1.0 : h / e;
      num += w[i] * a[i];
      den += w[i];
    }
    const double next = -num / den;
    const bool done = std::abs(next - dz) < 1e-9;
    dz = next;
    if (done) break;
  }
  GroundRiseFit fit;
  fit.dz_m = dz;
  fit.points = static_cast<int>(a.size());
  const Eigen::Vector3d sensor = T_world_sensor.translation();
  const Eigen::Vector3d sensor_earlier = earlier.T_world_sensor().translation();
  double wsum = 0.0, sq = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    fit.offset_m += w[i] * (p[i] - sensor);
    fit.offset_earlier_m +=
        w[i] * (Eigen::Vector3d(p[i].x(), p[i].y(), ground[i]) - sensor_earlier);
    fit.gradient += w[i] * gradient[i];
    wsum += w[i];
    sq += (a[i] + dz) * (a[i] + dz);
  }
  fit.offset_m /= wsum;
  fit.offset_earlier_m /= wsum;
  fit.gradient /= wsum;
  fit.rms_m = std::sqrt(sq / static_cast<double>(a.size()));
  return fit;
}

}  // namespace cairn::map::internal
