// Internal to the `cairn detect` subcommand: its options and the steps every input shares.
// Each input lives in its own file (detect.cpp: depth PNG/TIFF and point files;
// detect_rawlog.cpp: MRPT rawlogs; detect_stereo.cpp: stereo pairs; detect_kitti.cpp: KITTI
// sequence folders) and reports through the same helpers.
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <string>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detect_config.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sources/file_frame.hpp"

namespace cairn::apps {

struct DetectOptions {
  // One depth frame.
  std::string depth;       ///< 16-bit PNG or 32-bit float TIFF z-depth
  std::string intrinsics;  ///< camera YAML
  // One LiDAR scan.
  std::string points;  ///< KITTI-layout .bin (instead of --depth)
  std::string sensor;  ///< SphericalModel preset name; empty: rings found from the data
  std::string organised = "auto";
  int columns = 0;  ///< azimuth steps of an unorganised scan; 0: the sensor's default
  std::string up = "0,0,1";
  // An MRPT rawlog: every range observation (3-D range scan, point cloud, Velodyne scan,
  // stereo pair) of the selected sensor label.
  std::string rawlog;
  std::string label;      ///< sensor label to select; empty: every range sensor
  std::string annotated;  ///< annotated copy of the rawlog to write; empty: none
  int max_frames = 0;     ///< 0: all
  // A rectified stereo pair.
  std::string left, right;
  std::string stereo_calib;  ///< fx, cx, cy, baseline YAML or an OpenCV stereo calibration
  // A KITTI odometry sequence folder (velodyne/, calib.txt, poses.txt, times.txt).
  std::string kitti;
  std::string frames;  ///< "A:B" (inclusive), empty: all
  // Shared.
  std::string config;  ///< empty: built-in defaults
  std::string method = "cone";
  bool no_rules = false;
  bool no_feet = false;  ///< obstacle points that are not raised count as ground (WithoutFeet)
  std::string out;
};

using DetectClock = std::chrono::steady_clock;

double MillisecondsSince(DetectClock::time_point start);

/// Prints "cairn detect: error: <message>" on stderr and returns kExitFailure.
int DetectFail(const std::string& message);

/// A settings file's detection sections (detect_config.hpp); the Mapper's sections of the
/// same file are left to its loader.
Expected<od::io::DetectSettings> LoadDetectSettingsFile(const std::string& path);

/// The settings file of --config, or the built-in defaults.
Expected<od::io::DetectSettings> LoadDetectSettingsOrDefaults(const DetectOptions& options);

/// "x,y,z" -> a non-zero finite vector.
Expected<Eigen::Vector3d> ParseUpVector(const std::string& text);

/// The chosen method and the rules (or none) on one range image.
struct DetectResult {
  od::Detection detection;
  od::Classification classification;
  double detect_ms = 0.0;
};
Expected<DetectResult> DetectAndClassify(const od::RangeImage& image,
                                         const od::io::DetectSettings& settings,
                                         const DetectOptions& options);

/// How a scan's points are placed (--sensor, --organised, --columns of `options`).
Expected<od::LayoutOptions> ScanLayoutOptions(const DetectOptions& options);

/// The one scan (--points, --up and the layout options above) or the one depth image
/// (--depth, --intrinsics) of `options`, read by cairn::sources (file_frame.hpp).
Expected<sources::FileFrame> ReadScanInput(const DetectOptions& options);
Expected<sources::FileFrame> ReadDepthInput(const DetectOptions& options);

// The inputs that live in their own files (each present when its library is built).
int RunDetectRawlog(const DetectOptions& options);  // detect_rawlog.cpp, CAIRN_HAVE_SOURCES
int RunDetectStereo(const DetectOptions& options);  // detect_stereo.cpp, CAIRN_HAVE_STEREO
int RunDetectKitti(const DetectOptions& options);   // detect_kitti.cpp, CAIRN_HAVE_KITTI

}  // namespace cairn::apps
