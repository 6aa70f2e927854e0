// Stereo files: rig calibrations in, grey images in and out, disparities out. The matching
// itself is cairn::stereo (cairn/od/stereo.hpp).
//
// Calibration files (LoadStereoCalibration tells them apart by their content):
//  * cairn's stereo YAML, for images that are already rectified (any other key is an error):
//      width: 960            # [px] of the rectified images
//      height: 540
//      fx: 754.668           # [px]
//      fy: 754.668           # optional, fx when absent (rectified pixels are square)
//      cx: 489.379           # principal point [px], pixel centres at integer coordinates
//      cy: 265.162
//      baseline: 0.063       # distance between the optical centres [m], > 0
//      up: [0, -1, 0]        # optional: gravity's up in the left optical frame, or
//      pitch_deg: 10         #   optional instead: axis below the horizontal positive [deg]
//      roll_deg: 0           #   optional with pitch_deg [deg]
//  * FoundationStereo's K.txt: line 1 the 9 numbers of the left 3x3 intrinsic matrix
//    (row-major), line 2 the baseline [m]. It gives no image size (taken from the images).
//  * An OpenCV stereo calibration (cv::FileStorage YAML or XML, as cv::stereoCalibrate
//    gives it): M1, D1 (left intrinsics and distortion), M2, D2 (right), R, T (right camera
//    from left: p_right = R p_left + T, T in metres), and the raw image size as image_width
//    and image_height, or image_size: [width, height]. Raw images are rectified with
//    cv::stereoRectify (alpha 0: every rectified pixel is seen by both cameras) and
//    initUndistortRectifyMap / remap.
#pragma once

#include <filesystem>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/stereo.hpp"

namespace cairn::od::io {

/// Reads any of the three calibration formats above, telling them apart by content.
/// Errors name the file and the missing or bad field.
Expected<StereoCalibration> LoadStereoCalibration(const std::filesystem::path& path);
/// cairn's stereo YAML from text; `source` names it in messages.
Expected<StereoCalibration> ParseStereoCalibrationYaml(const std::string& yaml_text,
                                                       const std::string& source);
/// FoundationStereo's K.txt from text (no image size: model.width = height = 0).
Expected<StereoCalibration> ParseFoundationStereoK(const std::string& text,
                                                   const std::string& source);
/// An OpenCV stereo calibration (cv::FileStorage YAML or XML text), rectified.
Expected<StereoCalibration> ParseOpenCvStereoCalibration(const std::string& text,
                                                         const std::string& source);

/// Reads an image in any format OpenCV decodes (PNG, JPEG, TIFF, ...) as 8-bit grey:
/// colour is converted to luma, 16-bit is scaled by 1/256. Errors name the file.
Expected<GreyImage> ReadGreyImage(const std::filesystem::path& path);
/// Writes an 8-bit grey PNG atomically.
Status WriteGreyPng(const std::filesystem::path& path, const GreyImage& image);

/// Disparity as a 16-bit PNG in the KITTI convention: value = round(d * 256), 0 = hole.
Status WriteDisparityPng(const std::filesystem::path& path, const Grid<float>& disparity_px);
/// Disparity for people: colour map (OpenCV's turbo) from 0 to `max_disparity_px`, holes
/// black.
Status WriteDisparityColorPng(const std::filesystem::path& path, const Grid<float>& disparity_px,
                              double max_disparity_px);

}  // namespace cairn::od::io
