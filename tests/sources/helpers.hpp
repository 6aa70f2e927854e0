// Shared by the cairn::sources tests: MRPT's sample rawlogs, and synthetic observations with
// known geometry.
#pragma once

#include <gtest/gtest.h>
#include <mrpt/obs/CObservation3DRangeScan.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "cairn/od/units.hpp"
#include "cairn/sources/frame.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "cairn/sources/rawlog_source.hpp"

#ifndef CAIRN_MRPT_DATASETS
#error "CAIRN_MRPT_DATASETS must name MRPT's datasets folder"
#endif

namespace cairn::test {
inline std::optional<std::filesystem::path> MrptDataset(const std::string& name) {
  const std::filesystem::path path =
      std::filesystem::path(CAIRN_MRPT_DATASETS) / (name + ".rawlog");
  if (!std::filesystem::exists(path)) return std::nullopt;
  return path;
}

#define CAIRN_MRPT_DATASET_OR_SKIP(var, name)                                               \
  const std::optional<std::filesystem::path> var##_opt = ::cairn::test::MrptDataset(name); \
  if (!var##_opt) {                                                                         \
    GTEST_SKIP() << name << ".rawlog is absent from " << CAIRN_MRPT_DATASETS                \
                 << ": install Debian's mrpt-common (tools/setup-deps.sh)";                 \
  }                                                                                         \
  const std::filesystem::path& var = *var##_opt

/// The first range frame of a rawlog (fails the test when there is none).
inline sources::Frame FirstFrame(const std::filesystem::path& path,
                                 const sources::SourceOptions& options = {}) {
  Expected<sources::RawlogSource> source = sources::RawlogSource::Open(path, options);
  EXPECT_TRUE(source.ok()) << source.error().message;
  if (!source) return {};
  Expected<std::optional<sources::Frame>> frame = source->NextFrame();
  EXPECT_TRUE(frame.ok()) << frame.error().message;
  if (!frame || !*frame) {
    ADD_FAILURE() << path << ": no range frame";
    return {};
  }
  return std::move(**frame);
}

/// OpenCV's (and MRPT's) radial-tangential lens model, k1 k2 p1 p2 k3, on normalised
/// coordinates: where an undistorted ray (x, y, 1) is imaged.
inline Eigen::Vector2d Distort(const Eigen::Vector2d& p, const std::array<double, 8>& k) {
  const double x = p.x(), y = p.y(), r2 = x * x + y * y;
  const double radial = 1.0 + k[0] * r2 + k[1] * r2 * r2 + k[4] * r2 * r2 * r2;
  return {x * radial + 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x),
          y * radial + k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y};
}

/// The inverse, by Newton's method on Distort (numerical Jacobian); exact to 1e-12 for the
/// moderate distortions of the tests.
inline Eigen::Vector2d Undistort(const Eigen::Vector2d& d, const std::array<double, 8>& k) {
  Eigen::Vector2d p = d;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d f = Distort(p, k) - d;
    if (f.norm() < 1e-14) break;
    Eigen::Matrix2d J;
    const double h = 1e-7;
    J.col(0) = (Distort(p + Eigen::Vector2d(h, 0), k) - Distort(p, k)) / h;
    J.col(1) = (Distort(p + Eigen::Vector2d(0, h), k) - Distort(p, k)) / h;
    p -= J.inverse() * f;
  }
  return p;
}

/// A synthetic range camera: `width` x `height` pixels, focal `f`, principal point at the
/// centre, looking at z-depth `depth(col, row)` [m] (0: no return), with ranges stored in
/// 0.1 mm units as z-depth or as distance along the (undistorted) ray.
inline mrpt::obs::CObservation3DRangeScan::Ptr MakeScan(
    int width, int height, double f, const std::function<double(int, int)>& depth,
    bool range_is_depth) {
  auto scan = std::make_shared<mrpt::obs::CObservation3DRangeScan>();
  scan->sensorLabel = "RGBD";
  scan->timestamp = sources::ToMrptTime(1704067200.25);
  scan->hasRangeImage = true;
  scan->range_is_depth = range_is_depth;
  scan->rangeUnits = 0.0001f;
  scan->rangeImage_setSize(height, width);
  const double cx = (width - 1) / 2.0, cy = (height - 1) / 2.0;
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      double d = depth(c, r);
      if (!range_is_depth) {
        const double kx = (c - cx) / f, ky = (r - cy) / f;
        d *= std::sqrt(1.0 + kx * kx + ky * ky);
      }
      scan->rangeImage(r, c) = static_cast<std::uint16_t>(std::lround(d / 0.0001));
    }
  }
  scan->cameraParams.ncols = static_cast<std::uint32_t>(width);
  scan->cameraParams.nrows = static_cast<std::uint32_t>(height);
  scan->cameraParams.setIntrinsicParamsFromValues(f, f, cx, cy);
  scan->cameraParamsIntensity = scan->cameraParams;
  scan->maxRange = 10.0f;
  return scan;
}

}  // namespace cairn::test
