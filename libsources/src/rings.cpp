#include "cairn/sources/rings.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "cairn/od/units.hpp"

namespace cairn::sources {
namespace {

bool HasReturn(const Eigen::Vector3f& p) {
  return p.allFinite() && (p.x() != 0.0f || p.y() != 0.0f || p.z() != 0.0f);
}

double Elevation(const Eigen::Vector3f& p) {
  return std::atan2(static_cast<double>(p.z()), std::hypot(double{p.x()}, double{p.y()}));
}

std::string Degrees(double rad) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f", rad * 180.0 / kPi);
  return text;
}

}  // namespace

int ColumnsFromAzimuthStep(const std::vector<Eigen::Vector3f>& points,
                           const std::vector<std::int32_t>& rows, int ring_count,
                           const RingOptions& options) {
  std::vector<std::vector<double>> azimuths(static_cast<std::size_t>(std::max(ring_count, 0)));
  for (std::size_t i = 0; i < points.size() && i < rows.size(); ++i) {
    if (rows[i] < 0 || rows[i] >= ring_count) continue;
    azimuths[rows[i]].push_back(std::atan2(double{points[i].y()}, double{points[i].x()}));
  }
  std::vector<double> steps;
  for (std::vector<double>& ring : azimuths) {
    std::sort(ring.begin(), ring.end());
    for (std::size_t k = 1; k < ring.size(); ++k) {
      const double d = ring[k] - ring[k - 1];
      if (d > 1e-7) steps.push_back(d);  // returns of one firing (dual return) share azimuths
    }
  }
  if (steps.empty()) return options.min_columns;
  // Neighbours one step apart are the most common, but rays without return make gaps of two
  // or more steps that would pull a plain median up: keep the differences below 1.5 times
  // the lower quartile, then take their median.
  std::sort(steps.begin(), steps.end());
  const double quartile = steps[steps.size() / 4];
  const auto end = std::upper_bound(steps.begin(), steps.end(), 1.5 * quartile);
  const double step = steps[static_cast<std::size_t>(end - steps.begin()) / 2];
  const int columns = static_cast<int>(std::lround(2.0 * kPi / step));
  return std::clamp(columns, options.min_columns, options.max_columns);
}

Expected<RingLayout> FindRings(const std::vector<Eigen::Vector3f>& points,
                               const RingOptions& options) {
  std::vector<std::pair<double, std::size_t>> elevations;  // (elevation, point index)
  elevations.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (HasReturn(points[i])) elevations.emplace_back(Elevation(points[i]), i);
  }
  if (elevations.size() < 2) {
    return Error{"point cloud: " + std::to_string(elevations.size()) +
                 " returns, too few to find rings"};
  }
  // Descending: ring 0 is the top beam.
  std::sort(elevations.begin(), elevations.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });

  RingLayout out;
  out.rows.assign(points.size(), -1);
  out.cols.assign(points.size(), -1);

  // Groups of elevations separated by gaps.
  struct Group {
    std::size_t begin, end;  // into `elevations`
  };
  std::vector<Group> groups;
  std::size_t begin = 0;
  for (std::size_t k = 1; k <= elevations.size(); ++k) {
    if (k == elevations.size() ||
        elevations[k - 1].first - elevations[k].first > options.min_gap_rad) {
      groups.push_back({begin, k});
      begin = k;
    }
  }
  const auto min_count = static_cast<std::size_t>(
      std::ceil(options.min_ring_fraction * static_cast<double>(elevations.size())));
  std::vector<Group> rings;
  std::size_t noise = 0;
  for (const Group& g : groups) {
    if (g.end - g.begin >= std::max<std::size_t>(min_count, 1)) {
      rings.push_back(g);
    } else {
      noise += g.end - g.begin;
    }
  }
  const bool ring_structured = rings.size() >= 2 &&
                               static_cast<int>(rings.size()) <= options.max_rings &&
                               noise * 100 <= elevations.size();  // at most 1% stray returns
  if (ring_structured) {
    out.rings_found = true;
    for (const Group& g : rings) {
      double sum = 0.0;
      for (std::size_t k = g.begin; k < g.end; ++k) sum += elevations[k].first;
      out.model.ring_elevation_rad.push_back(sum / static_cast<double>(g.end - g.begin));
    }
    // Each return to its nearest ring (stray ones included), by walking both lists down.
    std::size_t ring = 0;
    const auto& e = out.model.ring_elevation_rad;
    for (const auto& [elevation, index] : elevations) {
      while (ring + 1 < e.size() && std::abs(e[ring + 1] - elevation) < std::abs(e[ring] - elevation)) {
        ++ring;
      }
      out.rows[index] = static_cast<std::int32_t>(ring);
    }
    out.layout = std::to_string(rings.size()) + " rings found from the elevations (" +
                 Degrees(e.front()) + " to " + Degrees(e.back()) + " deg)";
  } else {
    const double top = elevations.front().first, bottom = elevations.back().first;
    const int bins = std::max(
        1, static_cast<int>(std::floor((top - bottom) / options.fallback_bin_rad)) + 1);
    for (int b = 0; b < bins; ++b) {
      out.model.ring_elevation_rad.push_back(top - (b + 0.5) * options.fallback_bin_rad);
    }
    for (const auto& [elevation, index] : elevations) {
      out.rows[index] = std::min(
          bins - 1, static_cast<int>(std::floor((top - elevation) / options.fallback_bin_rad)));
    }
    out.layout = "no ring structure in the elevations: " + std::to_string(bins) +
                 " even bins of " + Degrees(options.fallback_bin_rad) + " deg";
  }
  out.model.width = ColumnsFromAzimuthStep(points, out.rows, out.model.height(), options);
  // Column 0 looks backwards, so that forward is in the middle of the image and left is left.
  out.model.azimuth_start_rad = kPi;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (out.rows[i] >= 0) out.cols[i] = out.model.Column(points[i].cast<double>());
  }
  out.layout += ", " + std::to_string(out.model.width) + " azimuth steps from the data";
  if (Status s = out.model.Validate(); !s) return Error{"point cloud: " + s.message()};
  return out;
}

}  // namespace cairn::sources
