// Detections written back into MRPT observations, so that an annotated copy of a rawlog
// carries its obstacles in MRPT's own terms.
//
// Range cameras (CObservation3DRangeScan): pixel labels (TPixelLabelInfo, one bit per label,
// 8 x BYTES labels, BYTES = 1, 2, 4 or 8, the smallest that fits). Labels:
//   bit 0 "obstacle"      every pixel of a kept segment
//   bit 1 "rejected"      every pixel of a segment rejected by the rules
//   bit k "obstacle <id>" / "rejected <id>" (k >= 2) the pixels of segment <id> (the id of
//                         segments.png and segments.json)
// When there are more segments than bits (more than 62), kept segments get their own bits
// first, then rejected ones, each group largest first; the rest carry only bit 0 or 1, and
// segments.png beside the rawlog has every id. Pixels are those of the recorded range image:
// where the decoder removed lens distortion, labels go back through
// DepthImage::decoded_of_source.
//
// LiDARs (CObservationPointCloud, CObservationVelodyneScan, CObservationRotatingScan): MRPT
// 2.5 has no per-point label field, and raw Velodyne packets cannot carry one. The lossless
// choice it offers is CWeightedPointsMap, whose uint32 per point holds the SemanticKITTI word
// that `labels.label` holds (lower 16 bits the class: 0 none, 1 kept, 2 rejected; upper 16
// bits the segment id). So each LiDAR observation is kept unchanged and followed by a
// CObservationPointCloud labelled "<label>_SEGMENTS" (same timestamp and sensorPose) whose
// map holds the decoded points (LiDAR frame, decode order, no-return points included) with
// their words as weights. MRPT's viewers draw these points but not their weights; tools that
// read weights as observation counts would misread them.
#pragma once

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>

#include <cstdint>
#include <string>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/sources/frame.hpp"

namespace cairn::sources {

inline constexpr const char* kSegmentCloudSuffix = "_SEGMENTS";
inline constexpr int kMaxPixelLabelBits = 64;

/// Which segment gets which bit (see the top of this file).
struct PixelLabelPlan {
  int bytes = 1;                                 ///< 1, 2, 4 or 8
  std::vector<std::pair<int, std::string>> bits;  ///< (segment id, name) for bits 2, 3, ...
  int segments_without_bit = 0;
};
PixelLabelPlan PlanPixelLabels(const od::Detection& detection,
                               const od::Classification& classification);

/// Sets `scan`'s pixel labels from a detection made on `decoded` (DecodeRangeScan(scan)).
/// Externally stored range and intensity images are brought inline, so that the scan reads
/// without its original images directory. Fails on size mismatches.
Status LabelRangeScan(::mrpt::obs::CObservation3DRangeScan& scan, const DepthImage& decoded,
                      const od::Detection& detection, const od::Classification& classification);

/// A labelled scan read back: per pixel of its range image (row-major), the class (0 none,
/// 1 kept, 2 rejected) and the segment id when the segment has its own bit (0 otherwise).
struct PixelLabelsRead {
  int width = 0, height = 0;
  std::vector<std::uint8_t> cls;
  std::vector<std::int32_t> segment;
};
/// Fails when the scan has no pixel labels or names them otherwise than LabelRangeScan.
Expected<PixelLabelsRead> ReadPixelLabels(const ::mrpt::obs::CObservation3DRangeScan& scan);

/// The observation to insert after LiDAR observation `source` (see the top of this file):
/// `words` one per point of `scan` (od::io::PointLabels). Fails on a size mismatch.
Expected<::mrpt::obs::CObservationPointCloud::Ptr> MakeSegmentCloud(
    const ::mrpt::obs::CObservation& source, const PointScan& scan,
    const std::vector<std::uint32_t>& words);

}  // namespace cairn::sources
