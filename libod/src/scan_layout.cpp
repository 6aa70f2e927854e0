#include "cairn/od/scan_layout.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <sstream>

#include "cairn/od/units.hpp"

namespace cairn::od {
namespace {

constexpr double kOrganisedAgreement = 0.9;  // share of neighbour pairs that must agree

// An angle into [-pi, pi] (search_region.cpp's WrapPi gives (-pi, pi]; the layout keeps the
// value it was written with).
double WrapAngle(double a) {
  if (a >= -kPi && a <= kPi) return a;  // what remainder gives, without its cost
  return std::remainder(a, 2.0 * kPi);
}

}  // namespace

Expected<PointLayout> ResolveLayout(const PointCloud& cloud, const SphericalModel& preset,
                                    OrganisedMode mode, const std::string& source) {
  if (Status s = preset.Validate(); !s) return Error{source + ": " + s.message()};
  const std::size_t n = cloud.points.size();
  const std::size_t rings = static_cast<std::size_t>(preset.height());
  PointLayout layout;
  layout.model = preset;
  const bool divisible = n > 0 && n % rings == 0;
  if (mode == OrganisedMode::kYes && !divisible) {
    return Error{source + ": " + std::to_string(n) + " points cannot be an organised scan of " +
                 std::to_string(rings) + " rings (not a multiple)"};
  }
  if (mode == OrganisedMode::kNo || !divisible) return layout;

  const std::size_t columns = n / rings;
  const double step = 2.0 * kPi / static_cast<double>(columns);
  auto azimuth = [](const Eigen::Vector3f& p) { return std::atan2(double(p.y()), double(p.x())); };
  auto elevation = [](const Eigen::Vector3f& p) {
    return std::atan2(double(p.z()), std::hypot(double(p.x()), double(p.y())));
  };
  // Evidence: within a column, elevation falls with the ring; along a ring, the azimuth
  // falls by one step per column (within a few steps: Ouster beams have azimuth offsets).
  std::size_t ring_pairs = 0, ring_agree = 0, col_pairs = 0, col_agree = 0;
  // Column 0's azimuth from the data: circular mean of azimuth + col * step over returns.
  std::complex<double> start_sum(0.0, 0.0);
  for (std::size_t c = 0; c < columns; ++c) {
    for (std::size_t r = 0; r < rings; ++r) {
      const Eigen::Vector3f& p = cloud.points[c * rings + r];
      if (!IsReturn(p)) continue;
      start_sum += std::polar(1.0, azimuth(p) + static_cast<double>(c) * step);
      if (r + 1 < rings) {
        const Eigen::Vector3f& below = cloud.points[c * rings + r + 1];
        if (IsReturn(below)) {
          ++ring_pairs;
          if (elevation(below) < elevation(p)) ++ring_agree;
        }
      }
      if (c + 1 < columns) {
        const Eigen::Vector3f& next = cloud.points[(c + 1) * rings + r];
        if (IsReturn(next)) {
          ++col_pairs;
          const double d = WrapAngle(azimuth(p) - azimuth(next));  // one step when organised
          if (d > -2.0 * step && d < 4.0 * step) ++col_agree;
        }
      }
    }
  }
  const bool evidence = ring_pairs > 0 && col_pairs > 0 &&
                        ring_agree >= kOrganisedAgreement * ring_pairs &&
                        col_agree >= kOrganisedAgreement * col_pairs;
  if (mode == OrganisedMode::kAuto && !evidence) return layout;

  layout.organised = true;
  layout.model.width = static_cast<int>(columns);
  layout.model.azimuth_start_rad = std::abs(start_sum) > 0.0 ? std::arg(start_sum) : 0.0;
  layout.rows.resize(n);
  layout.cols.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    layout.rows[i] = static_cast<std::int32_t>(i % rings);
    layout.cols[i] = static_cast<std::int32_t>(i / rings);
  }
  return layout;
}

