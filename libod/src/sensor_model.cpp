#include "cairn/od/sensor_model.hpp"

#include <cmath>
#include <string>

namespace cairn::od {

Status PinholeModel::Validate() const {
  auto bad = [](const char* field, const std::string& expected) {
    return Error{std::string("pinhole model: field '") + field + "' must be " + expected};
  };
  if (width <= 0) return bad("width", "a positive number of columns");
  if (height <= 0) return bad("height", "a positive number of rows");
  if (!std::isfinite(fx) || fx <= 0.0) return bad("fx", "a finite focal length > 0 [px]");
  if (!std::isfinite(fy) || fy <= 0.0) return bad("fy", "a finite focal length > 0 [px]");
  if (!std::isfinite(cx)) return bad("cx", "a finite principal point column [px]");
  if (!std::isfinite(cy)) return bad("cy", "a finite principal point row [px]");
  return Status::Ok();
}

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// Wraps an angle into [0, 2 pi).
double WrapPositive(double a) {
  a = std::fmod(a, 2.0 * kPi);
  return a < 0.0 ? a + 2.0 * kPi : a;
}

std::vector<double> Linear(double top_deg, double bottom_deg, int rings) {
  std::vector<double> e(rings);
  for (int i = 0; i < rings; ++i) {
    e[i] = (top_deg + (bottom_deg - top_deg) * i / (rings - 1)) * kDeg;
  }
  return e;
}

}  // namespace

double SphericalModel::azimuth_step_rad() const { return 2.0 * kPi / width; }

Status SphericalModel::Validate() const {
  auto bad = [](const std::string& field, const std::string& expected) {
    return Error{"spherical model: field '" + field + "' must be " + expected};
  };
  if (width < 1) return bad("width", "a positive number of azimuth steps");
  if (ring_elevation_rad.empty()) return bad("ring_elevation", "at least one ring");
  if (!std::isfinite(azimuth_start_rad)) return bad("azimuth_start", "finite");
  for (std::size_t i = 0; i < ring_elevation_rad.size(); ++i) {
    const double e = ring_elevation_rad[i];
    const std::string field = "ring_elevation[" + std::to_string(i) + "]";
    if (!std::isfinite(e) || std::abs(e) >= kPi / 2) return bad(field, "finite, within +-90 deg");
    if (i > 0 && e > ring_elevation_rad[i - 1]) {
      return bad(field, "no higher than the ring above it (top beam first)");
    }
  }
  return Status::Ok();
}

double SphericalModel::ColumnAzimuth(double col) const {
  return azimuth_start_rad - col * azimuth_step_rad();
}

int SphericalModel::Column(const Eigen::Vector3d& p) const {
  const double steps = WrapPositive(azimuth_start_rad - std::atan2(p.y(), p.x())) /
                       azimuth_step_rad();
  const int col = static_cast<int>(std::floor(steps + 0.5));
  return col >= width ? col - width : col;
}

int SphericalModel::NearestRing(const Eigen::Vector3d& p) const {
  const double e = std::atan2(p.z(), std::hypot(p.x(), p.y()));
  int best = 0;
  for (int r = 1; r < height(); ++r) {
    if (std::abs(ring_elevation_rad[r] - e) < std::abs(ring_elevation_rad[best] - e)) best = r;
  }
  return best;
}

Expected<SphericalModel> SphericalModel::Preset(const std::string& name, int width) {
  SphericalModel m;
  m.width = width;
  if (name == "HDL-64E") {
    // Two blocks: 32 lasers 1/3 deg apart from +2 deg, 32 spread from -8.83 to -24.8 deg.
    m.ring_elevation_rad = Linear(2.0, 2.0 - 31.0 / 3.0, 32);
    const std::vector<double> lower = Linear(-8.83, -24.8, 32);
    m.ring_elevation_rad.insert(m.ring_elevation_rad.end(), lower.begin(), lower.end());
  } else if (name == "OS1-64") {
    m.ring_elevation_rad = Linear(16.6, -16.6, 64);
  } else if (name == "VLP-16") {
    m.ring_elevation_rad = Linear(15.0, -15.0, 16);
  } else if (name == "VLP-32C") {
    const double table[] = {15.0,   10.333, 7.0,    4.667, 3.333,  2.333,  1.667,  1.333,
                            1.0,    0.667,  0.333,  0.0,   -0.333, -0.667, -1.0,   -1.333,
                            -1.667, -2.0,   -2.333, -2.667, -3.0,  -3.333, -3.667, -4.0,
                            -4.667, -5.333, -6.148, -7.254, -8.843, -11.31, -15.639, -25.0};
    for (double e : table) m.ring_elevation_rad.push_back(e * kDeg);
  } else {
    return Error{"unknown sensor preset '" + name +
                 "' (expected HDL-64E, VLP-16, VLP-32C or OS1-64)"};
  }
  if (Status s = m.Validate(); !s) return s.error();
  return m;
}

}  // namespace cairn::od
