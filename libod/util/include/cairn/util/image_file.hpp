// Images to files: encoded by OpenCV in memory, then written crash-safe (atomic_file.hpp).
// A target of its own, cairn::util_image, so that only what writes images links OpenCV
// (libsim's worlds and renderers do not).
#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"

namespace cairn::util {

/// Encodes `image` in `format` (OpenCV's extension: ".png", ".pgm", ".tiff") with OpenCV's
/// `params` (cv::IMWRITE_*) and writes it atomically. Errors name the file, the format and
/// the image's type.
Status WriteImageAtomic(const std::filesystem::path& path, const cv::Mat& image,
                        const std::string& format = ".png", const std::vector<int>& params = {});

/// An 8-bit grey grid as an OpenCV matrix over its values, without a copy: the grid must
/// outlive the matrix, and the matrix is only read (OpenCV takes the values as non-const).
/// The grid must be well formed.
cv::Mat GreyMatView(const od::Grid<std::uint8_t>& image);
/// An 8-bit single-channel matrix copied into a grid.
od::Grid<std::uint8_t> GreyGridOf(const cv::Mat& m);

/// An OpenCV matrix type in words: "8-bit 3-channel", "16-bit single-channel", ...
std::string DescribeImageType(int type);

}  // namespace cairn::util
