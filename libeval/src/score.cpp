#include "cairn/eval/score.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace cairn::eval {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double Ratio(double num, double den) { return den > 0.0 ? num / den : kNaN; }

bool InUnitInterval(double v) { return std::isfinite(v) && v > 0.0 && v <= 1.0; }

}  // namespace

Status ScoreOptions::Validate() const {
  if (!InUnitInterval(found_fraction)) {
    return Error{"found_fraction must be in (0, 1], got " + std::to_string(found_fraction)};
  }
  if (min_object_pixels < 1) {
    return Error{"min_object_pixels must be at least 1, got " + std::to_string(min_object_pixels)};
  }
  if (!InUnitInterval(false_fraction)) {
    return Error{"false_fraction must be in (0, 1], got " + std::to_string(false_fraction)};
  }
  if (!InUnitInterval(link_fraction)) {
    return Error{"link_fraction must be in (0, 1], got " + std::to_string(link_fraction)};
  }
  return Status::Ok();
}

double PointCounts::Precision() const { return Ratio(double(tp), double(tp + fp)); }
double PointCounts::Recall() const { return Ratio(double(tp), double(tp + fn)); }
double PointCounts::F1() const { return Ratio(2.0 * double(tp), double(2 * tp + fp + fn)); }
double PointCounts::IoU() const { return Ratio(double(tp), double(tp + fp + fn)); }

PointCounts& PointCounts::operator+=(const PointCounts& o) {
  tp += o.tp;
  fp += o.fp;
  fn += o.fn;
  return *this;
}

double Score::FoundRate() const { return Ratio(objects_found, objects_counted); }
double Score::SegmentsPerObject() const {
  return Ratio(double(segments_per_object_sum), objects_found);
}
double Score::ObjectsPerSegment() const {
  return Ratio(double(objects_per_segment_sum), true_segments);
}

Score& Score::operator+=(const Score& o) {
  strict += o.strict;
  band_excluded += o.band_excluded;
  band_pixels += o.band_pixels;
  objects_counted += o.objects_counted;
  objects_found += o.objects_found;
  objects_small += o.objects_small;
  non_obstacles_counted += o.non_obstacles_counted;
  non_obstacles_marked += o.non_obstacles_marked;
  segments += o.segments;
  kept_segments += o.kept_segments;
  false_obstacles += o.false_obstacles;
  segments_per_object_sum += o.segments_per_object_sum;
  segments_per_object_max = std::max(segments_per_object_max, o.segments_per_object_max);
  objects_per_segment_sum += o.objects_per_segment_sum;
  true_segments += o.true_segments;
  objects_per_segment_max = std::max(objects_per_segment_max, o.objects_per_segment_max);
  merged_segments += o.merged_segments;
  frames += o.frames;
  return *this;
}

