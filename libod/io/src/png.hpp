// PNG decoding through OpenCV, with errors that name the file (writing is
// util::WriteImageAtomic). Internal to
// cairn_od_io: OpenCV stays out of the public headers.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>

#include "cairn/od/expected.hpp"

namespace cairn::od::io::detail {

/// Reads a PNG as stored (no depth or channel conversion). Fails when the file is missing,
/// is not a PNG, cannot be decoded, or is not of `expected_type` (`expected` describes it,
/// e.g. "16-bit single-channel").
Expected<cv::Mat> ReadPng(const std::filesystem::path& path, int expected_type,
                          const char* expected);

}  // namespace cairn::od::io::detail
