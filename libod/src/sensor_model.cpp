#include "cairn/od/sensor_model.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <complex>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include "cairn/od/units.hpp"

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

std::vector<double> Linear(double top_deg, double bottom_deg, int rings) {
  std::vector<double> e(rings);
  for (int i = 0; i < rings; ++i) {
    e[i] = (top_deg + (bottom_deg - top_deg) * i / (rings - 1)) * kDegToRad;
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
  return ColumnAt(std::atan2(p.y(), p.x()));
}

int SphericalModel::ColumnAt(double azimuth_rad) const {
  const double steps = WrapPositive(azimuth_start_rad - azimuth_rad) / azimuth_step_rad();
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

const std::vector<std::string>& SphericalModel::PresetNames() {
  static const std::vector<std::string> names = {"HDL-64E", "VLP-16", "VLP-32C", "OS1-64"};
  return names;
}

Expected<SphericalModel> SphericalModel::Preset(const std::string& given, int width) {
  // Names in any case: "os1-64" as the settings file config/sensors/os1-64.yaml has it.
  std::string name = given;
  for (char& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  SphericalModel m;
  const bool velodyne_puck = name == "VLP-16" || name == "VLP-32C";
  m.width = width != 0 ? width : velodyne_puck ? 1800 : 2048;
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
    const double table[] = {15.0,   10.333, 7.0,    4.667,  3.333,  2.333,  1.667,   1.333,
                            1.0,    0.667,  0.333,  0.0,    -0.333, -0.667, -1.0,    -1.333,
                            -1.667, -2.0,   -2.333, -2.667, -3.0,   -3.333, -3.667,  -4.0,
                            -4.667, -5.333, -6.148, -7.254, -8.843, -11.31, -15.639, -25.0};
    for (double e : table) m.ring_elevation_rad.push_back(e * kDegToRad);
  } else {
    const std::vector<std::string>& names = PresetNames();
    std::string expected;
    for (std::size_t k = 0; k < names.size(); ++k) {
      expected += (k == 0 ? "" : k + 1 == names.size() ? " or " : ", ") + names[k];
    }
    return Error{"unknown sensor preset '" + given + "' (expected " + expected + ")"};
  }
  if (Status s = m.Validate(); !s) return s.error();
  return m;
}

double WrapPositive(double a) {
  constexpr double kTurn = 2.0 * 3.14159265358979323846;
  if (a >= 0.0 && a < kTurn) return a;  // what fmod gives, without its cost
  if (a < 0.0 && a > -kTurn) return a + kTurn;  // fmod(a) is a itself there
  a = std::fmod(a, kTurn);
  return a < 0.0 ? a + kTurn : a;
}

bool IsReturn(const Eigen::Vector3f& p) {
  return p.allFinite() && (p.x() != 0.f || p.y() != 0.f || p.z() != 0.f);
}

namespace {

double Elevation(const Eigen::Vector3f& p) {
  return std::atan2(static_cast<double>(p.z()),
                    std::hypot(static_cast<double>(p.x()), static_cast<double>(p.y())));
}

double Azimuth(const Eigen::Vector3f& p) {
  return std::atan2(static_cast<double>(p.y()), static_cast<double>(p.x()));
}

// Lower median of `v` (reordered; the same element FindElevationRings takes); v must not
// be empty.
double Median(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>((v.size() - 1) / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Elevations must stay strictly inside +-90 deg for the model to validate.
double ClampElevation(double e) {
  const double limit = kPi / 2 - 1e-9;
  return std::clamp(e, -limit, limit);
}

std::string Degrees(double rad) {
  const double d = std::round(rad / kDegToRad * 1000.0) / 1000.0;
  std::string s = std::to_string(d);
  s.erase(s.find_last_not_of('0') + 1);
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s + " deg";
}

}  // namespace

PointAngles::PointAngles(const std::vector<Eigen::Vector3f>& points)
    : azimuth(points.size(), std::numeric_limits<double>::quiet_NaN()),
      elevation(points.size(), std::numeric_limits<double>::quiet_NaN()) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!IsReturn(points[i])) continue;
    azimuth[i] = Azimuth(points[i]);
    elevation[i] = Elevation(points[i]);
  }
}

Expected<RingFit> FitRings(const std::vector<Eigen::Vector3f>& points,
                           const std::vector<std::int32_t>& ring_of_point, int rings, int width) {
  return FitRings(PointAngles(points), ring_of_point, rings, width);
}

Expected<RingFit> FitRings(const PointAngles& angles,
                           const std::vector<std::int32_t>& ring_of_point, int rings, int width) {
  const std::vector<double>& elevation = angles.elevation;
  const std::size_t n = elevation.size();
  if (ring_of_point.size() != n) {
    return Error{"rings: " + std::to_string(ring_of_point.size()) + " ring ids for " +
                 std::to_string(n) + " points"};
  }
  if (rings < 1) return Error{"rings: the ring count must be at least 1"};
  std::vector<std::vector<double>> elevations(static_cast<std::size_t>(rings));
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(elevation[i])) continue;  // no return
    const std::int32_t id = ring_of_point[i];
    if (id < 0 || id >= rings) {
      return Error{"rings: point " + std::to_string(i) + " has ring " + std::to_string(id) +
                   ", expected 0.." + std::to_string(rings - 1)};
    }
    elevations[id].push_back(elevation[i]);
  }
  std::vector<double> median(static_cast<std::size_t>(rings),
                             std::numeric_limits<double>::quiet_NaN());
  std::vector<int> measured;  // rings with returns, in the given order
  for (int r = 0; r < rings; ++r) {
    if (elevations[r].empty()) continue;
    median[r] = Median(elevations[r]);
    measured.push_back(r);
  }
  if (measured.empty()) return Error{"rings: no point is a return with a ring"};

  bool top_first = true;
  for (std::size_t k = 1; k < measured.size(); ++k) {
    top_first = top_first && median[measured[k]] <= median[measured[k - 1]];
  }
  RingFit fit;
  fit.model.width = width;
  std::vector<std::int32_t> row_of_ring(static_cast<std::size_t>(rings), -1);
  if (top_first) {
    // Every ring kept in place; the empty ones between measured neighbours interpolated,
    // those beyond them extrapolated with the mean spacing.
    const int first = measured.front(), last = measured.back();
    const double spacing =
        last > first ? (median[first] - median[last]) / (last - first) : 1.0 * kDegToRad;
    std::size_t next = 0;  // index into `measured` of the first measured ring >= r
    for (int r = 0; r < rings; ++r) {
      while (next < measured.size() && measured[next] < r) ++next;
      double e;
      if (!std::isnan(median[r])) {
        e = median[r];
      } else if (r < first) {
        e = median[first] + (first - r) * spacing;
      } else if (r > last) {
        e = median[last] - (r - last) * spacing;
      } else {
        const int above = measured[next - 1], below = measured[next];
        e = median[above] + (median[below] - median[above]) * (r - above) / (below - above);
      }
      fit.model.ring_elevation_rad.push_back(ClampElevation(e));
      row_of_ring[r] = r;
    }
  } else {
    std::stable_sort(measured.begin(), measured.end(),
                     [&](int a, int b) { return median[a] > median[b]; });
    for (std::size_t k = 0; k < measured.size(); ++k) {
      row_of_ring[measured[k]] = static_cast<std::int32_t>(k);
      fit.model.ring_elevation_rad.push_back(median[measured[k]]);
    }
  }
  if (Status s = fit.model.Validate(); !s) return s.error();
  fit.rows.assign(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isnan(elevation[i])) fit.rows[i] = row_of_ring[ring_of_point[i]];
  }
  return fit;
}

