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
  image.width_ = model.width;
  image.height_ = model.height;
  image.model_ = model;
  if (Status s = image.SetUp(up_sensor); !s) return s.error();

  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  image.x_.assign(n, kNaN);
  image.y_.assign(n, kNaN);
  image.z_.assign(n, kNaN);
  image.valid_.assign(n, 0);
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

Status RangeImage::SetUp(const Eigen::Vector3d& up_sensor) {
  // The forward axis of every current model is the optical axis (+z).
  Expected<Eigen::Matrix3d> R = LevelRotation(up_sensor, Eigen::Vector3d::UnitZ());
  if (!R) return Error{"range image: up vector " + R.error().message};
  R_level_sensor_ = *R;
  up_ = up_sensor.normalized();
  return Status::Ok();
}

int RangeImage::valid_count() const {
  return static_cast<int>(std::count(valid_.begin(), valid_.end(), std::uint8_t{1}));
}

}  // namespace cairn::od
