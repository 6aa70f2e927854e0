#include "cairn/od/io/depth_png.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"
#include "png.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::od::io {
namespace {

bool IsTiff(const std::string& bytes) {
  return bytes.size() >= 4 &&
         (std::memcmp(bytes.data(), "II*\0", 4) == 0 || std::memcmp(bytes.data(), "MM\0*", 4) == 0);
}

bool IsPng(const std::string& bytes) {
  return bytes.size() >= 8 && std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) == 0;
}

Status CheckScale(const std::string& name, double depth_scale_m) {
  if (!(depth_scale_m > 0.0) || !std::isfinite(depth_scale_m)) {
    return Error{name + ": depth_scale must be a positive number of metres per unit"};
  }
  return Status::Ok();
}

Status CheckSize(const std::string& name, const cv::Mat& image, int width, int height) {
  if (image.cols != width || image.rows != height) {
    return Error{name + ": image is " + std::to_string(image.cols) + "x" +
                 std::to_string(image.rows) + " px, the intrinsics say width " +
                 std::to_string(width) + ", height " + std::to_string(height)};
  }
  return Status::Ok();
}

Grid<float> Scaled16(const cv::Mat& image, double depth_scale_m) {
  Grid<float> depth;
  depth.width = image.cols;
  depth.height = image.rows;
  depth.data.resize(static_cast<std::size_t>(image.cols) * image.rows);
  for (int r = 0; r < image.rows; ++r) {
    const std::uint16_t* row = image.ptr<std::uint16_t>(r);
    for (int c = 0; c < image.cols; ++c) {
      depth.at(r, c) = static_cast<float>(row[c] * depth_scale_m);
    }
  }
  return depth;
}

}  // namespace

Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path, int width, int height,
                                   double depth_scale_m) {
  const std::string name = path.string();
  if (Status s = CheckScale(name, depth_scale_m); !s) return s.error();
  Expected<cv::Mat> image = detail::ReadPng(path, CV_16UC1, "16-bit single-channel depth");
  if (!image) return image.error();
  if (Status s = CheckSize(name, *image, width, height); !s) return s.error();
  return Scaled16(*image, depth_scale_m);
}

Expected<Grid<float>> ReadDepthPng(const std::filesystem::path& path,
                                   const CameraIntrinsics& intrinsics) {
  return ReadDepthPng(path, intrinsics.model.width, intrinsics.model.height,
                      intrinsics.depth_scale_m);
}

Expected<Grid<float>> ReadDepthTiff(const std::filesystem::path& path, int width, int height,
                                    double depth_scale_m) {
  const std::string name = path.string();
  if (Status s = CheckScale(name, depth_scale_m); !s) return s.error();
  Expected<std::string> bytes = util::ReadTextFile(path);
  if (!bytes) return bytes.error();
  if (!IsTiff(*bytes)) {
    return Error{name + ": not a TIFF file (expected a 32-bit float single-channel TIFF)"};
  }
  cv::Mat image;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes->size()), CV_8UC1, bytes->data());
    image = cv::imdecode(raw, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return Error{name + ": unreadable TIFF: " + e.err};
  }
  if (image.empty()) return Error{name + ": unreadable TIFF (corrupt or truncated)"};
  if (image.type() != CV_32FC1 && image.type() != CV_16UC1) {
    return Error{name + ": expected a 32-bit float (or 16-bit) single-channel TIFF, got " +
                 util::DescribeImageType(image.type())};
  }
  if (Status s = CheckSize(name, image, width, height); !s) return s.error();
  if (image.type() == CV_16UC1) return Scaled16(image, depth_scale_m);
  Grid<float> depth;
  depth.width = width;
  depth.height = height;
  depth.data.resize(static_cast<std::size_t>(width) * height);
  for (int r = 0; r < height; ++r) {
    const float* row = image.ptr<float>(r);
    for (int c = 0; c < width; ++c) {
      depth.at(r, c) = std::isfinite(row[c]) && row[c] > 0.0f ? row[c] : 0.0f;
    }
  }
  return depth;
}

Expected<Grid<float>> ReadDepthImage(const std::filesystem::path& path, int width, int height,
                                     double depth_scale_m) {
  const std::string name = path.string();
  // The signature decides, not the file name (a depth PNG saved as .tif still reads).
  Expected<std::string> bytes = util::ReadTextFile(path);
  if (!bytes) return bytes.error();
  if (IsTiff(*bytes)) return ReadDepthTiff(path, width, height, depth_scale_m);
  if (IsPng(*bytes)) return ReadDepthPng(path, width, height, depth_scale_m);
  return Error{name + ": not a depth image (expected a 16-bit PNG or a 32-bit float TIFF)"};
}

Expected<Grid<float>> ReadDepthImage(const std::filesystem::path& path,
                                     const CameraIntrinsics& intrinsics) {
  return ReadDepthImage(path, intrinsics.model.width, intrinsics.model.height,
                        intrinsics.depth_scale_m);
}

Status WriteDepthTiff(const std::filesystem::path& path, const Grid<float>& depth_m) {
  const std::string name = path.string();
  if (depth_m.width <= 0 || depth_m.height <= 0 ||
      depth_m.data.size() != static_cast<std::size_t>(depth_m.width) * depth_m.height) {
    return Error{name + ": depth grid of " + std::to_string(depth_m.data.size()) +
                 " values does not match its size " + std::to_string(depth_m.width) + "x" +
                 std::to_string(depth_m.height)};
  }
  cv::Mat image(depth_m.height, depth_m.width, CV_32FC1);
  for (int r = 0; r < depth_m.height; ++r) {
    float* row = image.ptr<float>(r);
    for (int c = 0; c < depth_m.width; ++c) {
      const float d = depth_m.at(r, c);
      row[c] = std::isfinite(d) && d > 0.0f ? d : 0.0f;
    }
  }
  return util::WriteImageAtomic(name, image, ".tiff");
}

Status WriteDepthPng(const std::filesystem::path& path, const Grid<float>& depth_m,
                     double depth_scale_m) {
  const std::string name = path.string();
  if (Status s = CheckScale(name, depth_scale_m); !s) return s.error();
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
  return util::WriteImageAtomic(path, image);
}

}  // namespace cairn::od::io