Status ElevationRingOptions::Validate() const {
  auto bad = [](const char* field, const char* expected) {
    return Error{std::string("elevation rings: field '") + field + "' must be " + expected};
  };
  if (!(min_gap_rad > 0.0) || !std::isfinite(min_gap_rad)) return bad("min_gap", "> 0");
  if (min_ring_points < 1) return bad("min_ring_points", ">= 1");
  if (!(max_spread_fraction > 0.0 && max_spread_fraction <= 1.0)) {
    return bad("max_spread_fraction", "in (0, 1]");
  }
  if (!(min_ring_share > 0.0 && min_ring_share <= 1.0)) return bad("min_ring_share", "in (0, 1]");
  return Status::Ok();
}

Expected<RingFit> FindElevationRings(const std::vector<Eigen::Vector3f>& points, int width,
                                     const ElevationRingOptions& options) {
  if (Status s = options.Validate(); !s) return s.error();
  std::vector<std::pair<double, std::size_t>> sorted;  // (elevation, point), top first
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (IsReturn(points[i])) sorted.emplace_back(Elevation(points[i]), i);
  }
  if (sorted.size() < 2) return Error{"elevation rings: fewer than two returns"};
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) {
    return a.first > b.first || (a.first == b.first && a.second < b.second);
  });

  // Groups [begin, end) of the sorted returns, split at gaps.
  struct Group {
    std::size_t begin, end;
    std::size_t size() const { return end - begin; }
  };
  std::vector<Group> groups{{0, 1}};
  for (std::size_t k = 1; k < sorted.size(); ++k) {
    if (sorted[k - 1].first - sorted[k].first > options.min_gap_rad) {
      groups.push_back({k, k + 1});
    } else {
      groups.back().end = k + 1;
    }
  }
  // Stray returns join the nearer neighbouring group.
  const auto min_points = static_cast<std::size_t>(options.min_ring_points);
  for (bool merged = true; merged && groups.size() > 1;) {
    merged = false;
    for (std::size_t g = 0; g < groups.size() && groups.size() > 1; ++g) {
      if (groups[g].size() >= min_points) continue;
      const double gap_above =
          g > 0 ? sorted[groups[g - 1].end - 1].first - sorted[groups[g].begin].first
                : std::numeric_limits<double>::infinity();
      const double gap_below = g + 1 < groups.size() ? sorted[groups[g].end - 1].first -
                                                           sorted[groups[g + 1].begin].first
                                                     : std::numeric_limits<double>::infinity();
      if (gap_above <= gap_below) {
        groups[g - 1].end = groups[g].end;
      } else {
        groups[g + 1].begin = groups[g].begin;
      }
      groups.erase(groups.begin() + static_cast<std::ptrdiff_t>(g));
      merged = true;
    }
  }

  // Each group's median and spread; a ring stands clear of its neighbours.
  const std::size_t count = groups.size();
  std::vector<double> median(count), spread(count);
  for (std::size_t g = 0; g < count; ++g) {
    const Group& group = groups[g];
    auto at = [&](double q) {
      return sorted[group.begin + static_cast<std::size_t>(q * (group.size() - 1) + 0.5)].first;
    };
    median[g] = at(0.5);
    spread[g] = at(0.05) - at(0.95);
  }
  std::size_t in_rings = 0, widest = 0;
  for (std::size_t g = 0; g < count; ++g) {
    double nearest = options.min_gap_rad / options.max_spread_fraction;  // a lone group
    if (count > 1) {
      nearest = std::numeric_limits<double>::infinity();
      if (g > 0) nearest = std::min(nearest, median[g - 1] - median[g]);
      if (g + 1 < count) nearest = std::min(nearest, median[g] - median[g + 1]);
    }
    if (spread[g] <= options.max_spread_fraction * nearest) in_rings += groups[g].size();
    if (spread[g] > spread[widest]) widest = g;
  }
  if (static_cast<double>(in_rings) < options.min_ring_share * sorted.size()) {
    return Error{"elevation rings: the returns' elevations (" + Degrees(sorted.back().first) +
                 " to " + Degrees(sorted.front().first) + ") do not split into separate rings: " +
                 std::to_string(count) + " groups, " + std::to_string(sorted.size() - in_rings) +
                 " of " + std::to_string(sorted.size()) + " returns in groups wider than " +
                 std::to_string(static_cast<int>(std::round(100 * options.max_spread_fraction))) +
                 "% of their spacing (the widest spans " + Degrees(spread[widest]) + ")"};
  }

  RingFit fit;
  fit.model.width = width;
  fit.rows.assign(points.size(), -1);
  for (std::size_t g = 0; g < count; ++g) {
    fit.model.ring_elevation_rad.push_back(median[g]);
    for (std::size_t k = groups[g].begin; k < groups[g].end; ++k) {
      fit.rows[sorted[k].second] = static_cast<std::int32_t>(g);
    }
  }
  if (Status s = fit.model.Validate(); !s) return s.error();
  return fit;
}

