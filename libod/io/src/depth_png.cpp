#include "cairn/od/io/depth_png.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>

#include "png.hpp"

namespace cairn::od::io {

Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path, int width, int height,
                                   double depth_scale_m) {
  const std::string name = path.string();
  if (!(depth_scale_m > 0.0) || !std::isfinite(depth_scale_m)) {
    return Error{name + ": depth_scale must be a positive number of metres per unit"};
  }
  Expected<cv::Mat> image = detail::ReadPng(path, CV_16UC1, "16-bit single-channel depth");
  if (!image) return image.error();
  if (image->cols != width || image->rows != height) {
    return Error{name + ": image is " + std::to_string(image->cols) + "x" +
                 std::to_string(image->rows) + " px, the intrinsics say width " +
                 std::to_string(width) + ", height " + std::to_string(height)};
  }
  Grid<float> depth;
  depth.width = width;
  depth.height = height;
  depth.data.resize(static_cast<std::size_t>(width) * height);
  for (int r = 0; r < height; ++r) {
    const std::uint16_t* row = image->ptr<std::uint16_t>(r);
    for (int c = 0; c < width; ++c) {
      depth.at(r, c) = static_cast<float>(row[c] * depth_scale_m);
    }
  }
  return depth;
}

Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path,
                                   const CameraIntrinsics& intrinsics) {
  return ReadDepthPng(path, intrinsics.model.width, intrinsics.model.height,
                      intrinsics.depth_scale_m);
}

Status WriteDepthPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                     double depth_scale_m) {
  const std::string name = path.string();
  if (!(depth_scale_m > 0.0) || !std::isfinite(depth_scale_m)) {
    return Error{name + ": depth_scale must be a positive number of metres per unit"};
  }
  if (depth_m.width <= 0 || depth_m.height <= 0 ||
      depth_m.data.size() != static_cast<std::size_t>(depth_m.width) * depth_m.height) {
    return Error{name + ": depth grid of " + std::to_string(depth_m.data.size()) +
                 " values does not match its size " + std::to_string(depth_m.width) + "x" +
                 std::to_string(depth_m.height)};
  }
  cv::Mat image(depth_m.height, depth_m.width, CV_16UC1);
  for (int r = 0; r < depth_m.height; ++r) {
    std::uint16_t* row = image.ptr<std::uint16_t>(r);
    for (int c = 0; c < depth_m.width; ++c) {
      const double d = depth_m.at(r, c);
      if (!std::isfinite(d) || d <= 0.0) {
        row[c] = 0;
        continue;
      }
      const double units = std::round(d / depth_scale_m);
      if (units > 65535.0) {
        return Error{name + ": depth " + std::to_string(d) + " m at row " + std::to_string(r) +
                     ", col " + std::to_string(c) + " exceeds the 16-bit range (" +
                     std::to_string(65535.0 * depth_scale_m) + " m at depth_scale " +
                     std::to_string(depth_scale_m) + ")"};
      }
      // A tiny positive depth must stay a return, not become "no return".
      row[c] = static_cast<std::uint16_t>(std::max(1.0, units));
    }
  }
  return detail::WritePngAtomic(path, image);
}

}  // namespace cairn::od::io
