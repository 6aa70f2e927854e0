// `cairn map`: the run's own files besides the map's (map_run.hpp): poses.tum (each fused
// frame's T_world_sensor), frames.csv (per-frame figures), summary.json and summary.txt.
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>

#include "cairn/map/map_files.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sources/trajectory.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/quantile.hpp"
#include "map_run.hpp"
#include "process_memory.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json ObstacleBrief(const map::Obstacle& o) {
  return {{"id", o.id},
          {"centroid", {o.centroid.x(), o.centroid.y(), o.centroid.z()}},
          {"height_m", o.height_m},
          {"footprint_area_m2", o.footprint_area_m2},
          {"frames", o.frames.size()}};
}

/// A distance that may be infinite (no lethal cell in the map) as JSON: -1 then.
double DistanceOrMinusOne(double d) { return std::isfinite(d) ? d : -1.0; }

json TruthJson(const TruthScore& truth) {
  const cairn::eval::MapScore& score = truth.score;
  json objects = json::array();
  for (const cairn::eval::MapObjectScore& t : score.objects) {
    objects.push_back({{"id", t.id},
                       {"name", t.name},
                       {"is_obstacle", t.is_obstacle},
                       {"x", t.centre.x()},
                       {"y", t.centre.y()},
                       {"cells", t.cells.size()},
                       {"obstacle_cells", t.obstacle_cells.size()},
                       {"found", t.found},
                       {"distance_to_lethal_m", DistanceOrMinusOne(t.nearest_lethal_m)},
                       {"map_obstacle", t.map_obstacle_id}});
  }
  return {{"world", truth.world},
          {"obstacles", score.obstacles},
          {"found", score.found},
          {"non_obstacles_marked", score.marked_non_obstacles},
          {"false_obstacles", score.false_obstacle_ids.size()},
          {"false_obstacle_ids", score.false_obstacle_ids},
          {"lethal_iou", score.iou},
          {"lethal_cells", score.lethal_cells.size()},
          {"true_obstacle_cells", score.obstacle_cells.size()},
          {"false_lethal_cells", score.false_lethal},
          {"elevation_rms_m", score.elevation_rms_m},
          {"elevation_max_error_m", score.elevation_max_m},
          {"elevation_cells", score.elevation_cells},
          {"objects", objects}};
}

void TruthText(const TruthScore& truth, std::ostringstream& text) {
  const cairn::eval::MapScore& score = truth.score;
  text << "  truth (" << truth.world << "): " << score.found << "/" << score.obstacles
       << " obstacles found, " << score.marked_non_obstacles << " non-obstacles marked, "
       << score.false_obstacle_ids.size() << " false obstacles; IoU of lethal and true obstacle "
       << "cells " << util::Fixed(score.iou, 2) << ", " << score.false_lethal
       << " lethal cells away from every obstacle; elevation RMS error "
       << util::Fixed(score.elevation_rms_m, 3) << " m over " << score.elevation_cells
       << " cells away from the objects\n";
  for (const cairn::eval::MapObjectScore& t : score.objects) {
    text << "    " << std::left << std::setw(12) << t.name << std::right
         << (t.is_obstacle ? " obstacle     " : " not obstacle ") << "at ("
         << util::Fixed(t.centre.x(), 1) << ", " << util::Fixed(t.centre.y(), 1) << "): "
         << (t.found ? "found"
                     : (t.scored()      ? "MISSED"
                        : t.is_obstacle ? "too low"
                                        : "clear"));
    if (std::isfinite(t.nearest_lethal_m)) {
      text << ", nearest lethal cell " << util::Fixed(t.nearest_lethal_m, 2) << " m";
    }
    text << "\n";
  }
}

}  // namespace

