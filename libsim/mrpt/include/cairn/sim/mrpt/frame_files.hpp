// Synthetic frames and their ground truth on disk. Every file is written to a temporary
// name in its directory and renamed into place (util::WriteFileAtomic).
//
// A camera frame (what `cairn detect` and `cairn eval` read):
//   depth.png        16-bit z-depth, metres = value * depth_scale, 0 = no return (od::io)
//   intrinsics.yaml  width, height, fx, fy, cx, cy, depth_scale, up (od::io::LoadIntrinsics)
//   truth.png        object id per pixel: 0 terrain, 1..254 objects, 255 no return (8-bit,
//                    as eval::LoadTruth and the demo frame have it); 16-bit with 65535
//                    = no return when some id exceeds 254
//   truth.yaml       objects: - {id, name, is_obstacle, height_m}; every object of the
//                    scene, height_m its top above the ground under its centre
// A LiDAR frame:
//   points.bin       KITTI layout: float32 x, y, z, intensity (0) per return, LiDAR frame
//                    (x forward, y left, z up) [m]
//   labels.label     uint32 per point, in points.bin's order: the object id (0 terrain)
//   rowcol.bin       uint16 ring (0 = top beam), uint16 azimuth column, per point
//   lidar.yaml       preset, azimuth_steps, elevations_deg (ring 0 first), up (gravity's up
//                    vector in the LiDAR frame)
//   truth.yaml       as above
// Pose files (TUM RGB-D format) are written and read by cairn::sources (trajectory.hpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/sim/world.hpp"

namespace cairn::sim {

/// The value of "no return" in a truth image: 255 when every id fits 1..254, else 65535.
int TruthNoHitLabel(const std::vector<std::int32_t>& object_ids);

/// Writes object ids (kTerrainId, object ids, kNoHitId) as truth.png (see above). Fails on
/// an id below -1 or above 65534, or a size mismatch.
Status WriteObjectIdPng(const std::filesystem::path& path, const od::Grid<std::int32_t>& ids);

/// Reads a truth image (8- or 16-bit) back into ids, no return as kNoHitId.
Expected<od::Grid<std::int32_t>> ReadObjectIdPng(const std::filesystem::path& path);

/// truth.yaml for every object of the scene.
Status WriteTruthYaml(const std::filesystem::path& path, const Scene& scene);

/// Metres per 16-bit unit for a depth image whose farthest return is `max_depth_m`: 1 mm,
/// or coarser (in steps of 0.1 mm) when 1 mm cannot reach that far.
double DepthScaleFor(double max_depth_m);

struct CameraFrameFiles {
  std::filesystem::path depth_png, intrinsics_yaml, truth_png, truth_yaml;
  double depth_scale_m = 0.001;
};

/// Writes a rendered camera frame and its truth into `dir` (created when missing).
Expected<CameraFrameFiles> WriteCameraFrame(const std::filesystem::path& dir,
                                            const DepthFrame& frame, const Scene& scene);

struct LidarFrameFiles {
  std::filesystem::path points_bin, labels, rowcol_bin, lidar_yaml, truth_yaml;
};

/// Writes a LiDAR scan and its truth into `dir` (created when missing); `up_lidar` is
/// gravity's up vector in the LiDAR frame.
Expected<LidarFrameFiles> WriteLidarFrame(const std::filesystem::path& dir, const LidarScan& scan,
                                          const LidarSpec& lidar, const Eigen::Vector3d& up_lidar,
                                          const Scene& scene);

/// The scan's points as a KITTI .bin (intensity 0), its object ids as uint32 labels, its
/// rings and columns as uint16 pairs.
Status WriteKittiPoints(const std::filesystem::path& path, const LidarScan& scan);
Status WriteLidarLabels(const std::filesystem::path& path, const LidarScan& scan);
Status WriteLidarRowCol(const std::filesystem::path& path, const LidarScan& scan);

}  // namespace cairn::sim