const char* RingSourceName(RingSource source) {
  switch (source) {
    case RingSource::kRingField:
      return "ring field";
    case RingSource::kOrganised:
      return "organised";
    case RingSource::kRingBreaks:
      return "ring breaks";
    case RingSource::kElevationClusters:
      return "elevation clusters";
    case RingSource::kNominal:
      return "nominal rings";
    case RingSource::kUniformBins:
      return "uniform elevation bins";
  }
  return "?";
}

Expected<RingBreaks> FindRingBreaks(const std::vector<Eigen::Vector3f>& points) {
  return FindRingBreaks(points, PointAngles(points));
}

Expected<RingBreaks> FindRingBreaks(const std::vector<Eigen::Vector3f>& points,
                                    const PointAngles& angles) {
  constexpr int kMinRingPoints = 4;                 // a fall back within fewer points is jitter
  constexpr double kSmallStep = 5.0 * kPi / 180.0;  // [rad] between neighbouring returns
  std::vector<std::size_t> index;                   // returns, in storage order
  std::vector<double> azimuth, elevation;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (std::isnan(angles.azimuth[i])) continue;  // no return
    index.push_back(i);
    azimuth.push_back(angles.azimuth[i]);
    elevation.push_back(angles.elevation[i]);
  }
  const std::size_t m = index.size();
  if (m < 3 * kMinRingPoints) {
    return Error{"ring breaks: " + std::to_string(m) + " returns are too few"};
  }
  // The sweep's direction: the sign of the median step between neighbours in storage
  // order, from the counts of each sign (the median of s steps, the (s/2)-th smallest, is
  // positive when at most s/2 steps are not, negative when more than s/2 are).
  std::vector<double> steps(m - 1);
  std::size_t positive = 0, negative = 0;
  for (std::size_t k = 1; k < m; ++k) {
    steps[k - 1] = WrapAngle(azimuth[k] - azimuth[k - 1]);
    positive += steps[k - 1] > 0.0;
    negative += steps[k - 1] < 0.0;
  }
  const std::size_t half = steps.size() / 2;
  if (steps.size() - positive > half && negative <= half) {
    return Error{"ring breaks: the azimuth does not sweep along the order"};
  }
  const double sweep = steps.size() - positive <= half ? 1.0 : -1.0;
  std::size_t small = 0;
  for (double d : steps) small += sweep * d >= 0.0 && sweep * d <= kSmallStep;
  if (small < 0.9 * steps.size()) {
    return Error{"ring breaks: only " + std::to_string(100 * small / steps.size()) +
                 "% of neighbouring returns step one way by under 5 deg (expected 90%): not "
                 "stored ring after ring"};
  }

  RingBreaks result;
  std::vector<std::size_t> breaks;  // returns (in `index`) that start a ring
  auto cut = [&](double seam) {
    result.ring.assign(points.size(), -1);
    breaks.clear();
    int ring = 0, count = 0;
    double previous = 0.0;
    for (std::size_t k = 0; k < m; ++k) {
      const double phase = WrapPositive(sweep * (azimuth[k] - seam));
      if (k > 0 && phase < previous - kPi && count >= kMinRingPoints) {
        ++ring;
        count = 0;
        breaks.push_back(k);
      }
      result.ring[index[k]] = ring;
      ++count;
      previous = phase;
    }
    result.rings = ring + 1;
  };
  // First pass: rings start at the first return's azimuth, which may lie a little after
  // the true seam, so a few returns of each ring would fall to the ring before.
  const double first_seam = azimuth[0];
  cut(first_seam);
  if (breaks.empty()) return Error{"ring breaks: the azimuth never turns back: one sweep"};
  // The true seam lies between the scan's last return (the last ring ends before it) and
  // its first (ring 0 starts after it); the first return may start ring 0 a little late,
  // and then the first returns of every other ring, between the seam and it, would fall to
  // the ring before. No azimuth gap marks the seam (rings join seamlessly), but there the
  // elevation steps by a ring spacing, with the same sign in every ring (rings are stored
  // in elevation order), while along a ring it runs smoothly or, across an object's edge,
  // jumps either way. In 0.1-degree bins over that interval, the step between the returns
  // on either side of the bin is taken in every ring; the bin where its median over the
  // rings is largest holds the seam.
  constexpr int kBins = 3600;  // 0.1 deg
  const double bin_rad = 2.0 * kPi / kBins;
  std::vector<double> phase(m);  // from the first-pass seam
  for (std::size_t k = 0; k < m; ++k) phase[k] = WrapPositive(sweep * (azimuth[k] - first_seam));
  const double last_phase = phase[m - 1];
  const int first_bin = static_cast<int>(std::ceil(last_phase / bin_rad));
  result.seam_rad = first_seam;
  double seam_phase = 0.0;
  if (last_phase > kPi && first_bin < kBins) {
    std::vector<std::vector<float>> steps_in(static_cast<std::size_t>(kBins - first_bin + 1));
    for (std::size_t k = 1; k < m; ++k) {
      double from = phase[k - 1], to = phase[k];
      if (to < from - kPi) to += 2.0 * kPi;  // across the first-pass seam
      if (to <= from) continue;              // a step backwards covers nothing
      if (std::floor(to / bin_rad) < first_bin) continue;  // ends before the first bin
      const float step = static_cast<float>(elevation[k] - elevation[k - 1]);
      const int lo = std::max(first_bin, static_cast<int>(std::ceil(from / bin_rad)));
      const int hi = std::min(kBins, static_cast<int>(std::floor(to / bin_rad)));
      for (int b = lo; b <= hi; ++b) steps_in[b - first_bin].push_back(step);
    }
    float best = -1.f;
    const std::size_t enough = static_cast<std::size_t>(result.rings / 2);
    for (std::size_t b = 0; b < steps_in.size(); ++b) {
      std::vector<float>& v = steps_in[b];
      if (v.empty() || v.size() < enough) continue;
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      if (std::abs(v[v.size() / 2]) > best) {
        best = std::abs(v[v.size() / 2]);
        seam_phase = (first_bin + static_cast<int>(b)) * bin_rad;
      }
    }
  }
  // Refined: the median azimuth between the two returns that straddle that bin.
  std::vector<double> straddle;
  for (std::size_t k = 1; k < m; ++k) {
    double from = phase[k - 1], to = phase[k];
    if (to < from - kPi) to += 2.0 * kPi;
    const double target = seam_phase < from ? seam_phase + 2.0 * kPi : seam_phase;
    if (to > from && from <= target && target <= to) {
      straddle.push_back(WrapAngle(0.5 * (from + to) - seam_phase));
    }
  }
  if (!straddle.empty()) {
    std::nth_element(straddle.begin(), straddle.begin() + straddle.size() / 2, straddle.end());
    seam_phase += straddle[straddle.size() / 2];
  }
  result.seam_rad = WrapAngle(first_seam + sweep * seam_phase);
  cut(result.seam_rad);

  if (result.rings < 3) {
    return Error{"ring breaks: " + std::to_string(result.rings) +
                 " sweeps, expected 3 rings or more"};
  }
  // Within a ring the azimuth never jumps far back (a tilting 2-D laser's lines do, at
  // every line's end, by less than the half turn that marks a new ring).
  constexpr double kFarBack = 10.0 * kPi / 180.0;
  std::size_t far_back = 0;
  for (std::size_t k = 1; k < m; ++k) {
    far_back += result.ring[index[k]] == result.ring[index[k - 1]] &&
                sweep * WrapAngle(azimuth[k] - azimuth[k - 1]) < -kFarBack;
  }
  if (far_back * 10 > static_cast<std::size_t>(result.rings)) {
    return Error{"ring breaks: the azimuth jumps back by more than 10 deg " +
                 std::to_string(far_back) + " times within " + std::to_string(result.rings) +
                 " rings: not stored ring after ring"};
  }
  // Each ring sweeps nearly a turn (a tilting 2-D laser's lines sweep half of one).
  std::vector<double> first(result.rings, -1.0), last(result.rings, 0.0);
  for (std::size_t k = 0; k < m; ++k) {
    const int r = result.ring[index[k]];
    const double from_seam = WrapPositive(sweep * (azimuth[k] - result.seam_rad));
    if (first[r] < 0.0) first[r] = from_seam;
    last[r] = from_seam;
  }
  std::vector<double> travel(result.rings);
  for (int r = 0; r < result.rings; ++r) travel[r] = last[r] - first[r];
  std::nth_element(travel.begin(), travel.begin() + result.rings / 2, travel.end());
  const double median_travel = travel[result.rings / 2];
  if (median_travel < 1.5 * kPi) {
    return Error{"ring breaks: the median ring sweeps " +
                 std::to_string(static_cast<int>(median_travel * 180.0 / kPi)) +
                 " deg, expected at least 270: not stored ring after ring"};
  }
  return result;
}