Expected<RingFit> UniformElevationBins(const std::vector<Eigen::Vector3f>& points, int width,
                                       double bin_rad) {
  if (width < 1) return Error{"elevation bins: width must be a positive number of columns"};
  const double bin = bin_rad > 0.0 ? bin_rad : 2.0 * kPi / width;
  if (!std::isfinite(bin)) return Error{"elevation bins: the bin size must be finite"};
  double top = -kPi, bottom = kPi;
  for (const Eigen::Vector3f& p : points) {
    if (!IsReturn(p)) continue;
    const double e = Elevation(p);
    top = std::max(top, e);
    bottom = std::min(bottom, e);
  }
  if (top < bottom) return Error{"elevation bins: no returns"};
  const double rows_f = std::floor((top - bottom) / bin) + 1.0;
  if (rows_f > 65536.0) {
    return Error{"elevation bins: " + Degrees(top - bottom) + " of elevation in bins of " +
                 Degrees(bin) + " would need more than 65536 rows"};
  }
  const int rows = static_cast<int>(rows_f);
  RingFit fit;
  fit.model.width = width;
  for (int r = 0; r < rows; ++r) {
    fit.model.ring_elevation_rad.push_back(ClampElevation(top - (r + 0.5) * bin));
  }
  fit.rows.assign(points.size(), -1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!IsReturn(points[i])) continue;
    const int r = static_cast<int>(std::floor((top - Elevation(points[i])) / bin));
    fit.rows[i] = std::clamp(r, 0, rows - 1);
  }
  if (Status s = fit.model.Validate(); !s) return s.error();
  return fit;
}

