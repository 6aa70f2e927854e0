#include "search_region.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

namespace cairn::od::internal {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Pixels added on every side of a region: covers float rounding of the stored points and
// the sub-pixel offset of a point from its cell centre.
constexpr double kMarginPx = 1.0;

// Points (cos t, sin t) of the unit circle where a cos t + b sin t + c = 0 (at most two),
// written to `out` as cos, sin pairs; in closed form, without trigonometric calls:
// (cos t, sin t) = (-c (a, b) -+ sqrt(a^2 + b^2 - c^2) (b, -a)) / (a^2 + b^2).
int SolveTrig(double a, double b, double c, double* out) {
  const double r2 = a * a + b * b;
  if (r2 < 1e-300) return 0;
  double disc = r2 - c * c;
  if (disc < -1e-12 * r2) return 0;
  disc = std::sqrt(std::max(0.0, disc));
  out[0] = (-c * a - disc * b) / r2;
  out[1] = (-c * b + disc * a) / r2;
  out[2] = (-c * a + disc * b) / r2;
  out[3] = (-c * b - disc * a) / r2;
  return 2;
}

}  // namespace

PinholeConeRegion::PinholeConeRegion(const PinholeModel& model, const Eigen::Vector3d& up,
                                     const DetectorConfig& config, double z_near)
    : model_(model), up_(up.normalized()), tan_theta_(std::tan(config.min_slope_rad)),
      z_near_(z_near) {
  // Any unit vector not parallel to up seeds the horizontal basis.
  const Eigen::Vector3d seed =
      std::abs(up_.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  a_ = (seed - seed.dot(up_) * up_).normalized();
  b_ = up_.cross(a_);
  for (int k = 0; k < 3; ++k) {
    half_extent_per_radius_[k] = std::sqrt(std::max(0.0, 1.0 - up_[k] * up_[k]));
  }
  const int slabs = std::max(1, config.region_slabs);
  for (int i = 0; i <= slabs; ++i) {
    slab_heights_.push_back(config.min_height_m +
                            (config.max_height_m - config.min_height_m) * i / slabs);
  }
}

// Grows `box` by the projection of the disk (center, radius, normal up) clipped to
// z >= z_near. The clipped disk is convex and its boundary is an arc plus a chord, so the
// extremes of a linear-fractional image coordinate lie at the arc's critical points or at
// the chord's ends. Along the circle, coordinate = N(t) / Z(t) with N, Z of the form
// n0 + n1 cos t + n2 sin t; d/dt = 0 reduces to A cos t + B sin t + C = 0.
void PinholeConeRegion::AddDisk(const Eigen::Vector3d& center, double radius, Box& box) const {
  const Eigen::Vector3d ra = radius * a_;
  const Eigen::Vector3d rb = radius * b_;
  const double d0 = center.z(), d1 = ra.z(), d2 = rb.z();
  const double z_reach = std::hypot(d1, d2);
  if (d0 + z_reach < z_near_) return;  // wholly nearer than any point: projects nowhere

  // u = (fx X + cx Z) / Z, v = (fy Y + cy Z) / Z.
  const double un0 = model_.fx * center.x() + model_.cx * d0;
  const double un1 = model_.fx * ra.x() + model_.cx * d1;
  const double un2 = model_.fx * rb.x() + model_.cx * d2;
  const double vn0 = model_.fy * center.y() + model_.cy * d0;
  const double vn1 = model_.fy * ra.y() + model_.cy * d1;
  const double vn2 = model_.fy * rb.y() + model_.cy * d2;
  const auto extend = [&](double c, double s, double z) {
    const double u = (un0 + un1 * c + un2 * s) / z;
    const double v = (vn0 + vn1 * c + vn2 * s) / z;
    box.u_min = std::min(box.u_min, u);
    box.u_max = std::max(box.u_max, u);
    box.v_min = std::min(box.v_min, v);
    box.v_max = std::max(box.v_max, v);
  };

  double cs[8];
  int n = SolveTrig(un2 * d0 - un0 * d2, un0 * d1 - un1 * d0, un2 * d1 - un1 * d2, cs);
  n += SolveTrig(vn2 * d0 - vn0 * d2, vn0 * d1 - vn1 * d0, vn2 * d1 - vn1 * d2, cs + 2 * n);
  for (int i = 0; i < n; ++i) {
    const double c = cs[2 * i], s = cs[2 * i + 1];
    // Critical points on the clipped-away part of the circle are not in the region.
    const double z = d0 + d1 * c + d2 * s;
    if (z >= z_near_) extend(c, s, z);
  }
  if (d0 - z_reach < z_near_) {
    // Chord ends: Z(t) = z_near exactly (used as is, so rounding cannot drop them).
    double chord[4];
    const int m = SolveTrig(d1, d2, d0 - z_near_, chord);
    for (int i = 0; i < m; ++i) extend(chord[2 * i], chord[2 * i + 1], z_near_);
  }
}

void PinholeConeRegion::Compute(const Eigen::Vector3d& p, RowSpans& spans) const {
  const int rows = model_.height, cols = model_.width;
  constexpr int kMaxSlabs = 64;
  int boxes[kMaxSlabs][4];  // r_lo, r_hi, c_lo, c_hi (inclusive)
  int count = 0;
  spans.row_begin = rows;
  spans.row_end = 0;
  // Each rim bounds two slabs: project it once.
  Box rims[kMaxSlabs + 1];
  const int slabs = std::min(kMaxSlabs, static_cast<int>(slab_heights_.size()) - 1);
  for (int i = 0; i <= slabs; ++i) {
    rims[i] = Box{kInf, -kInf, kInf, -kInf};
    AddDisk(p + slab_heights_[i] * up_, slab_heights_[i] / tan_theta_, rims[i]);
  }
  for (int i = 0; i < slabs; ++i) {
    const Box& b0 = rims[i];
    const Box& b1 = rims[i + 1];
    Box box{std::min(b0.u_min, b1.u_min), std::max(b0.u_max, b1.u_max),
            std::min(b0.v_min, b1.v_min), std::max(b0.v_max, b1.v_max)};
    const double h0 = slab_heights_[i], h1 = slab_heights_[i + 1];
    const Eigen::Vector3d c0 = p + h0 * up_, c1 = p + h1 * up_;
    const double r0 = h0 / tan_theta_, r1 = h1 / tan_theta_;
    // A slab that reaches nearer than z_near has extreme points on the plane z = z_near
    // too; bound that cross-section by the slab's axis-aligned box.
    const Eigen::Vector3d e0 = r0 * half_extent_per_radius_, e1 = r1 * half_extent_per_radius_;
    const double z_lo = std::min(c0.z() - e0.z(), c1.z() - e1.z());
    const double z_hi = std::max(c0.z() + e0.z(), c1.z() + e1.z());
    if (z_lo < z_near_ && z_hi >= z_near_) {
      const double x_lo = std::min(c0.x() - e0.x(), c1.x() - e1.x());
      const double x_hi = std::max(c0.x() + e0.x(), c1.x() + e1.x());
      const double y_lo = std::min(c0.y() - e0.y(), c1.y() - e1.y());
      const double y_hi = std::max(c0.y() + e0.y(), c1.y() + e1.y());
      box.u_min = std::min(box.u_min, model_.fx * x_lo / z_near_ + model_.cx);
      box.u_max = std::max(box.u_max, model_.fx * x_hi / z_near_ + model_.cx);
      box.v_min = std::min(box.v_min, model_.fy * y_lo / z_near_ + model_.cy);
      box.v_max = std::max(box.v_max, model_.fy * y_hi / z_near_ + model_.cy);
    }
    if (box.empty()) continue;
    // Clamp in double before converting: near the camera the box can exceed int's range.
    const auto lo = [](double x, int limit) {
      return static_cast<int>(std::clamp(std::ceil(x - kMarginPx), 0.0, double(limit)));
    };
    const auto hi = [](double x, int limit) {
      return static_cast<int>(std::clamp(std::floor(x + kMarginPx), -1.0, double(limit - 1)));
    };
    int* b = boxes[count];
    b[0] = lo(box.v_min, rows);
    b[1] = hi(box.v_max, rows);
    b[2] = lo(box.u_min, cols);
    b[3] = hi(box.u_max, cols);
    if (b[0] > b[1] || b[2] > b[3]) continue;
    spans.row_begin = std::min(spans.row_begin, b[0]);
    spans.row_end = std::max(spans.row_end, b[1] + 1);
    ++count;
  }
  if (count == 0) {
    spans.row_begin = spans.row_end = 0;
    return;
  }
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    spans.col_begin[r] = cols;  // empty until a slab covers the row
    spans.col_end[r] = 0;
  }
  for (int k = 0; k < count; ++k) {
    const int* b = boxes[k];
    for (int r = b[0]; r <= b[1]; ++r) {
      spans.col_begin[r] = std::min(spans.col_begin[r], b[2]);
      spans.col_end[r] = std::max(spans.col_end[r], b[3] + 1);
    }
  }
}

void PaperWindow(const PinholeModel& model, const DetectorConfig& config, int row, int col,
                 double depth, RowSpans& spans) {
  const double side = config.window_scale * model.fy * config.min_height_m / depth;
  const int half = static_cast<int>(std::ceil(0.5 * side));
  spans.row_begin = std::max(0, row - static_cast<int>(std::ceil(side)));
  spans.row_end = row + 1;
  const int c_lo = std::max(0, col - half);
  const int c_hi = std::min(model.width, col + half + 1);
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    spans.col_begin[r] = c_lo;
    spans.col_end[r] = c_hi;
  }
}

double NearestDepth(const RangeImage& image) {
  double z_near = kInf;
  for (int i = 0; i < image.size(); ++i) {
    if (image.valid(i)) z_near = std::min(z_near, static_cast<double>(image.z()[i]));
  }
  // Stored coordinates are floats: step just below the nearest so that nothing is clipped.
  return z_near * (1.0 - 1e-6);
}

}  // namespace cairn::od::internal