namespace {

// Storage order index = col * rings + ring, judged from the data: the azimuth follows the
// column (one step per column, either way) and the rows have distinct, tight elevations.
struct OrganisedFit {
  bool ok = false;
  double resolved = 0.0;  // share of neighbouring rows (by elevation) told apart
  bool azimuth_decreasing = true;
};

OrganisedFit CheckOrganised(const std::vector<Eigen::Vector3f>& points,
                            const std::vector<double>& azimuth,
                            const std::vector<double>& elevation, std::size_t rings) {
  OrganisedFit fit;
  const std::size_t n = points.size(), columns = n / rings;
  if (rings < 2 || columns < 2 || n % rings != 0) return fit;
  const double step = 2.0 * kPi / static_cast<double>(columns);
  std::size_t pairs = 0, decreasing = 0, increasing = 0;
  for (std::size_t i = 0; i + rings < n; ++i) {
    const std::size_t next = i + rings;
    if (!IsReturn(points[i]) || !IsReturn(points[next])) continue;
    ++pairs;
    const double d = WrapAngle(azimuth[i] - azimuth[next]);
    decreasing += d > -2.0 * step && d < 4.0 * step;
    increasing += -d > -2.0 * step && -d < 4.0 * step;
  }
  if (pairs == 0 || std::max(decreasing, increasing) < kOrganisedAgreement * pairs) return fit;
  fit.azimuth_decreasing = decreasing >= increasing;
  std::vector<std::vector<double>> row_elevations(rings);
  for (std::size_t i = 0; i < n; ++i) {
    if (IsReturn(points[i])) row_elevations[i % rings].push_back(elevation[i]);
  }
  struct Row {
    double median, spread;
  };
  std::vector<Row> rows;
  for (std::vector<double>& e : row_elevations) {
    if (e.empty()) continue;
    auto at = [&](double q) {
      const auto it = e.begin() + static_cast<std::ptrdiff_t>(q * (e.size() - 1) + 0.5);
      std::nth_element(e.begin(), it, e.end());
      return *it;
    };
    const double p10 = at(0.1), p90 = at(0.9), median = at(0.5);
    rows.push_back({median, p90 - p10});
  }
  if (rows.size() < 2) return fit;
  std::sort(rows.begin(), rows.end(),
            [](const Row& a, const Row& b) { return a.median > b.median; });
  std::size_t apart = 0;
  for (std::size_t k = 1; k < rows.size(); ++k) {
    const double gap = rows[k - 1].median - rows[k].median;
    // Beams with vertical offsets (HDL-64E) scatter over more than their spacing: a row is
    // told apart from its neighbour when the gap is a quarter of their spread or more.
    apart += gap > 1e-6 && gap > 0.25 * std::max(rows[k - 1].spread, rows[k].spread);
  }
  fit.resolved = static_cast<double>(apart) / static_cast<double>(rows.size() - 1);
  fit.ok = fit.resolved >= kOrganisedAgreement;
  return fit;
}

// Columns of an organised scan, and column 0's azimuth from the data.
void OrganisedColumns(const PointCloud& cloud, std::size_t rings, bool azimuth_decreasing,
                      SphericalModel& model, std::vector<std::int32_t>& cols) {
  const std::size_t n = cloud.points.size(), columns = n / rings;
  const double step = 2.0 * kPi / static_cast<double>(columns);
  model.width = static_cast<int>(columns);
  cols.assign(n, -1);
  std::complex<double> start_sum(0.0, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t c = i / rings;
    const std::size_t col = azimuth_decreasing ? c : columns - 1 - c;
    if (!IsReturn(cloud.points[i])) continue;
    cols[i] = static_cast<std::int32_t>(col);
    start_sum +=
        std::polar(1.0, std::atan2(double(cloud.points[i].y()), double(cloud.points[i].x())) +
                            static_cast<double>(col) * step);
  }
  model.azimuth_start_rad = std::abs(start_sum) > 0.0 ? std::arg(start_sum) : 0.0;
}

// What FindLayout's finders share, once the angles are known.
struct LayoutScan {
  const PointCloud& cloud;
  const LayoutOptions& options;
  const std::string& source;  // names the cloud in errors
  const PointAngles& angles;  // every point's, NaN for no return
};

// The ring count of an organised scan (0: none found) and its fit.
struct OrganisedChoice {
  std::size_t rings = 0;
  OrganisedFit fit;
};

// Appends `text` to a layout's note, "; " between reasons.
void AddLayoutNote(std::string& note, const std::string& text) {
  note += (note.empty() ? "" : "; ") + text;
}

// Every return on the preset's nominal rings and columns; `note` says why.
FoundLayout NominalLayout(const std::vector<Eigen::Vector3f>& points, const LayoutOptions& options,
                          std::string note) {
  const std::size_t n = points.size();
  FoundLayout layout;
  layout.note = std::move(note);
  layout.source = RingSource::kNominal;
  layout.model = *options.preset;
  if (options.columns > 0) layout.model.width = options.columns;
  layout.rows.assign(n, -1);
  layout.cols.assign(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (!IsReturn(points[i])) continue;
    layout.rows[i] = layout.model.NearestRing(points[i].cast<double>());
    layout.cols[i] = layout.model.Column(points[i].cast<double>());
  }
  return layout;
}

// Rows found in the data, columns from the azimuth unless given (or the preset's nominal rings).
Expected<FoundLayout> FinishLayout(const LayoutScan& scan, std::string note, RingSource ring_source,
                                   RingFit fit, std::vector<std::int32_t> cols) {
  const LayoutOptions& options = scan.options;
  const std::vector<Eigen::Vector3f>& points = scan.cloud.points;
  const std::size_t n = points.size();
  if (options.preset && fit.model.height() != options.preset->height()) {
    AddLayoutNote(note, std::string(RingSourceName(ring_source)) + " give " +
                            std::to_string(fit.model.height()) + " rings, the preset has " +
                            std::to_string(options.preset->height()) + ": nominal rings used");
    return NominalLayout(points, options, std::move(note));
  }
  FoundLayout layout;
  layout.note = std::move(note);
  layout.source = ring_source;
  layout.rows = std::move(fit.rows);
  layout.model = std::move(fit.model);
  if (cols.empty()) {
    int width = options.columns;
    if (width == 0 && options.preset) width = options.preset->width;
    if (width == 0 && layout.model.width > 1) width = layout.model.width;  // chosen already
    if (width == 0) {
      Expected<int> measured = MeasureAzimuthSteps(points, layout.rows);
      if (!measured) return Error{scan.source + ": " + measured.error().message};
      width = *measured;
    }
    layout.model.width = width;
    // Column centres on the returns' azimuths; forward (+x) in the middle column, so
    // that range images read like the scene seen from the sensor.
    layout.model.azimuth_start_rad =
        WrapAngle(FitAzimuthStart(scan.angles, width) + (width / 2) * (2.0 * kPi / width));
    cols.assign(n, -1);
    for (std::size_t i = 0; i < n; ++i) {
      if (layout.rows[i] >= 0) cols[i] = layout.model.ColumnAt(scan.angles.azimuth[i]);
    }
  }
  layout.cols = std::move(cols);
  if (Status s = layout.model.Validate(); !s) return Error{scan.source + ": " + s.message()};
  return layout;
}

// Rows from the file's ring field; columns from the storage order too when it is organised.
Expected<FoundLayout> LayoutFromRingField(const LayoutScan& scan) {
  const PointCloud& cloud = scan.cloud;
  const std::size_t n = cloud.points.size();
  if (cloud.ring.size() != n) {
    return Error{scan.source + ": " + std::to_string(cloud.ring.size()) + " ring numbers for " +
                 std::to_string(n) + " points"};
  }
  const std::int32_t rings = *std::max_element(cloud.ring.begin(), cloud.ring.end()) + 1;
  Expected<RingFit> fit = FitRings(scan.angles, cloud.ring, rings, 1);
  if (!fit) return Error{scan.source + ": ring field: " + fit.error().message};
  // Organised as well (Ouster): the columns are the storage order's.
  std::vector<std::int32_t> cols;
  const std::size_t r = static_cast<std::size_t>(rings);
  bool in_order = scan.options.organised != OrganisedMode::kNo && n % r == 0;
  for (std::size_t i = 0; in_order && i < n; ++i) {
    in_order = static_cast<std::size_t>(cloud.ring[i]) == i % r;
  }
  if (in_order) {
    const OrganisedFit organised =
        CheckOrganised(cloud.points, scan.angles.azimuth, scan.angles.elevation, r);
    OrganisedColumns(cloud, r, organised.azimuth_decreasing, fit->model, cols);
  }
  return FinishLayout(scan, "", RingSource::kRingField, std::move(*fit), std::move(cols));
}

// The ring count that makes the storage order organised (0: none), forced by OrganisedMode::kYes.
Expected<OrganisedChoice> ChooseOrganisedRings(const LayoutScan& scan) {
  const LayoutOptions& options = scan.options;
  const std::vector<Eigen::Vector3f>& points = scan.cloud.points;
  const std::vector<double>& azimuth = scan.angles.azimuth;
  const std::vector<double>& elevation = scan.angles.elevation;
  const std::size_t n = points.size();
  std::vector<std::size_t> candidates;
  if (options.preset) {
    candidates.push_back(static_cast<std::size_t>(options.preset->height()));
  } else {
    for (std::size_t r = 2; r <= 1024 && r <= n / 2; ++r) {
      if (n % r == 0) candidates.push_back(r);
    }
  }
  OrganisedChoice best;
  for (std::size_t r : candidates) {
    const OrganisedFit fit = CheckOrganised(points, azimuth, elevation, r);
    if (fit.ok && fit.resolved > best.fit.resolved) {
      best.fit = fit;
      best.rings = r;
    }
  }
  if (best.rings == 0 && options.organised == OrganisedMode::kYes) {
    if (!options.preset) {
      return Error{scan.source + ": " + std::to_string(n) +
                   " points: no ring count makes an organised scan of them (index = col * "
                   "rings + ring with tight rows); give --sensor"};
    }
    best.rings = candidates.front();
    if (n % best.rings != 0) {
      return Error{scan.source + ": " + std::to_string(n) +
                   " points cannot be an organised scan of " + std::to_string(best.rings) +
                   " rings (not a multiple)"};
    }
    best.fit = CheckOrganised(points, azimuth, elevation, best.rings);
    best.fit.azimuth_decreasing = true;  // forced: Ouster's convention
  }
  return best;
}

// Columns for uniform elevation bins: square cells, about one return per cell.
Expected<int> SquareCellColumns(const LayoutScan& scan) {
  // About one return per cell over the directions seen: the band of elevations times the
  // azimuths covered (in 1-degree sectors; a 2-D laser tilting in front of a robot covers
  // half a turn).
  const std::vector<Eigen::Vector3f>& points = scan.cloud.points;
  const std::vector<double>& azimuth = scan.angles.azimuth;
  const std::vector<double>& elevation = scan.angles.elevation;
  double top = -kPi, bottom = kPi;
  std::size_t returns = 0;
  std::vector<char> sector(360, 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!IsReturn(points[i])) continue;
    top = std::max(top, elevation[i]);
    bottom = std::min(bottom, elevation[i]);
    sector[std::min<std::size_t>(
        359, static_cast<std::size_t>(WrapPositive(azimuth[i]) / (2.0 * kPi) * 360.0))] = 1;
    ++returns;
  }
  if (returns == 0) return Error{scan.source + ": no returns (every point is at the origin)"};
  const double covered = 2.0 * kPi * std::count(sector.begin(), sector.end(), 1) / 360.0;
  const double cell = std::sqrt(covered * std::max(top - bottom, 1e-3) / returns);
  return static_cast<int>(std::clamp(std::round(2.0 * kPi / cell), 16.0, 65536.0));
}

}  // namespace

