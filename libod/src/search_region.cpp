#include "search_region.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "cairn/od/units.hpp"

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

namespace {

// Smallest z-depth of a valid point: clipping the cone there loses nothing.
double NearestDepth(const RangeImage& image) {
  double z_near = kInf;
  for (int i = 0; i < image.size(); ++i) {
    if (image.valid(i)) z_near = std::min(z_near, static_cast<double>(image.z()[i]));
  }
  // Stored coordinates are floats: step just below the nearest so that nothing is clipped.
  return z_near * (1.0 - 1e-6);
}
double WrapPi(double a) {
  a = std::remainder(a, 2.0 * kPi);
  return a <= -kPi ? a + 2.0 * kPi : a;
}

double Elevation(const Eigen::Vector3d& p) { return std::atan2(p.z(), std::hypot(p.x(), p.y())); }

}  // namespace

SphericalConeRegion::SphericalConeRegion(const RangeImage& image, const SphericalModel& model,
                                         const DetectorConfig& config)
    : model_(model), up_(image.up()), tan_theta_(std::tan(config.min_slope_rad)),
      row_elevation_min_(image.height(), kInf), row_elevation_max_(image.height(), -kInf) {
  const int slabs = std::max(1, config.region_slabs);
  for (int i = 0; i <= slabs; ++i) {
    slab_heights_.push_back(config.min_height_m +
                            (config.max_height_m - config.min_height_m) * i / slabs);
  }
  const int width = image.width();
  for (int i = 0; i < image.size(); ++i) {
    if (!image.valid(i)) continue;
    const Eigen::Vector3d p = image.point(i);
    const int row = i / width, col = i % width;
    const double e = Elevation(p);
    row_elevation_min_[row] = std::min(row_elevation_min_[row], e);
    row_elevation_max_[row] = std::max(row_elevation_max_[row], e);
    const double offset = WrapPi(std::atan2(p.y(), p.x()) - model_.ColumnAzimuth(col));
    offset_min_ = std::min(offset_min_, offset);
    offset_max_ = std::max(offset_max_, offset);
  }
}

void SphericalConeRegion::Compute(const Eigen::Vector3d& p, int col, RowSpans& spans) const {
  const int rows = model_.height(), width = model_.width;
  const double step = model_.azimuth_step_rad();
  spans.row_begin = rows;
  spans.row_end = 0;
  // Column intervals are unwrapped around the point's own column while slabs are merged.
  int lo_all = 0, hi_all = -1;
  bool full_circle = false;
  double e_lo_all = kInf, e_hi_all = -kInf;
  for (std::size_t i = 0; i + 1 < slab_heights_.size(); ++i) {
    const double h0 = slab_heights_[i], h1 = slab_heights_[i + 1];
    const Eigen::Vector3d c0 = p + h0 * up_, c1 = p + h1 * up_;
    const Eigen::Vector3d m = 0.5 * (c0 + c1);
    // The ball about m holding both rim disks (so their hull); widened against rounding.
    const double half = 0.5 * (h1 - h0);
    double radius = std::sqrt(half * half + (h1 / tan_theta_) * (h1 / tan_theta_));
    const double distance = m.norm();
    radius += 1e-5 * (distance + radius) + 1e-6;
    if (distance <= radius) {  // the sensor is inside: every direction
      e_lo_all = -kPi / 2;
      e_hi_all = kPi / 2;
      full_circle = true;
      continue;
    }
    const double alpha = std::asin(radius / distance);
    const double e_centre = std::asin(std::clamp(m.z() / distance, -1.0, 1.0));
    const double e_lo = e_centre - alpha, e_hi = e_centre + alpha;
    e_lo_all = std::min(e_lo_all, e_lo);
    e_hi_all = std::max(e_hi_all, e_hi);
    if (e_hi >= kPi / 2 || e_lo <= -kPi / 2) {  // the ball's directions hold a pole
      full_circle = true;
      continue;
    }
    const double spread = std::asin(std::min(1.0, std::sin(alpha) / std::cos(e_centre)));
    const double az = std::atan2(m.y(), m.x());
    // Column azimuth a(c) = start - c step must lie in [az - spread - offset_max,
    // az + spread - offset_min], taken nearest to the point's column.
    const double c_mid = col + WrapPi(model_.ColumnAzimuth(col) - az) / step;
    const double c_half = (spread + std::max(offset_max_, -offset_min_)) / step;
    const int lo = static_cast<int>(std::floor(c_mid - c_half - 1.0));
    const int hi = static_cast<int>(std::ceil(c_mid + c_half + 1.0));
    if (hi_all < lo_all) {
      lo_all = lo;
      hi_all = hi;
    } else {
      lo_all = std::min(lo_all, lo);
      hi_all = std::max(hi_all, hi);
    }
  }
  if (hi_all - lo_all + 1 >= width) full_circle = true;
  int begin = 0, end = width;
  if (!full_circle) {
    if (hi_all < lo_all) return;  // no slab: empty region
    begin = ((lo_all % width) + width) % width;
    end = begin + (hi_all - lo_all + 1);
  }
  for (int r = 0; r < rows; ++r) {
    if (row_elevation_max_[r] < e_lo_all || row_elevation_min_[r] > e_hi_all) continue;
    spans.row_begin = std::min(spans.row_begin, r);
    spans.row_end = r + 1;
  }
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    const bool meets = row_elevation_max_[r] >= e_lo_all && row_elevation_min_[r] <= e_hi_all;
    spans.col_begin[r] = meets ? begin : 0;
    spans.col_end[r] = meets ? end : 0;
  }
  if (spans.row_begin >= spans.row_end) spans.row_begin = spans.row_end = 0;
}

