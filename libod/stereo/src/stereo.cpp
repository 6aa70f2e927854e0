#include "cairn/od/stereo.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/image_file.hpp"

namespace cairn::od {
namespace {

cv::Mat ToCv(const Eigen::Matrix3d& e) {
  cv::Mat m(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = e(r, c);
  }
  return m;
}

std::string SizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

int OpenCvMode(StereoMode mode) {
  switch (mode) {
    case StereoMode::kSgbm:
      return cv::StereoSGBM::MODE_SGBM;
    case StereoMode::kSgbm3Way:
      return cv::StereoSGBM::MODE_SGBM_3WAY;
    case StereoMode::kHh:
      return cv::StereoSGBM::MODE_HH;
    case StereoMode::kHh4:
      return cv::StereoSGBM::MODE_HH4;
  }
  return cv::StereoSGBM::MODE_SGBM;
}

}  // namespace

Expected<StereoPair> PrepareStereoPair(GreyImage left, GreyImage right,
                                       const StereoCalibration& calibration,
                                       const std::string& left_name,
                                       const std::string& right_name) {
  if (!left.well_formed()) return Error{left_name + ": malformed image"};
  if (!right.well_formed()) return Error{right_name + ": malformed image"};
  if (left.width != right.width || left.height != right.height) {
    return Error{right_name + ": is " + SizeText(right.width, right.height) +
                 " px, the left image " + left_name + " is " + SizeText(left.width, left.height)};
  }
  if (!(calibration.baseline_m > 0.0) || !std::isfinite(calibration.baseline_m)) {
    return Error{"stereo calibration: baseline must be positive [m], got " +
                 util::Number(calibration.baseline_m)};
  }
  StereoPair pair;
  pair.calibration = calibration;
  if (!calibration.rectification) {
    PinholeModel& m = pair.calibration.model;
    if (m.width == 0 && m.height == 0) {  // the calibration leaves the size to the images
      m.width = left.width;
      m.height = left.height;
    } else if (m.width != left.width || m.height != left.height) {
      return Error{left_name + ": is " + SizeText(left.width, left.height) +
                   " px, the stereo calibration says " + SizeText(m.width, m.height)};
    }
    if (Status s = m.Validate(); !s) return Error{"stereo calibration: " + s.message()};
    pair.left = std::move(left);
    pair.right = std::move(right);
    return pair;
  }
  const StereoRectification& rect = *calibration.rectification;
  if (rect.raw_width != left.width || rect.raw_height != left.height) {
    return Error{left_name + ": is " + SizeText(left.width, left.height) +
                 " px, the stereo calibration's raw images are " +
                 SizeText(rect.raw_width, rect.raw_height)};
  }
  const cv::Size size(rect.raw_width, rect.raw_height);
  cv::Mat rectified[2];
  try {
    const GreyImage* raw[2] = {&left, &right};
    const Eigen::Matrix3d* K[2] = {&rect.K1, &rect.K2};
    const std::vector<double>* D[2] = {&rect.D1, &rect.D2};
    const Eigen::Matrix3d* R[2] = {&rect.R1, &rect.R2};
    const Eigen::Matrix3d* P[2] = {&rect.P1, &rect.P2};
    for (int i = 0; i < 2; ++i) {
      cv::Mat map_x, map_y;
      cv::initUndistortRectifyMap(ToCv(*K[i]), cv::Mat(*D[i]), ToCv(*R[i]), ToCv(*P[i]), size,
                                  CV_32FC1, map_x, map_y);
      cv::remap(util::GreyMatView(*raw[i]), rectified[i], map_x, map_y, cv::INTER_LINEAR,
                cv::BORDER_CONSTANT, cv::Scalar(0));
    }
  } catch (const cv::Exception& e) {
    return Error{"stereo rectification failed: " + e.err};
  }
  pair.left = util::GreyGridOf(rectified[0]);
  pair.right = util::GreyGridOf(rectified[1]);
  pair.calibration.rectification.reset();
  return pair;
}

// -----------------------------------------------------------------------------------------
// Matching

const char* StereoModeName(StereoMode mode) {
  switch (mode) {
    case StereoMode::kSgbm:
      return "sgbm";
    case StereoMode::kSgbm3Way:
      return "sgbm_3way";
    case StereoMode::kHh:
      return "hh";
    case StereoMode::kHh4:
      return "hh4";
  }
  return "unknown";
}

Status StereoConfig::Validate() const {
  auto bad = [](const char* field, const std::string& expected) {
    return Error{std::string("stereo config: ") + field + " must be " + expected};
  };
  if (!std::isfinite(min_depth_m) || min_depth_m <= 0.0) {
    return bad("min_depth_m", "a positive depth [m]");
  }
  if (num_disparities < 0 || num_disparities % 16 != 0) {
    return bad("num_disparities", "0 (from min_depth) or a positive multiple of 16 [px]");
  }
  if (!std::isfinite(max_depth_m) || max_depth_m < 0.0) {
    return bad("max_depth_m", "0 (no limit) or a positive depth [m]");
  }
  if (max_depth_m > 0.0 && max_depth_m <= min_depth_m) {
    return bad("max_depth_m", "0 or more than min_depth_m");
  }
  if (block_size < 1 || block_size > 31 || block_size % 2 == 0) {
    return bad("block_size", "odd, 1..31 [px]");
  }
  if (p1 < 0) return bad("p1", "0 (8 * block_size^2) or positive");
  if (p2 < 0) return bad("p2", "0 (32 * block_size^2) or positive");
  const int eff_p1 = p1 > 0 ? p1 : 8 * block_size * block_size;
  const int eff_p2 = p2 > 0 ? p2 : 32 * block_size * block_size;
  if (eff_p2 <= eff_p1) {
    return bad("p2",
               "greater than p1 (" + std::to_string(eff_p1) + "), got " + std::to_string(eff_p2));
  }
  if (uniqueness < 0 || uniqueness > 100) return bad("uniqueness", "0..100 [%]");
  if (speckle_window < 0) return bad("speckle_window", "0 (off) or a positive pixel count");
  if (speckle_range < 0) return bad("speckle_range", ">= 0 [px]");
  if (pre_filter_cap < 1 || pre_filter_cap > 63) return bad("pre_filter_cap", "1..63");
  if (!std::isfinite(min_texture) || min_texture < 0.0) {
    return bad("min_texture", ">= 0 [grey levels per px]");
  }
  if (!std::isfinite(disparity_sigma_px) || disparity_sigma_px <= 0.0) {
    return bad("disparity_sigma_px", "a positive disparity noise [px]");
  }
  return Status::Ok();
}

Expected<int> StereoConfig::NumDisparities(double fx_baseline, int width) const {
  if (Status s = Validate(); !s) return s.error();
  int n = num_disparities;
  if (n == 0) {
    if (!(fx_baseline > 0.0) || !std::isfinite(fx_baseline)) {
      return Error{"stereo config: fx * baseline must be positive to derive num_disparities"};
    }
    const double d_max = fx_baseline / min_depth_m;
    n = 16 * static_cast<int>(std::ceil(std::min(d_max, 1e6) / 16.0));
    n = std::max(n, 16);
    if (n >= width) {
      return Error{"stereo config: min_depth_m " + util::Number(min_depth_m) +
                   " m needs disparities up to " + util::Number(d_max) +
                   " px, more than the image's " + std::to_string(width) +
                   " columns allow; raise min_depth (stereo.min_depth in the settings)"};
    }
  } else if (n >= width) {
    return Error{"stereo config: num_disparities " + std::to_string(n) + " must be less than the " +
                 "image width " + std::to_string(width)};
  }
  return n;
}

namespace {

/// StereoDisparity::range_end_fraction of the pixels that are no hole.
double RangeEndFraction(const StereoDisparity& d) {
  const float range_end = 0.875f * static_cast<float>(d.num_disparities);
  std::size_t matched = 0, at_end = 0;
  for (std::size_t i = 0; i < d.disparity_px.data.size(); ++i) {
    if (d.hole.data[i] != static_cast<std::uint8_t>(StereoHole::kNone)) continue;
    ++matched;
    at_end += d.disparity_px.data[i] >= range_end ? 1 : 0;
  }
  return matched > 0 ? static_cast<double>(at_end) / matched : 0.0;
}

}  // namespace

Expected<StereoDisparity> ComputeDisparity(const GreyImage& left, const GreyImage& right,
                                           const StereoConfig& config, int num_disparities) {
  if (Status s = config.Validate(); !s) return s.error();
  if (!left.well_formed() || !right.well_formed()) return Error{"stereo: malformed image"};
  if (left.width != right.width || left.height != right.height) {
    return Error{"stereo: the images differ in size: " + SizeText(left.width, left.height) +
                 " and " + SizeText(right.width, right.height)};
  }
  if (num_disparities < 16 || num_disparities % 16 != 0 || num_disparities >= left.width) {
    return Error{"stereo: num_disparities must be a positive multiple of 16 below the width " +
                 std::to_string(left.width) + ", got " + std::to_string(num_disparities)};
  }
  const int b = config.block_size;
  const int p1 = config.p1 > 0 ? config.p1 : 8 * b * b;
  const int p2 = config.p2 > 0 ? config.p2 : 32 * b * b;
  cv::Mat disparity_fixed;  // CV_16S, 1/16 px; invalid = -16 (minDisparity - 1, times 16)
  try {
    cv::Ptr<cv::StereoSGBM> matcher = cv::StereoSGBM::create(
        0, num_disparities, b, p1, p2, config.disp12_max_diff, config.pre_filter_cap,
        config.uniqueness, config.speckle_window, config.speckle_range, OpenCvMode(config.mode));
    matcher->compute(util::GreyMatView(left), util::GreyMatView(right), disparity_fixed);
  } catch (const cv::Exception& e) {
    return Error{std::string("stereo: semi-global matching failed: ") + e.err};
  }

  // Texture along x in each matching window: the mean |dI/dx| (central difference).
  cv::Mat texture;
  if (config.min_texture > 0.0) {
    cv::Mat gradient;
    cv::Sobel(util::GreyMatView(left), gradient, CV_32F, 1, 0, 1, 0.5, 0.0, cv::BORDER_REPLICATE);
    gradient = cv::abs(gradient);
    cv::boxFilter(gradient, texture, CV_32F, cv::Size(b, b), cv::Point(-1, -1), true,
                  cv::BORDER_REPLICATE);
  }

  StereoDisparity out;
  out.num_disparities = num_disparities;
  out.disparity_px = Grid<float>{left.width, left.height, {}};
  out.disparity_px.data.assign(left.data.size(), 0.0f);
  out.hole = Grid<std::uint8_t>{left.width, left.height, {}};
  out.hole.data.assign(left.data.size(), static_cast<std::uint8_t>(StereoHole::kNone));
  for (int r = 0; r < left.height; ++r) {
    const std::int16_t* d_row = disparity_fixed.ptr<std::int16_t>(r);
    const float* t_row = texture.empty() ? nullptr : texture.ptr<float>(r);
    for (int c = 0; c < left.width; ++c) {
      StereoHole reason = StereoHole::kNone;
      if (d_row[c] < 0) {
        reason = StereoHole::kNoMatch;
      } else if (t_row != nullptr && t_row[c] < config.min_texture) {
        reason = StereoHole::kLowTexture;
      } else if (d_row[c] == 0) {
        reason = StereoHole::kOutOfRange;
      }
      switch (reason) {
        case StereoHole::kNone:
          out.disparity_px.at(r, c) = static_cast<float>(d_row[c]) / 16.0f;
          continue;
        case StereoHole::kNoMatch:
          ++out.holes.no_match;
          break;
        case StereoHole::kLowTexture:
          ++out.holes.low_texture;
          break;
        case StereoHole::kOutOfRange:
          ++out.holes.out_of_range;
          break;
      }
      out.hole.at(r, c) = static_cast<std::uint8_t>(reason);
    }
  }
  out.range_end_fraction = RangeEndFraction(out);
  return out;
}

Expected<StereoDepth> ComputeStereoDepth(const StereoPair& pair, const StereoConfig& config) {
  const StereoCalibration& calib = pair.calibration;
  if (Status s = calib.model.Validate(); !s) return Error{"stereo calibration: " + s.message()};
  if (!(calib.baseline_m > 0.0) || !std::isfinite(calib.baseline_m)) {
    return Error{"stereo calibration: baseline must be positive [m], got " +
                 util::Number(calib.baseline_m)};
  }
  if (calib.rectification) {
    return Error{"stereo: the pair is not rectified yet (PrepareStereoPair rectifies it)"};
  }
  if (pair.left.width != calib.model.width || pair.left.height != calib.model.height) {
    return Error{"stereo: images are " + SizeText(pair.left.width, pair.left.height) +
                 " px, the calibration says " + SizeText(calib.model.width, calib.model.height)};
  }
  const double fb = calib.fx_baseline();
  Expected<int> n = config.NumDisparities(fb, pair.left.width);
  if (!n) return n.error();
  Expected<StereoDisparity> disparity = ComputeDisparity(pair.left, pair.right, config, *n);
  if (!disparity) return disparity.error();

  StereoDepth out;
  out.depth_m = Grid<float>{pair.left.width, pair.left.height, {}};
  out.depth_m.data.assign(pair.left.data.size(), 0.0f);
  out.sigma_m = out.depth_m;
  StereoDisparity& d = *disparity;
  for (std::size_t i = 0; i < d.disparity_px.data.size(); ++i) {
    const double disp = d.disparity_px.data[i];
    if (!(disp > 0.0)) continue;
    const double z = fb / disp;
    if (config.max_depth_m > 0.0 && z > config.max_depth_m) {
      d.disparity_px.data[i] = 0.0f;
      d.hole.data[i] = static_cast<std::uint8_t>(StereoHole::kOutOfRange);
      ++d.holes.out_of_range;
      continue;
    }
    out.depth_m.data[i] = static_cast<float>(z);
    out.sigma_m.data[i] = static_cast<float>(z * z / fb * config.disparity_sigma_px);
  }
  d.range_end_fraction = RangeEndFraction(d);  // over the pixels max_depth left matched
  out.disparity = std::move(d);
  return out;
}

}  // namespace cairn::od
