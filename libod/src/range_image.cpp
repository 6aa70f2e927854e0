#include "cairn/od/range_image.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "cairn/od/leveling.hpp"

namespace cairn::od {

Expected<RangeImage> RangeImage::FromDepth(const std::vector<float>& depth_m,
                                           const PinholeModel& model,
                                           const Eigen::Vector3d& up_sensor) {
  if (Status s = model.Validate(); !s) return s.error();
  const std::size_t n = static_cast<std::size_t>(model.width) * model.height;
  if (depth_m.size() != n) {
    return Error{"depth image has " + std::to_string(depth_m.size()) + " values, expected " +
                 std::to_string(model.width) + " x " + std::to_string(model.height)};
  }
  RangeImage image;
  image.model_ = model;
  if (Status s = image.SetUp(up_sensor); !s) return s.error();

  image.Allocate(model.width, model.height);
  for (int r = 0; r < model.height; ++r) {
    for (int c = 0; c < model.width; ++c) {
      const int i = r * model.width + c;
      const float d = depth_m[i];
      if (!(d > 0.0f) || !std::isfinite(d)) continue;
      const Eigen::Vector3d p = model.Unproject(c, r, d);
      image.x_[i] = static_cast<float>(p.x());
      image.y_[i] = static_cast<float>(p.y());
      image.z_[i] = static_cast<float>(p.z());
      image.valid_[i] = 1;
    }
  }
  return image;
}

Expected<RangeImage> RangeImage::FromPoints(const std::vector<Eigen::Vector3f>& points,
                                            const SphericalModel& model,
                                            const Eigen::Vector3d& up_sensor,
                                            const std::vector<std::int32_t>& rows,
                                            const std::vector<std::int32_t>& cols) {
  if (Status s = model.Validate(); !s) return s.error();
  const auto size_error = [&](const char* what, std::size_t size) {
    return Error{std::string("point cloud: '") + what + "' has " + std::to_string(size) +
                 " entries for " + std::to_string(points.size()) + " points"};
  };
  if (!rows.empty() && rows.size() != points.size()) return size_error("rows", rows.size());
  if (!cols.empty() && cols.size() != points.size()) return size_error("cols", cols.size());
  RangeImage image;
  image.model_ = model;
  if (Status s = image.SetUp(up_sensor); !s) return s.error();
  const int width = model.width, height = model.height();
  image.Allocate(width, height);
  image.cell_of_point_.assign(points.size(), -1);
  std::vector<float> best_range(static_cast<std::size_t>(width) * height,
                                std::numeric_limits<float>::infinity());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    const float range = p.norm();
    if (!std::isfinite(range) || range <= 0.0f) continue;
    const int row = rows.empty() ? model.NearestRing(p.cast<double>()) : rows[i];
    const int col = cols.empty() ? model.Column(p.cast<double>()) : cols[i];
    if (row < 0 || row >= height || col < 0 || col >= width) {
      return Error{"point cloud: point " + std::to_string(i) + " has cell (row " +
                   std::to_string(row) + ", col " + std::to_string(col) + ") outside " +
                   std::to_string(height) + " x " + std::to_string(width)};
    }
    const int cell = row * width + col;
    image.cell_of_point_[i] = cell;
    if (range >= best_range[cell]) continue;
    best_range[cell] = range;
    image.x_[cell] = p.x();
    image.y_[cell] = p.y();
    image.z_[cell] = p.z();
    image.valid_[cell] = 1;
  }
  return image;
}

int RangeImage::DropReturnsNearerThan(double range_m) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const double range2 = range_m * range_m;
  int dropped = 0;
  for (std::size_t i = 0; i < valid_.size(); ++i) {
    if (valid_[i] == 0) continue;
    const double r2 = static_cast<double>(x_[i]) * x_[i] + static_cast<double>(y_[i]) * y_[i] +
                      static_cast<double>(z_[i]) * z_[i];
    if (!(r2 < range2)) continue;
    x_[i] = y_[i] = z_[i] = kNaN;
    valid_[i] = 0;
    ++dropped;
  }
  return dropped;
}

void RangeImage::Allocate(int width, int height) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const std::size_t n = static_cast<std::size_t>(width) * height;
  width_ = width;
  height_ = height;
  x_.assign(n, kNaN);
  y_.assign(n, kNaN);
  z_.assign(n, kNaN);
  valid_.assign(n, 0);
}

Status RangeImage::SetUp(const Eigen::Vector3d& up_sensor) {
  // Heading: the optical axis (+z) of a camera, +x of a LiDAR.
  const Eigen::Vector3d forward = std::holds_alternative<PinholeModel>(model_)
                                      ? Eigen::Vector3d::UnitZ()
                                      : Eigen::Vector3d::UnitX();
  Expected<Eigen::Matrix3d> R = LevelRotation(up_sensor, forward);
  if (!R) return Error{"range image: up vector " + R.error().message};
  R_level_sensor_ = *R;
  up_ = up_sensor.normalized();
  return Status::Ok();
}

int RangeImage::valid_count() const {
  return static_cast<int>(std::count(valid_.begin(), valid_.end(), std::uint8_t{1}));
}

}  // namespace cairn::od