ConeRegion::ConeRegion(const RangeImage& image, const DetectorConfig& config)
    : image_(image), config_(config) {
  if (config.search != SearchMode::kExact || image.valid_count() == 0) return;
  if (const auto* pinhole = std::get_if<PinholeModel>(&image.model())) {
    exact_.emplace<PinholeConeRegion>(*pinhole, image.up(), config, NearestDepth(image));
  } else {
    exact_.emplace<SphericalConeRegion>(image, std::get<SphericalModel>(image.model()), config);
  }
}

void ConeRegion::Compute(int pixel, RowSpans& spans) const {
  if (const auto* pinhole = std::get_if<PinholeConeRegion>(&exact_)) {
    pinhole->Compute(image_.point(pixel), spans);
  } else if (const auto* spherical = std::get_if<SphericalConeRegion>(&exact_)) {
    spherical->Compute(image_.point(pixel), pixel % image_.width(), spans);
  } else {
    PaperWindow(pixel, spans);
  }
}

void ConeRegion::PaperWindow(int pixel, RowSpans& spans) const {
  const int row = pixel / image_.width(), col = pixel % image_.width();
  // Side of the window in pixels: rows and columns per radian of the model.
  double rows_per_rad = 0.0, cols_per_rad = 0.0, distance = 0.0;
  if (const auto* pinhole = std::get_if<PinholeModel>(&image_.model())) {
    rows_per_rad = pinhole->fy;
    cols_per_rad = pinhole->fx;
    distance = image_.z()[pixel];  // image size of a length L at depth z: f L / z
  } else {
    const auto& model = std::get<SphericalModel>(image_.model());
    const double span = model.ring_elevation_rad.front() - model.ring_elevation_rad.back();
    rows_per_rad = model.height() > 1 && span > 0 ? (model.height() - 1) / span : 1.0;
    cols_per_rad = 1.0 / model.azimuth_step_rad();
    distance = image_.range(pixel);
  }
  const double side_rad = config_.window_scale * config_.min_height_m / distance;
  const int up_rows = static_cast<int>(std::ceil(side_rad * rows_per_rad));
  const int half_cols = static_cast<int>(std::ceil(0.5 * side_rad * cols_per_rad));
  const int width = image_.width();
  const bool wraps = std::holds_alternative<SphericalModel>(image_.model());
  int c_lo = col - half_cols, c_hi = col + half_cols + 1;
  if (wraps && c_hi - c_lo >= width) {
    c_lo = 0;
    c_hi = width;
  } else if (wraps) {
    c_lo = ((c_lo % width) + width) % width;
    c_hi = c_lo + 2 * half_cols + 1;
  } else {
    c_lo = std::max(0, c_lo);
    c_hi = std::min(width, c_hi);
  }
  spans.row_begin = std::max(0, row - up_rows);
  spans.row_end = row + 1;
  for (int r = spans.row_begin; r < spans.row_end; ++r) {
    spans.col_begin[r] = c_lo;
    spans.col_end[r] = c_hi;
  }
}

}  // namespace cairn::od::internal