Expected<int> MeasureAzimuthSteps(const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::int32_t>& rows) {
  if (rows.size() != points.size()) {
    return Error{"azimuth steps: " + std::to_string(rows.size()) + " rows for " +
                 std::to_string(points.size()) + " points"};
  }
  const std::int32_t row_count =
      rows.empty() ? 0 : std::max<std::int32_t>(0, *std::max_element(rows.begin(), rows.end()) + 1);
  std::vector<std::vector<double>> azimuths(static_cast<std::size_t>(row_count));
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (rows[i] >= 0 && IsReturn(points[i])) azimuths[rows[i]].push_back(Azimuth(points[i]));
  }
  constexpr double kRepeated = 1e-7;  // [rad]: returns of one firing seen twice
  std::vector<double> gaps;
  for (std::vector<double>& row : azimuths) {
    std::sort(row.begin(), row.end());
    for (std::size_t k = 1; k < row.size(); ++k) {
      if (row[k] - row[k - 1] > kRepeated) gaps.push_back(row[k] - row[k - 1]);
    }
  }
  if (gaps.empty()) return Error{"azimuth steps: no row has two returns at distinct azimuths"};
  // Rays without a return leave gaps of two or more steps; those above 1.5 times the lower
  // quartile do not count, or a few per cent of them would pull the median off one step.
  std::vector<double> quartile = gaps;
  const auto q = quartile.begin() + static_cast<std::ptrdiff_t>((quartile.size() - 1) / 4);
  std::nth_element(quartile.begin(), q, quartile.end());
  const double limit = 1.5 * *q;
  gaps.erase(std::remove_if(gaps.begin(), gaps.end(), [limit](double g) { return g > limit; }),
             gaps.end());
  const double steps = std::round(2.0 * kPi / Median(gaps));
  return static_cast<int>(std::clamp(steps, 16.0, 65536.0));
}

double FitAzimuthStart(const std::vector<Eigen::Vector3f>& points, int width) {
  return FitAzimuthStart(PointAngles(points), width);
}

double FitAzimuthStart(const PointAngles& angles, int width) {
  std::complex<double> sum(0.0, 0.0);
  for (const double a : angles.azimuth) {
    if (!std::isnan(a)) sum += std::polar(1.0, width * a);
  }
  return std::abs(sum) > 0.0 ? std::arg(sum) / width : 0.0;
}

}  // namespace cairn::od
