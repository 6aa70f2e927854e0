// Single files in: one frame from a depth image and its camera, a LiDAR scan file, or a
// stereo pair, made into its range image, with what the files gave besides it (the points
// in file order and their layout, the depth, the matching) for the outputs that name them.
// OneFrameSource hands any of them out through the FrameSource interface of the sequences.
//
// Frames as frame.hpp states them: depth and stereo in the camera's optical frame, scans in
// the LiDAR's. Each image is levelled with the up vector the files give (the camera YAML's
// `up`, the caller's for a scan, the stereo calibration's or, without one, a level camera).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/scan_layout.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/sources/frame_source.hpp"

namespace cairn::sources {

struct FileFrame {
  std::string name;                               ///< the file, or "LEFT + RIGHT", for messages
  od::RangeImage image;                           ///< levelled with `up`
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  ///< gravity's up in the sensor frame
  // A depth image or a stereo pair.
  od::Grid<float> depth_m;  ///< z-depth [m], 0 = no return
  od::PinholeModel model;   ///< the (rectified left) camera
  // A scan.
  od::PointCloud cloud;    ///< as read, in file order
  od::FoundLayout layout;  ///< each point's ring and column, and where they came from
  // A stereo pair.
  std::optional<od::StereoPair> pair;     ///< rectified
  std::optional<od::StereoDepth> stereo;  ///< the matching: disparity, holes, sigma
  bool rectified_here = false;            ///< the calibration was of raw cameras
  bool up_given = true;     ///< false: the calibration gave no up, the camera is level
  double matching_s = 0.0;  ///< the time the matching took [s]
};

/// A 16-bit PNG or 32-bit float TIFF z-depth image with its camera YAML (od::io readers).
/// Errors name the file.
Expected<FileFrame> ReadDepthFrame(const std::string& depth, const std::string& intrinsics);

/// A scan file (KITTI .bin, PLY, text; od::io::ReadPointFile) placed by od::PlaceScan with
/// `layout` and levelled with `up` (LiDAR frame). Errors name the file.
Expected<FileFrame> ReadScanFrame(const std::string& points, const od::LayoutOptions& layout,
                                  const Eigen::Vector3d& up);

/// A stereo pair (any image format OpenCV reads) with its rig's calibration (any format
/// od::io::LoadStereoCalibration reads; raw pairs are rectified), matched with `stereo`.
/// Errors name the file; a failed matching names the calibration and `settings_name` (where
/// `stereo` came from).
Expected<FileFrame> ReadStereoFrame(const std::string& left, const std::string& right,
                                    const std::string& calibration, const od::StereoConfig& stereo,
                                    const std::string& settings_name);

/// `frame` as a source of one frame (index 0, stamp 0), placed so that its up vector is the
/// world's z. Fails when the up vector is zero or not finite.
Expected<std::unique_ptr<FrameSource>> OneFrameSource(FileFrame frame);

}  // namespace cairn::sources
