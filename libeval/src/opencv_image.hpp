// What the figure makers of cairn::eval share to draw with OpenCV: the font of every
// label and the way from an OpenCV BGR image to the RGB image od_io writes.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "cairn/od/io/detection_files.hpp"

namespace cairn::eval::detail {

inline constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

/// An 8-bit, 3-channel BGR image as RGB.
inline od::io::RgbImage FromMat(const cv::Mat& bgr) {
  od::io::RgbImage out{bgr.cols, bgr.rows, {}};
  out.data.reserve(static_cast<std::size_t>(bgr.cols) * bgr.rows);
  for (int r = 0; r < bgr.rows; ++r) {
    const auto* row = bgr.ptr<cv::Vec3b>(r);
    for (int c = 0; c < bgr.cols; ++c) out.data.push_back({row[c][2], row[c][1], row[c][0]});
  }
  return out;
}

}  // namespace cairn::eval::detail