namespace {

// Per fused frame, each stage's time [ms]: its median and 95th percentile, in the order
// they are printed.
struct StageStat {
  const char* name;
  double median_ms, p95_ms;
};
std::vector<StageStat> PerFrameStages(const std::vector<FrameRecord>& records) {
  const std::pair<const char*, double (*)(const FrameRecord&)> stages[] = {
      {"read", [](const FrameRecord& r) { return r.read_s; }},
      {"detect", [](const FrameRecord& r) { return r.detect_s; }},
      {"tilt", [](const FrameRecord& r) { return r.refine_s; }},
      {"fuse", [](const FrameRecord& r) { return r.fuse_s; }},
      {"octree", [](const FrameRecord& r) { return r.fused.octree_s; }},
      {"classify", [](const FrameRecord& r) { return r.fused.classify_s; }},
      {"grid", [](const FrameRecord& r) { return r.fused.grid_s; }},
      {"frame", [](const FrameRecord& r) { return r.read_s + r.detect_s + r.refine_s + r.fuse_s; }},
  };
  std::vector<StageStat> out;
  for (const auto& [name, of] : stages) {
    std::vector<double> ms;
    for (const FrameRecord& r : records) ms.push_back(1e3 * of(r));
    out.push_back({name, util::Quantile(ms, 0.5), util::Quantile(ms, 0.95)});
  }
  return out;
}

}  // namespace

