// KITTI odometry sequences at the edge: a folder with velodyne/NNNNNN.bin scans,
// calib.txt, times.txt and (for the training sequences) poses.txt.
//
// Frames and conventions, as the KITTI odometry devkit's readme states them:
//  - cam0: the left grey camera, x right, y down, z forward; velodyne: x forward, y left,
//    z up. `Tr` in calib.txt is T_cam0_velodyne (maps velodyne points into cam0).
//  - poses.txt line k: the 3x4 [R | t] of cam0 at frame k in cam0 of frame 0, row-major,
//    i.e. T_cam0start_cam0(k). The velodyne's pose in the same frame is Pose * Tr.
//  - A map frame with z up (as cairn's world frame) is the velodyne frame of frame 0:
//    T_map_velodyne(k) = Tr^-1 * Pose(k) * Tr.
// Readers name the file, the line and the key in every error.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::od::io {

/// calib.txt: "KEY: v1 ... v12" lines, each a row-major 3x4 matrix.
struct KittiCalibration {
  /// P0..P3: rectified projections of cameras 0..3 (cam0 rectified frame -> pixels) [px].
  std::array<Eigen::Matrix<double, 3, 4>, 4> P;
  /// Tr: velodyne -> cam0, as stored (its rotation is orthonormal to the file's precision).
  Eigen::Isometry3d T_cam0_velodyne = Eigen::Isometry3d::Identity();
};

/// Reads calib.txt. Fails, naming the file and the key, when P0, P1, P2, P3 or Tr is missing
/// or does not hold 12 numbers, on a line that is not "KEY: numbers", or when Tr's rotation
/// is not orthonormal (to 1e-3). Other keys (Tr_imu_velo in raw recordings) are ignored.
Expected<KittiCalibration> ReadKittiCalibration(const std::filesystem::path& path);

/// Reads poses.txt: one row-major 3x4 [R | t] per line, T_cam0start_cam0 of each frame
/// [m]. Fails, naming the file and line, on a line without exactly 12 numbers or a
/// rotation that is not orthonormal (to 1e-3), and on no poses.
Expected<std::vector<Eigen::Isometry3d>> ReadKittiPoses(const std::filesystem::path& path);

/// Reads times.txt: one time stamp per line [s] from the start of the sequence. Fails,
/// naming the file and line, on a line that is not one finite number, on a stamp earlier
/// than the one before it, and on no stamps.
Expected<std::vector<double>> ReadKittiTimes(const std::filesystem::path& path);

/// One scan of a sequence.
struct KittiFrame {
  int index = 0;               ///< the scan's number (its file name)
  double stamp_s = 0.0;        ///< times.txt [s]
  std::filesystem::path scan;  ///< velodyne/NNNNNN.bin
  /// From poses.txt when the sequence has one: cam0's pose in cam0 of frame 0 (the file's
  /// line), the velodyne's in the same frame (Pose * Tr), and the velodyne's in the z-up
  /// map frame (velodyne of frame 0: Tr^-1 * Pose * Tr).
  std::optional<Eigen::Isometry3d> T_cam0start_cam0;
  std::optional<Eigen::Isometry3d> T_cam0start_velodyne;
  std::optional<Eigen::Isometry3d> T_map_velodyne;
};

/// A sequence folder.
struct KittiSequence {
  std::filesystem::path folder;
  KittiCalibration calibration;
  std::vector<KittiFrame> frames;  ///< every velodyne/NNNNNN.bin, by index
  bool has_poses = false;          ///< poses.txt present
};

/// Opens a sequence folder: lists velodyne/*.bin (six-digit names) and reads calib.txt and
/// times.txt (both required) and poses.txt (optional: test sequences have none). Fails,
/// naming the file, when the folder or velodyne/ is missing or has no scans, when a scan's
/// name is not a number, or when times.txt or poses.txt has fewer lines than the highest
/// scan index needs.
Expected<KittiSequence> OpenKittiSequence(const std::filesystem::path& folder);

/// "A:B" (inclusive, either side may be empty: "5:", ":3") or "A" -> the frames of
/// `sequence` whose index lies in the range. Fails on bad syntax, A > B, or no frame in it.
Expected<std::vector<KittiFrame>> SelectKittiFrames(const KittiSequence& sequence,
                                                    const std::string& range);

}  // namespace cairn::od::io