Expected<FoundLayout> FindLayout(const PointCloud& cloud, const LayoutOptions& options,
                                 const std::string& source) {
  const std::vector<Eigen::Vector3f>& points = cloud.points;
  const std::size_t n = points.size();
  if (n == 0) return Error{source + ": no points"};
  if (options.preset) {
    if (Status s = options.preset->Validate(); !s) return Error{source + ": " + s.message()};
  }
  if (options.columns < 0) return Error{source + ": columns must be positive (0: automatic)"};
  if (Status s = options.elevation.Validate(); !s) return Error{source + ": " + s.message()};
  std::string note;  // why sources were passed over

  if (options.preset && options.organised == OrganisedMode::kNo) {
    return NominalLayout(points, options, note);
  }

  // Every point's angles, once (NaN for no return): each finder below reads them.
  const PointAngles angles(points);
  const LayoutScan scan{cloud, options, source, angles};

  // 1. The file's ring field.
  if (!cloud.ring.empty()) return LayoutFromRingField(scan);

  // 2. The storage order, organised.
  if (options.organised != OrganisedMode::kNo) {
    Expected<OrganisedChoice> organised = ChooseOrganisedRings(scan);
    if (!organised) return organised.error();
    const std::size_t rings = organised->rings;
    if (rings > 0) {
      std::vector<std::int32_t> ring(n);
      for (std::size_t i = 0; i < n; ++i) ring[i] = static_cast<std::int32_t>(i % rings);
      Expected<RingFit> fit = FitRings(angles, ring, static_cast<int>(rings), 1);
      if (fit) {
        std::vector<std::int32_t> cols;
        OrganisedColumns(cloud, rings, organised->fit.azimuth_decreasing, fit->model, cols);
        return FinishLayout(scan, note, RingSource::kOrganised, std::move(*fit), std::move(cols));
      }
      AddLayoutNote(note, "organised: " + fit.error().message);
    }
  }

  // 3. Ring after ring in the storage order.
  Expected<RingBreaks> breaks = FindRingBreaks(points, angles);
  if (breaks) {
    Expected<RingFit> fit = FitRings(angles, breaks->ring, breaks->rings, 1);
    if (fit) return FinishLayout(scan, note, RingSource::kRingBreaks, std::move(*fit), {});
    AddLayoutNote(note, fit.error().message);
  }

  // 4. The elevation histogram.
  Expected<RingFit> clusters = FindElevationRings(points, 1, options.elevation);
  if (clusters) {
    return FinishLayout(scan, note, RingSource::kElevationClusters, std::move(*clusters), {});
  }
  AddLayoutNote(note, clusters.error().message);

  // 5. No rings in the data.
  if (options.preset) return NominalLayout(points, options, note);
  int width = options.columns;
  if (width == 0) {
    Expected<int> square = SquareCellColumns(scan);
    if (!square) return square.error();
    width = *square;
  }
  Expected<RingFit> bins = UniformElevationBins(points, width);
  if (!bins) return Error{source + ": " + bins.error().message};
  return FinishLayout(scan, note, RingSource::kUniformBins, std::move(*bins), {});
}

Expected<PlacedScan> PlaceScan(const PointCloud& cloud, const LayoutOptions& options,
                               const Eigen::Vector3d& up_sensor, const std::string& source) {
  Expected<FoundLayout> layout = FindLayout(cloud, options, source);
  if (!layout) return layout.error();
  Expected<RangeImage> image =
      RangeImage::FromPoints(cloud.points, layout->model, up_sensor, layout->rows, layout->cols);
  if (!image) return Error{source + ": " + image.error().message};
  return PlacedScan{std::move(*layout), std::move(*image)};
}

}  // namespace cairn::od