Expected<std::string> WriteRunFiles(const RunReport& run, const fs::path& dir, StageTimes& times) {
  const std::vector<FrameRecord>& records = run.state.records;
  const map::TerrainMap& terrain =
      (run.smoothed != nullptr ? run.smoothed->mapper : run.mapper).map();
  const map::MapperConfig& config = run.mapper.config();
  const bool refine = config.tilt.mode != map::TiltMode::kPrior;
  // Per-frame poses (TUM, as fused) and figures (CSV).
  std::string tum =
      "# cairn map: T_world_sensor of each frame as fused (stamp tx ty tz qx qy qz qw)\n";
  std::ostringstream csv;
  csv << "frame,stamp_s,valid_points,segments,kept,obstacle_points,obstacles_created,"
         "lethal_cells,tilt_refined,d_roll_deg,d_pitch_deg,dz_m,rms_before_m,rms_after_m,"
         "read_ms,detect_ms,refine_ms,fuse_ms,rss_mb,heap_mb,tilt_sigma_deg,verticals,"
         "not_observable\n";
  double distance_m = 0.0;
  for (std::size_t k = 0; k < records.size(); ++k) {
    const FrameRecord& r = records[k];
    if (k > 0) {
      distance_m +=
          (r.T_world_body.translation() - records[k - 1].T_world_body.translation()).norm();
    }
    tum += sources::TumLine({r.stamp_s, r.T_world_sensor}) + "\n";
    csv << r.index << "," << util::Fixed(r.stamp_s, 6) << "," << r.valid_points << "," << r.segments
        << "," << r.kept << "," << r.fused.obstacle_points << "," << r.fused.obstacles_created
        << "," << r.fused.lethal_cells << "," << (r.refined ? 1 : 0) << ","
        << util::Fixed(r.d_roll_rad / kDegToRad, 3) << ","
        << util::Fixed(r.d_pitch_rad / kDegToRad, 3) << "," << util::Fixed(r.dz_m, 3) << ","
        << util::Fixed(r.rms_before_m, 4) << "," << util::Fixed(r.rms_after_m, 4) << ","
        << util::Fixed(r.read_s * 1e3, 1) << "," << util::Fixed(r.detect_s * 1e3, 1) << ","
        << util::Fixed(r.refine_s * 1e3, 1) << "," << util::Fixed(r.fuse_s * 1e3, 1) << ","
        << util::Fixed(r.rss_mb, 1) << "," << util::Fixed(r.heap_mb, 1) << ","
        << (std::isfinite(r.tilt_sigma_rad) ? util::Fixed(r.tilt_sigma_rad / kDegToRad, 3)
                                            : std::string())
        << "," << r.verticals << "," << r.not_observable << "\n";
  }
  if (Status s = util::WriteFileAtomic(dir / "poses.tum", tum); !s) return s.error();
  if (Status s = util::WriteFileAtomic(dir / "frames.csv", csv.str()); !s) return s.error();
  times.write_s = SecondsSince(run.write_start);

  // Summary.
  const int n = static_cast<int>(records.size());
  const double wall_s = run.wall_s;
  const map::MapMemory memory = terrain.Memory();
  Expected<map::CellBox> bounds = map::ExportBounds(terrain);
  json summary;
  summary["input"] = SourceJson(run.source.Describe());
  summary["frames"] = n;
  const int imu_frames = static_cast<int>(std::count_if(
      records.begin(), records.end(), [](const FrameRecord& r) { return r.tilt_from_imu; }));
  summary["imu_tilt_frames"] = imu_frames;
  summary["distance_driven_m"] = distance_m;
  summary["duration_s"] = records.back().stamp_s - records.front().stamp_s;
  summary["map"] = {{"mode", config.map.window_size_m > 0 ? "online" : "offline"},
                    {"window_size_m", config.map.window_size_m},
                    {"cell_size_m", config.map.cell_size_m},
                    {"voxel_size_m", config.map.voxel_size_m},
                    {"grid_bytes", memory.grid_bytes},
                    {"octree_bytes", memory.octree_bytes},
                    {"octree_leaves", memory.octree_leaves}};
  if (bounds) summary["map"]["extent_cells"] = {bounds->size().x(), bounds->size().y()};
  int lethal = 0, known = 0;
  const map::TerrainGrid& g = terrain.grid();
  for (int j = 0; j < g.extent().y(); ++j) {
    for (int i = 0; i < g.extent().x(); ++i) {
      const map::Cell& c = g.At(g.min_index() + map::CellIndex(i, j));
      lethal += c.lethal ? 1 : 0;
      known += c.observed ? 1 : 0;
    }
  }
  summary["map"]["observed_cells"] = known;
  summary["map"]["lethal_cells"] = lethal;
  json obstacles = json::array();
  for (const map::Obstacle& o : terrain.obstacles()) obstacles.push_back(ObstacleBrief(o));
  summary["obstacles"] = {{"live", terrain.obstacles().size()},
                          {"retired", terrain.obstacles_retired()},
                          {"list", obstacles}};
  if (refine) {
    double sum_before = 0.0, sum_after = 0.0;
    int counted = 0;
    for (const FrameRecord& r : records) {
      if (!r.refined) continue;
      sum_before += r.rms_before_m;
      sum_after += r.rms_after_m;
      ++counted;
    }
    summary["tilt"] = {
        {"refine", true},
        {"mode", map::TiltModeName(config.tilt.mode)},
        {"refined_frames", run.state.refined_frames},
        {"final_correction_deg",
         {records.back().d_roll_rad / kDegToRad, records.back().d_pitch_rad / kDegToRad}},
        {"final_dz_m", records.back().dz_m},
        {"mean_rms_before_m", counted ? sum_before / counted : 0.0},
        {"mean_rms_after_m", counted ? sum_after / counted : 0.0}};
    if (config.tilt.mode == map::TiltMode::kGravity) {
      int flagged = 0, verticals = 0;
      for (const FrameRecord& r : records) {
        flagged += r.not_observable.empty() ? 0 : 1;
        verticals += r.verticals;
      }
      summary["tilt"]["vertical_cues"] = verticals;
      summary["tilt"]["frames_not_observable"] = flagged;
      summary["tilt"]["not_observable_at_end"] = records.back().not_observable;
      // The tilt error the estimator expects (RMS), over the frames fused at its estimate.
      std::vector<double> sigma_deg;
      for (const FrameRecord& r : records) {
        if (std::isfinite(r.tilt_sigma_rad)) sigma_deg.push_back(r.tilt_sigma_rad / kDegToRad);
      }
      if (!sigma_deg.empty()) {
        summary["tilt"]["tilt_sigma_median_deg"] = util::Quantile(sigma_deg, 0.5);
      }
    }
  } else {
    summary["tilt"] = {{"refine", false}, {"mode", map::TiltModeName(config.tilt.mode)}};
  }
  summary["tilt"]["smoothed"] = run.smoothed != nullptr;
  if (run.smoothed != nullptr) {
    summary["tilt"]["smooth_solve_s"] = run.smoothed->solve_s;
    summary["tilt"]["smooth_pass_s"] = run.smoothed->pass_s;
  }
  // Frames not fused, by reason, and each with what was found.
  std::map<std::string, int> by_reason;
  json skipped_list = json::array();
  for (const SkippedFrame& s : run.state.skipped) {
    ++by_reason[s.reason];
    skipped_list.push_back({{"frame", s.name}, {"reason", s.reason}, {"detail", s.detail}});
  }
  summary["skipped"] = {{"count", run.state.skipped.size()},
                        {"by_reason", by_reason},
                        {"frames", skipped_list}};
  summary["time_s"] = {{"read", times.read_s},     {"detect", times.detect_s},
                       {"refine", times.refine_s}, {"fuse", times.fuse_s},
                       {"write", times.write_s},   {"checkpoint", times.checkpoint_s},
                       {"total", wall_s}};
  summary["frames_per_s"] = wall_s > 0 ? n / wall_s : 0.0;
  const std::vector<StageStat> stages = PerFrameStages(records);
  for (const StageStat& st : stages) {
    summary["per_frame_ms"][st.name] = {{"median", st.median_ms}, {"p95", st.p95_ms}};
  }
  const double frame_median_ms = stages.back().median_ms;
  // The rate the pipeline keeps up with, frame after frame (the files written at the end
  // left out).
  summary["sustained_frames_per_s"] = frame_median_ms > 0 ? 1e3 / frame_median_ms : 0.0;
  // Of this process: a resumed run's peak is its own, not the interrupted run's.
  summary["peak_rss_mb"] = ReadProcessMemory().peak_rss_mb;
  if (run.truth) summary["truth"] = TruthJson(*run.truth);
  if (run.poses) {
    summary["truth_poses"] = {{"source", run.poses->source},
                              {"frames", run.poses->frames},
                              {"tilt_error_median_deg", run.poses->tilt_median_deg},
                              {"tilt_error_p95_deg", run.poses->tilt_p95_deg},
                              {"tilt_error_max_deg", run.poses->tilt_max_deg},
                              {"height_error_rms_m", run.poses->height_rms_m}};
  }

  std::ostringstream text;
  text << "cairn map: " << n << " frames from " << summary["input"]["path"].get<std::string>()
       << " (" << summary["input"]["kind"].get<std::string>() << "), " << util::Fixed(distance_m, 1)
       << " m driven in " << util::Fixed(summary["duration_s"].get<double>(), 1) << " s of data\n"
       << "  poses: " << run.source.trajectory().source() << " (IMU tilt on " << imu_frames << "/"
       << n << " frames)\n";
  if (!run.state.skipped.empty()) {
    text << "  skipped: " << run.state.skipped.size() << " frame"
         << (run.state.skipped.size() == 1 ? "" : "s") << " not fused (";
    bool first = true;
    for (const auto& [reason, count] : by_reason) {
      text << (first ? "" : ", ") << reason << " " << count;
      first = false;
    }
    text << "; summary.json lists them)\n";
  }
  text << "  map: " << summary["map"]["mode"].get<std::string>() << ", cell "
       << config.map.cell_size_m << " m, voxel " << config.map.voxel_size_m << " m, " << known
       << " cells observed, " << lethal << " lethal\n"
       << "  obstacles: " << terrain.obstacles().size() << " (" << terrain.obstacles_retired()
       << " retired on the way)\n";
  if (refine) {
    text << "  tilt (" << map::TiltModeName(config.tilt.mode) << "): applied on "
         << run.state.refined_frames << "/" << n << " frames; correction at the end "
         << util::Fixed(records.back().d_roll_rad / kDegToRad, 2) << " deg roll, "
         << util::Fixed(records.back().d_pitch_rad / kDegToRad, 2) << " deg pitch, "
         << util::Fixed(records.back().dz_m, 3) << " m height";
    if (config.tilt.mode == map::TiltMode::kGravity) {
      const std::string& last = records.back().not_observable;
      text << "; " << summary["tilt"]["vertical_cues"].get<int>() << " vertical cues; "
           << (last.empty() ? std::string("every state observed at the end")
                            : "not observable at the end: " + last)
           << " (" << summary["tilt"]["frames_not_observable"].get<int>() << "/" << n
           << " frames flagged)";
      if (summary["tilt"].contains("tilt_sigma_median_deg")) {
        text << "; stated tilt sigma "
             << util::Fixed(summary["tilt"]["tilt_sigma_median_deg"].get<double>(), 2)
             << " deg (median)";
      }
    }
    if (run.smoothed != nullptr) {
      text << "\n  smoothed: every frame posed again by the smoother (solved in "
           << util::Fixed(run.smoothed->solve_s, 2) << " s) and fused again at it ("
           << util::Fixed(run.smoothed->pass_s, 2)
           << " s, a second pass over the input); the poses and the correction above are its";
    }
    if (config.tilt.mode == map::TiltMode::kRefineToMap) {
      text << "; ground RMS " << util::Fixed(summary["tilt"]["mean_rms_before_m"].get<double>(), 3)
           << " -> " << util::Fixed(summary["tilt"]["mean_rms_after_m"].get<double>(), 3) << " m";
    }
    text << "\n";
  }
  text << "  time: read " << util::Fixed(times.read_s, 2) << " s, detect "
       << util::Fixed(times.detect_s, 2) << " s, refine " << util::Fixed(times.refine_s, 2)
       << " s, fuse " << util::Fixed(times.fuse_s, 2) << " s, write "
       << util::Fixed(times.write_s, 2) << " s; " << util::Fixed(wall_s, 2) << " s in all, "
       << util::Fixed(n / wall_s, 2) << " frames/s; peak memory "
       << util::Fixed(summary["peak_rss_mb"].get<double>(), 0) << " MiB\n";
  // read, detect, tilt, fuse (octree, classify, grid), frame
  const auto stat = [&](std::size_t k) {
    return std::string(stages[k].name) + " " + util::Fixed(stages[k].median_ms, 1) + "/" +
           util::Fixed(stages[k].p95_ms, 1);
  };
  text << "  per frame, median/95th percentile [ms]: " << stat(0) << ", " << stat(1) << ", "
       << stat(2) << ", " << stat(3) << " (" << stat(4) << ", " << stat(5) << ", " << stat(6)
       << "), " << stat(7) << "; "
       << util::Fixed(summary["sustained_frames_per_s"].get<double>(), 1)
       << " frames/s sustained\n";
  if (run.poses) {
    text << "  poses against " << run.poses->source << ": tilt error median "
         << util::Fixed(run.poses->tilt_median_deg, 2) << " deg, 95th percentile "
         << util::Fixed(run.poses->tilt_p95_deg, 2) << " deg; height error RMS "
         << util::Fixed(run.poses->height_rms_m, 3) << " m (" << run.poses->frames << " frames)\n";
  }
  if (run.truth) TruthText(*run.truth, text);
  if (Status s = util::WriteFileAtomic(dir / "summary.json", summary.dump(2) + "\n"); !s) {
    return s.error();
  }
  if (Status s = util::WriteFileAtomic(dir / "summary.txt", text.str()); !s) return s.error();
  return text.str();
}

}  // namespace cairn::apps
