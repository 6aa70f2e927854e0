// Images to files: encoded by OpenCV in memory, then written crash-safe (atomic_file.hpp).
// A target of its own, cairn::util_image, so that only what writes images links OpenCV
// (libsim's worlds and renderers do not).
#pragma once

#include <filesystem>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::util {

/// Encodes `image` in `format` (OpenCV's extension: ".png", ".pgm", ".tiff") with OpenCV's
/// `params` (cv::IMWRITE_*) and writes it atomically. Errors name the file, the format and
/// the image's type.
Status WriteImageAtomic(const std::filesystem::path& path, const cv::Mat& image,
                        const std::string& format = ".png", const std::vector<int>& params = {});

/// An OpenCV matrix type in words: "8-bit 3-channel", "16-bit single-channel", ...
std::string DescribeImageType(int type);

}  // namespace cairn::util
