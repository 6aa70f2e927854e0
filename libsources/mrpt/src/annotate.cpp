#include "cairn/sources/annotate.hpp"

#include <mrpt/maps/CWeightedPointsMap.h>
#include <mrpt/obs/TPixelLabelInfo.h>

#include <algorithm>
#include <map>
#include <opencv2/core.hpp>

#include "cairn/sources/mrpt_convert.hpp"
#include "mrpt_errors.hpp"

namespace cairn::sources {
namespace {

using ::mrpt::obs::CObservation3DRangeScan;
using ::mrpt::obs::TPixelLabelInfoBase;
using od::SegmentClass;

constexpr int kKeptBit = 0;
constexpr int kRejectedBit = 1;
constexpr const char* kKeptName = "obstacle";
constexpr const char* kRejectedName = "rejected";

SegmentClass ClassOf(const od::Classification& classification, int id) {
  if (id <= 0 || id > static_cast<int>(classification.verdicts.size())) return SegmentClass::kKept;
  return classification.verdicts[id - 1].cls;
}

TPixelLabelInfoBase::Ptr NewLabels(int bytes) {
  using ::mrpt::obs::TPixelLabelInfo;
  switch (bytes) {
    case 1: return std::make_shared<TPixelLabelInfo<1>>();
    case 2: return std::make_shared<TPixelLabelInfo<2>>();
    case 4: return std::make_shared<TPixelLabelInfo<4>>();
    default: return std::make_shared<TPixelLabelInfo<8>>();
  }
}

// An externally stored image made inline (loaded, then copied into memory).
void Inline(::mrpt::img::CImage& image) {
  if (!image.isExternallyStored()) return;
  image.forceLoad();
  image = ::mrpt::img::CImage(image.asCvMatRef().clone(), ::mrpt::img::DEEP_COPY);
}

}  // namespace

PixelLabelPlan PlanPixelLabels(const od::Detection& detection,
                               const od::Classification& classification) {
  std::vector<const od::SegmentFeatures*> kept, rejected;
  for (const od::SegmentFeatures& s : detection.segments) {
    (ClassOf(classification, s.id) == SegmentClass::kRejected ? rejected : kept).push_back(&s);
  }
  auto largest_first = [](const od::SegmentFeatures* a, const od::SegmentFeatures* b) {
    return a->point_count != b->point_count ? a->point_count > b->point_count : a->id < b->id;
  };
  std::stable_sort(kept.begin(), kept.end(), largest_first);
  std::stable_sort(rejected.begin(), rejected.end(), largest_first);
  PixelLabelPlan plan;
  const int wanted = 2 + static_cast<int>(detection.segments.size());
  plan.bytes = wanted <= 8 ? 1 : wanted <= 16 ? 2 : wanted <= 32 ? 4 : 8;
  const int capacity = 8 * plan.bytes - 2;
  for (const auto* group : {&kept, &rejected}) {
    const char* name = group == &kept ? kKeptName : kRejectedName;
    for (const od::SegmentFeatures* s : *group) {
      if (static_cast<int>(plan.bits.size()) < capacity) {
        plan.bits.emplace_back(s->id, std::string(name) + " " + std::to_string(s->id));
      } else {
        ++plan.segments_without_bit;
      }
    }
  }
  return plan;
}

Status LabelRangeScan(CObservation3DRangeScan& scan, const DepthImage& decoded,
                      const od::Detection& detection, const od::Classification& classification) {
  const std::string who = "CObservation3DRangeScan '" + scan.sensorLabel + "'";
  try {
    scan.load();
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its externally stored data: " + detail::Describe(e)};
  }
  const int rows = static_cast<int>(scan.rangeImage.rows());
  const int cols = static_cast<int>(scan.rangeImage.cols());
  if (detection.width != decoded.model.width || detection.height != decoded.model.height ||
      rows != decoded.model.height || cols != decoded.model.width ||
      (!decoded.decoded_of_source.empty() &&
       decoded.decoded_of_source.size() != static_cast<std::size_t>(rows) * cols)) {
    return Error{who + ": the detection (" + std::to_string(detection.width) + "x" +
                 std::to_string(detection.height) + ") was not made on this scan's " +
                 std::to_string(cols) + "x" + std::to_string(rows) + " range image"};
  }
  const PixelLabelPlan plan = PlanPixelLabels(detection, classification);
  std::map<int, int> bit_of_segment;
  TPixelLabelInfoBase::Ptr labels = NewLabels(plan.bytes);
  labels->setLabelName(kKeptBit, kKeptName);
  labels->setLabelName(kRejectedBit, kRejectedName);
  for (std::size_t k = 0; k < plan.bits.size(); ++k) {
    const int bit = 2 + static_cast<int>(k);
    bit_of_segment[plan.bits[k].first] = bit;
    labels->setLabelName(bit, plan.bits[k].second);
  }
  labels->setSize(rows, cols);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::size_t source = static_cast<std::size_t>(r) * cols + c;
      const std::int32_t pixel = decoded.decoded_of_source.empty()
                                     ? static_cast<std::int32_t>(source)
                                     : decoded.decoded_of_source[source];
      if (pixel < 0) continue;
      const int id = detection.labels[pixel];
      if (id == 0) continue;
      const bool rejected = ClassOf(classification, id) == SegmentClass::kRejected;
      labels->setLabel(r, c, static_cast<std::uint8_t>(rejected ? kRejectedBit : kKeptBit));
      if (auto it = bit_of_segment.find(id); it != bit_of_segment.end()) {
        labels->setLabel(r, c, static_cast<std::uint8_t>(it->second));
      }
    }
  }
  scan.pixelLabels = labels;
  // Inline storage: the annotated copy is read without the original images directory.
  scan.rangeImage_forceResetExternalStorage();
  if (scan.hasPoints3D && scan.points3D_isExternallyStored()) {
    scan.points3D_overrideExternalStoredFlag(false);
  }
  try {
    if (scan.hasIntensityImage) Inline(scan.intensityImage);
    if (scan.hasConfidenceImage) Inline(scan.confidenceImage);
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its externally stored images: " + detail::Describe(e)};
  }
  return {};
}

