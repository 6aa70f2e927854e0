#include "cairn/map/gravity_cues.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <variant>

#include "cairn/od/units.hpp"

namespace cairn::map {
namespace {

Status VerticalsError(const std::string& field, const std::string& what) {
  return Error{"tilt.verticals." + field + ": " + what};
}

constexpr double kLowFraction = 0.2;
constexpr double kLowMinM = 0.3;

// Principal axes of points: eigenvalues ascending (l3 <= l2 <= l1), axes as columns.
struct Shape {
  bool ok = false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d l = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
};

Shape ShapeOf(const std::vector<Eigen::Vector3d>& points) {
  Shape s;
  if (points.size() < 3) return s;
  for (const Eigen::Vector3d& p : points) s.mean += p;
  s.mean /= static_cast<double>(points.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) covariance += (p - s.mean) * (p - s.mean).transpose();
  covariance /= static_cast<double>(points.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  if (eig.info() != Eigen::Success) return s;
  s.l = eig.eigenvalues().cwiseMax(1e-12);
  s.axes = eig.eigenvectors();
  s.ok = true;
  return s;
}

}  // namespace

Status VerticalCueConfig::Validate() const {
  if (!(min_height_m >= 0.0 && std::isfinite(min_height_m))) {
    return VerticalsError("min_height", "must be >= 0 m");
  }
  if (min_points < 3) return VerticalsError("min_points", "must be >= 3");
  if (!(min_elongation >= 1.0 && std::isfinite(min_elongation))) {
    return VerticalsError("min_elongation", "must be >= 1");
  }
  if (!(max_radius_m > 0.0 && std::isfinite(max_radius_m))) {
    return VerticalsError("max_radius", "must be > 0 m");
  }
  if (!(min_wall_width_m > 0.0 && std::isfinite(min_wall_width_m))) {
    return VerticalsError("min_wall_width", "must be > 0 m");
  }
  if (!(min_flatness >= 1.0 && std::isfinite(min_flatness))) {
    return VerticalsError("min_flatness", "must be >= 1");
  }
  if (!(max_angle_rad > 0.0 && max_angle_rad <= 0.5 * kPi)) {
    return VerticalsError("max_angle", "must be in (0, 90] deg");
  }
  if (!(max_range_m > 0.0)) return VerticalsError("max_range", "must be > 0 m");
  return {};
}

std::vector<VerticalCue> FindVerticalCues(const od::RangeImage& image,
                                          const od::Detection& detection,
                                          const od::Classification& classification,
                                          const Eigen::Vector3d& up_sensor,
                                          const VerticalCueConfig& config) {
  std::vector<VerticalCue> cues;
  const std::size_t segments = detection.segments.size();
  if (segments == 0) return cues;
  const Eigen::Vector3d up = up_sensor.normalized();
  // The points of each kept segment that could be a cue, and the heights (along `up`) of
  // those in the image's first and last rows.
  const int width = image.width(), last_row = (image.height() - 1) * width;
  std::vector<std::vector<Eigen::Vector3d>> points(segments);
  struct EdgeRow {
    double min = std::numeric_limits<double>::infinity();
    double max = -std::numeric_limits<double>::infinity();
  };
  std::vector<EdgeRow> first(segments), last(segments);
  for (int i = 0; i < image.size(); ++i) {
    const int label = detection.labels[i];
    if (label <= 0 || !image.valid(i)) continue;
    if (classification.verdicts[label - 1].cls != od::SegmentClass::kKept) continue;
    const od::SegmentFeatures& f = detection.segments[label - 1];
    if (f.height_max_m < config.min_height_m || f.range_mean_m > config.max_range_m) continue;
    points[label - 1].push_back(image.point(i));
    if (i < width || i >= last_row) {
      EdgeRow& e = (i < width ? first : last)[label - 1];
      e.min = std::min(e.min, image.point(i).dot(up));
      e.max = std::max(e.max, image.point(i).dot(up));
    }
  }
  const bool wraps = std::holds_alternative<od::SphericalModel>(image.model());
  const double cos_max = std::cos(config.max_angle_rad);
  const double sin_max = std::sin(config.max_angle_rad);
  for (std::size_t k = 0; k < segments; ++k) {
    std::vector<Eigen::Vector3d>& p = points[k];
    if (static_cast<int>(p.size()) < config.min_points) continue;
    // The lowest part of a segment is where it meets the ground (its foot, and on a slope
    // ground that tilts the axis): only the points above the lowest kLowFraction of its
    // height (and at least kLowMinM above its lowest point) are measured.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Eigen::Vector3d& q : p) {
      lo = std::min(lo, q.dot(up));
      hi = std::max(hi, q.dot(up));
    }
    const double cut = lo + std::max(kLowMinM, kLowFraction * (hi - lo));
    // A segment an edge row of the image cuts at its top (a trunk taller than the view, or
    // than a LiDAR's top ring reaches: the first row, or the last in an image held upside
    // down) is measured below the lowest of its points there: that row's rays (a pitched
    // camera's plane, a ring's cone) cut a trunk higher at its sides than at its front, and
    // what lies above the lowest cut leans the axis away from the sensor. With the trunks
    // the image's sides cut left out (below), the cues of VerticalCues.ATrunkCutByTheImage-
    // StillPointsUp lean 0.01 deg on average instead of 0.11 (0.26 with the camera rolled).
    double top = std::numeric_limits<double>::infinity();
    for (const EdgeRow& e : {first[k], last[k]}) {
      if (e.max > 0.5 * (lo + hi)) top = std::min(top, e.min);
    }
    p.erase(std::remove_if(
                p.begin(), p.end(),
                [&](const Eigen::Vector3d& q) { return q.dot(up) < cut || q.dot(up) > top; }),
            p.end());
    if (static_cast<int>(p.size()) < config.min_points) continue;
    Shape shape = ShapeOf(p);
    if (!shape.ok) continue;
    const double s1 = std::sqrt(shape.l(2)), s2 = std::sqrt(shape.l(1)), s3 = std::sqrt(shape.l(0));
    if (s1 / s2 >= config.min_elongation && s2 <= config.max_radius_m) {
      // A trunk. One the image's left or right edge cuts is no cue: that edge is not vertical
      // where the camera is pitched or rolled, and what is left of the trunk leans. (For a
      // camera held upright, its roll within 45 deg; a LiDAR scan's columns wrap around.)
      const od::SegmentFeatures& f = detection.segments[k];
      if (!wraps && (f.col_min == 0 || f.col_max == width - 1)) continue;
      // Refit without the points far from the first axis (mixed pixels at its silhouette, a
      // branch).
      const Eigen::Vector3d axis0 = shape.axes.col(2);
      std::vector<double> off(p.size());
      for (std::size_t j = 0; j < p.size(); ++j) off[j] = ((p[j] - shape.mean).cross(axis0)).norm();
      std::vector<double> sorted = off;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const double limit = 2.5 * std::max(sorted[sorted.size() / 2], 0.01);
      std::vector<Eigen::Vector3d> inliers;
      for (std::size_t j = 0; j < p.size(); ++j) {
        if (off[j] <= limit) inliers.push_back(p[j]);
      }
      if (static_cast<int>(inliers.size()) >= config.min_points) shape = ShapeOf(inliers);
      if (!shape.ok) continue;
      Eigen::Vector3d axis = shape.axes.col(2);
      if (axis.dot(up) < 0.0) axis = -axis;
      if (axis.dot(up) >= cos_max) cues.push_back({axis, false});
    } else if (config.walls && s2 >= config.min_wall_width_m && s2 / s3 >= config.min_flatness) {
      const Eigen::Vector3d normal = shape.axes.col(0);
      // A wall stands: its plane holds the vertical.
      if (std::abs(normal.dot(up)) <= sin_max) cues.push_back({normal, true});
    }
  }
  return cues;
}

}  // namespace cairn::map
