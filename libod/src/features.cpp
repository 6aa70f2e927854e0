#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <variant>

#include "detection_internal.hpp"

namespace cairn::od::internal {

LevelPoints::LevelPoints(const RangeImage& image)
    : x(image.size()), y(image.size()), z(image.size()) {
  const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();
  for (int i = 0; i < image.size(); ++i) {
    const Eigen::Vector3f p(image.x()[i], image.y()[i], image.z()[i]);
    const Eigen::Vector3f q = R * p;  // NaN stays NaN
    x[i] = q.x();
    y[i] = q.y();
    z[i] = q.z();
  }
}

RowTiles::RowTiles(const LevelPoints& level, int width, int height)
    : tiles_per_row((width + kTileWidth - 1) / kTileWidth) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const std::size_t n = static_cast<std::size_t>(tiles_per_row) * height;
  for (auto* v : {&x_min, &y_min, &z_min}) v->assign(n, kInf);
  for (auto* v : {&x_max, &y_max, &z_max}) v->assign(n, -kInf);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const int i = r * width + c;
      if (std::isnan(level.z[i])) continue;
      const std::size_t t = static_cast<std::size_t>(r) * tiles_per_row + c / kTileWidth;
      x_min[t] = std::min(x_min[t], level.x[i]);
      x_max[t] = std::max(x_max[t], level.x[i]);
      y_min[t] = std::min(y_min[t], level.y[i]);
      y_max[t] = std::max(y_max[t], level.y[i]);
      z_min[t] = std::min(z_min[t], level.z[i]);
      z_max[t] = std::max(z_max[t], level.z[i]);
    }
  }
}

UnionFind::UnionFind(int n) : parent_(n) {
  for (int i = 0; i < n; ++i) parent_[i] = i;
}

int UnionFind::Find(int i) {
  while (parent_[i] != i) {
    parent_[i] = parent_[parent_[i]];  // path halving
    i = parent_[i];
  }
  return i;
}

void UnionFind::Union(int i, int j) {
  i = Find(i);
  j = Find(j);
  if (i == j) return;
  if (i < j) {
    parent_[j] = i;
  } else {
    parent_[i] = j;
  }
}

void UnionFind::Merge(UnionFind& other) {
  for (int i = 0; i < static_cast<int>(parent_.size()); ++i) {
    const int root = other.Find(i);
    if (root != i) Union(i, root);
  }
}

std::vector<std::int32_t> UnionFind::Components() {
  const int n = static_cast<int>(parent_.size());
  std::vector<std::int32_t> size(n, 0), root(n);
  for (int i = 0; i < n; ++i) ++size[root[i] = Find(i)];
  for (int i = 0; i < n; ++i) {
    if (size[root[i]] == 1) root[i] = -1;
  }
  return root;
}

namespace {

struct SegmentSums {
  double sx = 0, sy = 0, sz = 0, s_range = 0, slope_sum = 0;
  double z_min = std::numeric_limits<double>::infinity();
};

}  // namespace

