// Stereo pairs in, z-depth out: a calibrated rig, rectification of raw pairs, semi-global
// matching (OpenCV's StereoSGBM) and depth with its uncertainty. An algorithm of its own
// target, cairn::stereo (OpenCV's calib3d); the calibration files and the image files are
// read and written by cairn::od_io (cairn/od/io/stereo_files.hpp).
//
// Frames and units: the rectified left camera's optical frame (x right, y down, z forward)
// is the frame of every depth; the right camera sits baseline_m along its +x axis, so a
// point at z-depth z [m] appears d = fx * baseline / z pixels further left in the right
// image than in the left (d > 0). Disparities are in pixels of the rectified images.
//
// Holes are never ranges: a pixel the matcher cannot vouch for (no unique match, left-right
// inconsistent, a speckle, too little texture in its matching window, outside the depth
// range) has depth 0, sigma 0 and disparity 0, and its reason is recorded.
//
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::od {

/// 8-bit grey image, row-major.
using GreyImage = Grid<std::uint8_t>;

/// How raw (unrectified) images become the rectified pair of a StereoCalibration: the
/// two cameras as calibrated and cv::stereoRectify's result.
struct StereoRectification {
  int raw_width = 0;                                 ///< [px] of the raw images
  int raw_height = 0;                                ///< [px]
  Eigen::Matrix3d K1 = Eigen::Matrix3d::Identity();  ///< raw left intrinsics [px]
  Eigen::Matrix3d K2 = Eigen::Matrix3d::Identity();  ///< raw right intrinsics [px]
  std::vector<double> D1, D2;  ///< OpenCV distortion coefficients (k1 k2 p1 p2 [k3 ...])
  Eigen::Matrix3d R1 = Eigen::Matrix3d::Identity();  ///< rectified left from raw left
  Eigen::Matrix3d R2 = Eigen::Matrix3d::Identity();  ///< rectified right from raw right
  Eigen::Matrix3d P1 = Eigen::Matrix3d::Identity();  ///< rectified left intrinsics [px]
  Eigen::Matrix3d P2 = Eigen::Matrix3d::Identity();  ///< rectified right intrinsics [px]
};

/// A rectified stereo rig: the left camera and the baseline, all depth needs. Constructible
/// directly as StereoCalibration{model, baseline_m} (e.g. from an MRPT stereo observation).
struct StereoCalibration {
  StereoCalibration() = default;
  StereoCalibration(const PinholeModel& rectified_left, double baseline,
                    std::optional<Eigen::Vector3d> up_optical = std::nullopt)
      : model(rectified_left), baseline_m(baseline), up(std::move(up_optical)) {}

  /// The rectified left camera. width and height are 0 when the file gave no size (K.txt);
  /// PrepareStereoPair then takes them from the images.
  PinholeModel model;
  double baseline_m = 0.0;  ///< distance between the optical centres along x [m], > 0
  /// Gravity's up vector in the left optical frame (unit), when the file gives it.
  std::optional<Eigen::Vector3d> up;
  /// Present when the calibration is of raw cameras (OpenCV files): the images given to
  /// PrepareStereoPair are raw and get rectified.
  std::optional<StereoRectification> rectification;

  /// fx * baseline [px m]: disparity d [px] <-> depth z [m] by z = fx_baseline() / d.
  double fx_baseline() const { return model.fx * baseline_m; }
};

/// A rectified pair with the calibration that belongs to it (size known, no rectification).
struct StereoPair {
  GreyImage left;
  GreyImage right;
  StereoCalibration calibration;
};

/// Checks the pair against the calibration and rectifies raw images when the calibration
/// says so. Fails when the two images differ in size, or differ from the calibration's
/// (rectified or raw) size; `left_name` and `right_name` name the images in messages.
Expected<StereoPair> PrepareStereoPair(GreyImage left, GreyImage right,
                                       const StereoCalibration& calibration,
                                       const std::string& left_name = "left image",
                                       const std::string& right_name = "right image");

/// OpenCV's semi-global matching variants (cv::StereoSGBM modes).
enum class StereoMode {
  kSgbm,      ///< 5 directions, one pass (OpenCV's default)
  kSgbm3Way,  ///< faster 3-way variant, the default: on Middlebury Aloe 6.6% of the matches
              ///< off by > 1 px against 7.6% for kSgbm (texture test off), in 2/3 the time
  kHh,        ///< full 8-direction Hirschmueller, more memory
  kHh4,       ///< 4 directions
};
/// "sgbm" | "sgbm_3way" | "hh" | "hh4".
const char* StereoModeName(StereoMode mode);

/// The `stereo:` section of the settings YAML (see config/default.yaml); file keys are the
/// member names without the unit suffix.
struct StereoConfig {
  /// Closest depth to match [m]: sets the disparity search range when num_disparities is 0
  /// (d_max = fx * baseline / min_depth, rounded up to a multiple of 16). Surfaces nearer
  /// than the range allows are not reliably holes (the matcher may settle on a wrong
  /// disparity inside the range): set it below the nearest surface the camera can see.
  double min_depth_m = 1.0;
  /// Disparity search range [px], a positive multiple of 16; 0 derives it from min_depth.
  int num_disparities = 0;
  /// Farther depths become holes [m]; 0: no limit (every positive disparity).
  double max_depth_m = 0.0;
  int block_size = 5;        ///< matching window side [px], odd, 1..31
  int p1 = 0;                ///< SGM penalty for 1 px disparity steps; 0: 8 * block_size^2
  int p2 = 0;                ///< SGM penalty for larger steps, > p1; 0: 32 * block_size^2
  int uniqueness = 10;       ///< best cost must beat the second best by this [%], 0..100
  int speckle_window = 100;  ///< disparity blobs of fewer pixels become holes [px]; 0: off
  int speckle_range = 2;     ///< disparity spread within one blob [px], >= 0
  int disp12_max_diff = 1;   ///< left-right check tolerance [px]; < 0 disables the check
  int pre_filter_cap = 63;   ///< clip of the x-derivative pre-filter, 1..63
  StereoMode mode = StereoMode::kSgbm3Way;
  /// Least mean absolute horizontal intensity gradient, (I(x+1) - I(x-1)) / 2, over the
  /// matching window [grey levels per px]; pixels below are holes (matching needs texture
  /// along x). It must clear the image noise: pure noise of sigma s grey levels averages
  /// 0.56 s and reaches 1.1 s in a 5x5 window somewhere in a VGA frame. 0: off.
  double min_texture = 1.5;
  /// Disparity noise sigma_d [px] for the depth uncertainty sigma_z = z^2 / (fx B) sigma_d.
  double disparity_sigma_px = 0.25;

  /// Names the first bad field by its member name.
  Status Validate() const;
  /// The search range for a rig with fx * baseline = `fx_baseline` [px m] and images
  /// `width` px wide: num_disparities, or the one derived from min_depth. Fails when it
  /// would not leave a column to match.
  Expected<int> NumDisparities(double fx_baseline, int width) const;
};

/// Why a pixel has no depth.
enum class StereoHole : std::uint8_t {
  kNone = 0,        ///< valid
  kNoMatch = 1,     ///< the matcher found no unique, left-right consistent, non-speckle match
  kLowTexture = 2,  ///< too little horizontal gradient in the matching window
  kOutOfRange = 3,  ///< disparity <= 0, or depth beyond max_depth
};

struct StereoHoleCounts {
  int no_match = 0;
  int low_texture = 0;
  int out_of_range = 0;
  int total() const { return no_match + low_texture + out_of_range; }
};

/// Disparity of the left image [px, sub-pixel to 1/16], 0 at holes.
struct StereoDisparity {
  Grid<float> disparity_px;
  Grid<std::uint8_t> hole;  ///< StereoHole per pixel
  StereoHoleCounts holes;
  int num_disparities = 0;  ///< search range used [px]
  /// Share of the matched pixels whose disparity lies in the last eighth of the search
  /// range. Surfaces nearer than the range allows pile up there (the matcher's cost keeps
  /// falling towards the true disparity beyond the range): a large share says the range is
  /// too short for the scene (lower min_depth), not that the scene is that near.
  double range_end_fraction = 0.0;
  /// range_end_fraction above which the range is likely too short for the scene.
  static constexpr double kRangeEndWarning = 0.15;
  bool range_too_short() const { return range_end_fraction > kRangeEndWarning; }
};

/// Semi-global matching of a rectified pair (same size, grey), searching disparities
/// 0 .. num_disparities - 1 (a positive multiple of 16 below the width). Every invalid
/// or low-texture pixel is a hole.
Expected<StereoDisparity> ComputeDisparity(const GreyImage& left, const GreyImage& right,
                                           const StereoConfig& config, int num_disparities);

/// Depth of the left image of a rectified pair.
struct StereoDepth {
  Grid<float> depth_m;  ///< z-depth [m]; 0 = hole
  Grid<float> sigma_m;  ///< depth standard deviation z^2 / (fx B) * sigma_d [m]; 0 at holes
  StereoDisparity disparity;
  double hole_fraction() const {
    return depth_m.data.empty() ? 0.0
                                : static_cast<double>(disparity.holes.total()) / depth_m.size();
  }
};

/// Disparity, then z = fx B / d and its sigma. Fails on a bad config or calibration.
Expected<StereoDepth> ComputeStereoDepth(const StereoPair& pair, const StereoConfig& config);

}  // namespace cairn::od