Expected<PixelLabelsRead> ReadPixelLabels(const CObservation3DRangeScan& scan) {
  const std::string who = "CObservation3DRangeScan '" + scan.sensorLabel + "'";
  if (!scan.hasPixelLabels()) return Error{who + ": no pixel labels"};
  const TPixelLabelInfoBase& labels = *scan.pixelLabels;
  if (labels.checkLabelNameExistence(kKeptName) != kKeptBit ||
      labels.checkLabelNameExistence(kRejectedName) != kRejectedBit) {
    return Error{who + ": pixel labels 0 and 1 are not named 'obstacle' and 'rejected'"};
  }
  std::map<int, int> segment_of_bit;
  for (const auto& [bit, name] : labels.pixelLabelNames) {
    if (bit < 2) continue;
    const auto space = name.find(' ');
    if (space == std::string::npos) return Error{who + ": pixel label " + std::to_string(bit) + " '" + name + "' names no segment"};
    try {
      segment_of_bit[static_cast<int>(bit)] = std::stoi(name.substr(space + 1));
    } catch (const std::exception&) {
      return Error{who + ": pixel label " + std::to_string(bit) + " '" + name + "' names no segment"};
    }
  }
  PixelLabelsRead out;
  out.height = static_cast<int>(scan.rangeImage.rows());
  out.width = static_cast<int>(scan.rangeImage.cols());
  out.cls.assign(static_cast<std::size_t>(out.width) * out.height, 0);
  out.segment.assign(out.cls.size(), 0);
  for (int r = 0; r < out.height; ++r) {
    for (int c = 0; c < out.width; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * out.width + c;
      if (labels.checkLabel(r, c, kKeptBit)) out.cls[i] = 1;
      if (labels.checkLabel(r, c, kRejectedBit)) out.cls[i] = 2;
      for (const auto& [bit, id] : segment_of_bit) {
        if (labels.checkLabel(r, c, static_cast<std::uint8_t>(bit))) out.segment[i] = id;
      }
    }
  }
  return out;
}

Expected<::mrpt::obs::CObservationPointCloud::Ptr> MakeSegmentCloud(
    const ::mrpt::obs::CObservation& source, const PointScan& scan,
    const std::vector<std::uint32_t>& words) {
  if (words.size() != scan.points.size()) {
    return Error{"'" + source.sensorLabel + "': " + std::to_string(words.size()) +
                 " labels for " + std::to_string(scan.points.size()) + " points"};
  }
  auto map = ::mrpt::maps::CWeightedPointsMap::Create();
  map->reserve(scan.points.size());
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    map->insertPointFast(scan.points[i].x(), scan.points[i].y(), scan.points[i].z());
    map->setPointWeight(i, words[i]);
  }
  auto cloud = std::make_shared<::mrpt::obs::CObservationPointCloud>();
  cloud->sensorLabel = source.sensorLabel + kSegmentCloudSuffix;
  cloud->timestamp = source.timestamp;
  ::mrpt::poses::CPose3D pose;
  source.getSensorPose(pose);
  cloud->sensorPose = pose;
  cloud->pointcloud = map;
  return cloud;
}

}  // namespace cairn::sources