Detection BuildDetection(const RangeImage& image, const LevelPoints& level,
                         const std::vector<std::int32_t>& component,
                         const std::vector<std::uint8_t>& raised, float min_height,
                         const DetectionStats& stats) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int n = image.size(), width = image.width();
  Detection det;
  det.width = width;
  det.height = image.height();
  det.labels.assign(n, 0);
  det.foot.assign(n, 0);
  det.stats = stats;
  det.stats.obstacle_points = 0;

  // Ids in row-major order of first pixels; id_of_rep maps a representative to its id.
  // The segments' pixels, in row-major order: every later pass visits only them.
  std::vector<std::int32_t> members;
  for (int i = 0; i < n; ++i) {
    if (component[i] >= 0) members.push_back(i);
  }
  std::vector<std::int32_t> id_of_rep(n, 0);
  std::vector<SegmentSums> sums;
  for (const int i : members) {
    const int rep = component[i];
    if (id_of_rep[rep] == 0) {
      id_of_rep[rep] = static_cast<std::int32_t>(det.segments.size()) + 1;
      SegmentFeatures f;
      f.id = id_of_rep[rep];
      f.bbox_min = Eigen::Vector3d::Constant(kInf);
      f.bbox_max = Eigen::Vector3d::Constant(-kInf);
      f.range_min_m = kInf;
      f.row_min = f.col_min = std::numeric_limits<int>::max();
      f.row_max = f.col_max = -1;
      det.segments.push_back(f);
      sums.emplace_back();
    }
    const int id = id_of_rep[rep];
    det.labels[i] = id;
    ++det.stats.obstacle_points;
    SegmentFeatures& f = det.segments[id - 1];
    SegmentSums& s = sums[id - 1];
    const Eigen::Vector3d p(level.x[i], level.y[i], level.z[i]);
    const double range = image.range(i);
    ++f.point_count;
    f.raised_count += raised[i] != 0;
    f.bbox_min = f.bbox_min.cwiseMin(p);
    f.bbox_max = f.bbox_max.cwiseMax(p);
    f.range_min_m = std::min(f.range_min_m, range);
    const int r = i / width, c = i % width;
    f.row_min = std::min(f.row_min, r);
    f.row_max = std::max(f.row_max, r);
    f.col_min = std::min(f.col_min, c);
    f.col_max = std::max(f.col_max, c);
    s.sx += p.x();
    s.sy += p.y();
    s.sz += p.z();
    s.s_range += range;
    s.z_min = std::min(s.z_min, p.z());
  }
  // Surface slopes from each point's neighbours in its own segment.
  const bool wraps = std::holds_alternative<SphericalModel>(image.model());
  const int height = image.height();
  const auto at = [&](int j) { return Eigen::Vector3d(level.x[j], level.y[j], level.z[j]); };
  // The tangent along one line through i: neighbours `before` and `after` (-1: none).
  const auto tangent = [&](int i, int before, int after, Eigen::Vector3d& t) {
    const int id = det.labels[i];
    const bool b = before >= 0 && det.labels[before] == id;
    const bool a = after >= 0 && det.labels[after] == id;
    if (!a && !b) return false;
    t = (a ? at(after) : at(i)) - (b ? at(before) : at(i));
    return true;
  };
  for (const int i : members) {
    const int id = det.labels[i];
    const int r = i / width, c = i % width;
    int left = c > 0 ? i - 1 : (wraps ? i + width - 1 : -1);
    int right = c + 1 < width ? i + 1 : (wraps ? i - c : -1);
    if (width == 1) left = right = -1;
    const int up = r > 0 ? i - width : -1;
    const int down = r + 1 < height ? i + width : -1;
    Eigen::Vector3d tu, tv;
    if (!tangent(i, left, right, tu) || !tangent(i, up, down, tv)) continue;
    const Eigen::Vector3d normal = tu.cross(tv);
    const double horizontal = std::sqrt(normal.x() * normal.x() + normal.y() * normal.y());
    if (!(horizontal > 0.0 || normal.z() != 0.0)) continue;
    const double slope = std::atan2(horizontal, std::abs(normal.z()));
    SegmentFeatures& f = det.segments[id - 1];
    ++f.slope_points;
    f.slope_max_rad = std::max(f.slope_max_rad, slope);
    sums[id - 1].slope_sum += slope;
  }
  for (std::size_t k = 0; k < det.segments.size(); ++k) {
    SegmentFeatures& f = det.segments[k];
    const SegmentSums& s = sums[k];
    const double np = f.point_count;
    const Eigen::Vector3d extent = f.bbox_max - f.bbox_min;
    f.bbox_perimeter_m = 2.0 * (extent.x() + extent.y());
    f.bbox_volume_m3 = extent.x() * extent.y() * extent.z();
    f.slope_mean_rad = f.slope_points > 0 ? s.slope_sum / f.slope_points : 0.0;
    f.centroid = Eigen::Vector3d(s.sx, s.sy, s.sz) / np;
    f.ground_height_m = s.z_min;
    f.height_mean_m = f.centroid.z() - s.z_min;
    f.height_max_m = f.bbox_max.z() - s.z_min;
    f.range_mean_m = s.s_range / np;
  }
  // Feet: not raised, and lower than HT above the segment's ground.
  for (const int i : members) {
    const int id = det.labels[i];
    if (raised[i] != 0) continue;
    SegmentFeatures& f = det.segments[id - 1];
    if (level.z[i] - f.ground_height_m < min_height) {
      det.foot[i] = 1;
      ++f.foot_count;
    }
  }
  return det;
}

}  // namespace cairn::od::internal