Expected<FrameScore> ScoreDetection(const FrameTruth& truth,
                                    const std::vector<std::int32_t>& foot_band,
                                    const od::Detection& detection,
                                    const od::Classification& classification,
                                    const ScoreOptions& options) {
  if (Status s = options.Validate(); !s) return s.error();
  if (Status s = truth.Validate(); !s) return s.error();
  const std::size_t n = truth.object_id.size();
  if (detection.width != truth.width || detection.height != truth.height ||
      detection.labels.size() != n) {
    return Error{"score: detection is " + std::to_string(detection.width) + "x" +
                 std::to_string(detection.height) + ", truth " + std::to_string(truth.width) + "x" +
                 std::to_string(truth.height)};
  }
  if (!foot_band.empty() && foot_band.size() != n) {
    return Error{"score: foot band has " + std::to_string(foot_band.size()) + " pixels, truth " +
                 std::to_string(n)};
  }
  if (classification.verdicts.size() != detection.segments.size()) {
    return Error{"score: " + std::to_string(classification.verdicts.size()) + " verdicts for " +
                 std::to_string(detection.segments.size()) + " segments"};
  }
  const int segment_count = static_cast<int>(detection.segments.size());

  FrameScore out;
  out.score.frames = 1;
  out.score.segments = segment_count;
  // Objects by position in truth.objects; ids map to positions.
  int max_id = 0;
  for (const TruthObject& o : truth.objects) max_id = std::max(max_id, o.id);
  std::vector<int> position(static_cast<std::size_t>(max_id) + 1, -1);
  for (std::size_t k = 0; k < truth.objects.size(); ++k) {
    const TruthObject& o = truth.objects[k];
    position[o.id] = static_cast<int>(k);
    ObjectOutcome outcome;
    outcome.id = o.id;
    outcome.name = o.name;
    outcome.is_obstacle = o.is_obstacle;
    out.objects.push_back(outcome);
  }
  out.segments.resize(detection.segments.size());
  std::vector<std::uint8_t> kept(detection.segments.size() + 1, 0);
  for (int s = 0; s < segment_count; ++s) {
    out.segments[s].id = s + 1;
    out.segments[s].kept = classification.verdicts[s].cls == od::SegmentClass::kKept;
    kept[s + 1] = out.segments[s].kept ? 1 : 0;
  }

  // Detected pixels per (kept segment, obstacle object), for the links.
  std::unordered_map<std::int64_t, int> overlap;
  for (std::size_t i = 0; i < n; ++i) {
    const int id = truth.object_id[i];
    const int label = detection.labels[i];
    if (label < 0 || label > segment_count) {
      return Error{"score: segment label " + std::to_string(label) + " at pixel " +
                   std::to_string(i) + " (the detection has " + std::to_string(segment_count) +
                   " segments)"};
    }
    if (id == sim::kNoHitId) continue;
    const TruthObject* object = id > 0 ? &truth.objects[position[id]] : nullptr;
    const bool positive = object != nullptr && object->is_obstacle;
    const bool in_band = !foot_band.empty() && foot_band[i] != 0 && id == sim::kTerrainId;
    const bool detected = label != 0 && kept[label];

    PointCounts& strict = out.score.strict;
    PointCounts& loose = out.score.band_excluded;
    if (detected && positive) {
      ++strict.tp;
      ++loose.tp;
    } else if (detected) {
      ++strict.fp;
      if (!in_band) ++loose.fp;
    } else if (positive) {
      ++strict.fn;
      ++loose.fn;
    }
    if (in_band) ++out.score.band_pixels;

    if (object != nullptr) {
      ObjectOutcome& o = out.objects[position[id]];
      ++o.pixels;
      if (detected) ++o.detected;
    }
    if (label != 0) {
      SegmentOutcome& s = out.segments[label - 1];
      ++s.pixels;
      if (positive || in_band) ++s.on_obstacles;
      if (detected && positive) {
        ++overlap[static_cast<std::int64_t>(label) * (max_id + 1) + id];
      }
    }
  }

  for (ObjectOutcome& o : out.objects) {
    o.counted = o.pixels >= options.min_object_pixels;
    const bool marked = o.detected >= options.found_fraction * o.pixels;
    if (o.is_obstacle) {
      if (o.counted) {
        ++out.score.objects_counted;
        o.found = marked;
        if (o.found) ++out.score.objects_found;
      } else if (o.pixels > 0) {
        ++out.score.objects_small;
      }
    } else if (o.counted) {
      ++out.score.non_obstacles_counted;
      if (marked) ++out.score.non_obstacles_marked;
    }
  }
  for (SegmentOutcome& s : out.segments) {
    if (!s.kept) continue;
    ++out.score.kept_segments;
    s.false_obstacle = s.pixels > 0 && s.on_obstacles < options.false_fraction * s.pixels;
    if (s.false_obstacle) ++out.score.false_obstacles;
  }
  for (const auto& [key, shared] : overlap) {
    const int label = static_cast<int>(key / (max_id + 1));
    const int id = static_cast<int>(key % (max_id + 1));
    ObjectOutcome& o = out.objects[position[id]];
    SegmentOutcome& s = out.segments[label - 1];
    const double need = std::max(1.0, options.link_fraction * std::min(o.detected, s.pixels));
    if (shared < need) continue;
    ++o.segments;
    ++s.objects;
  }
  for (const ObjectOutcome& o : out.objects) {
    if (!o.found) continue;
    out.score.segments_per_object_sum += o.segments;
    out.score.segments_per_object_max = std::max(out.score.segments_per_object_max, o.segments);
  }
  for (const SegmentOutcome& s : out.segments) {
    if (!s.kept || s.false_obstacle) continue;
    ++out.score.true_segments;
    out.score.objects_per_segment_sum += s.objects;
    out.score.objects_per_segment_max = std::max(out.score.objects_per_segment_max, s.objects);
    if (s.objects >= 2) ++out.score.merged_segments;
  }
  return out;
}

}  // namespace cairn::eval
