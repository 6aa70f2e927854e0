#include "cairn/eval/map_study.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>

#include "cairn/eval/euroc_gravity.hpp"
#include "cairn/od/parallel.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/format.hpp"
#include "map_study_parts.hpp"

namespace cairn::eval {
namespace study {

std::string WorldFile(const MapStudyOptions& options, const std::string& name) {
  if (name.size() > 5 && name.compare(name.size() - 5, 5, ".yaml") == 0) {
    return (options.root / name).string();
  }
  return (options.root / "datasets" / "worlds" / (name + ".yaml")).string();
}

Status Drives::Run(int count, const std::function<Expected<std::string>(int)>& body) {
  std::vector<std::optional<Error>> errors(count);
  od::ParallelFor(
      count, options_.threads,
      [&](int k) {
        Expected<std::string> line = body(k);
        const std::lock_guard<std::mutex> lock(mutex_);
        ++done_;
        if (!line) {
          errors[k] = line.error();
        } else if (options_.on_drive) {
          options_.on_drive(*line, done_, total_);
        }
      },
      1);
  for (const std::optional<Error>& e : errors) {
    if (e) return *e;
  }
  return Status::Ok();
}

namespace {

namespace fs = std::filesystem;
using util::Fixed;

struct Condition {
  std::string label;
  DriftRunSpec spec;  // world and waypoints filled per world
  int seeds = 1;
};

struct WorldRoute {
  std::string world;
  std::vector<Eigen::Vector2d> waypoints;
  bool sloped = false;
};

const std::vector<WorldRoute>& DriftWorlds() {
  static const std::vector<WorldRoute> worlds = {
      {"poles_and_rocks", {{0.0, 0.0}, {16.0, 0.0}}, false},
      {"sideways_mounds", {{0.0, 40.0}, {20.0, 40.0}}, false},
      {"uphill_tilted", {{0.0, 0.0}, {20.0, 1.0}, {30.0, -0.5}}, true},
  };
  return worlds;
}

std::vector<Condition> Conditions(bool sloped) {
  std::vector<Condition> out;
  Condition truth{"true poses", {}, 1};
  truth.spec.true_poses = true;
  out.push_back(truth);
  for (const double drift : {0.0, 0.01, 0.03}) {
    Condition c{"odometry " + Fixed(drift * 100.0, 0) + "%", {}, drift > 0.0 ? 3 : 1};
    DriftOdometryBy(c.spec, drift);
    out.push_back(c);
  }
  if (sloped) {
    Condition bias{"IMU bias 2 deg", {}, 1};
    bias.spec.imu_bias_rad = 2.0 * kDegToRad;
    out.push_back(bias);
    Condition refined = bias;
    refined.label = "IMU bias 2 deg + tilt refiner";
    refined.spec.refine_tilt = true;
    out.push_back(refined);
    Condition drift_bias{"odometry 1% + IMU bias 2 deg", {}, 3};
    DriftOdometryBy(drift_bias.spec, 0.01);
    drift_bias.spec.imu_bias_rad = 2.0 * kDegToRad;
    out.push_back(drift_bias);
    Condition both{"odometry 1% + IMU bias 2 deg + tilt refiner", {}, 3};
    DriftOdometryBy(both.spec, 0.01);
    both.spec.imu_bias_rad = 2.0 * kDegToRad;
    both.spec.refine_tilt = true;
    out.push_back(both);
  }
  return out;
}

/// One drive of the drift study.
struct DriftDrive {
  std::string world, condition;
  DriftRunSpec spec;
};

std::vector<DriftDrive> DriftDrivesInOrder(const MapStudyOptions& options) {
  std::vector<DriftDrive> out;
  for (const WorldRoute& world : DriftWorlds()) {
    for (const Condition& condition : Conditions(world.sloped)) {
      for (int k = 1; k <= condition.seeds; ++k) {
        DriftDrive d{world.world, condition.label, condition.spec};
        d.spec.world = WorldFile(options, world.world);
        d.spec.settings = options.settings;
        d.spec.waypoints = world.waypoints;
        d.spec.drive_seed = static_cast<std::uint64_t>(k);
        out.push_back(std::move(d));
      }
    }
  }
  return out;
}

Expected<std::vector<Row>> DriftStudy(const std::vector<DriftDrive>& drives_in_order,
                                      Drives& drives) {
  std::vector<std::optional<DriftRunResult>> results(drives_in_order.size());
  const Status st =
      drives.Run(static_cast<int>(drives_in_order.size()), [&](int k) -> Expected<std::string> {
        const DriftDrive& d = drives_in_order[k];
        Expected<DriftRunResult> r = RunDrift(d.spec);
        if (!r) return Error{d.world + ", " + d.condition + ": " + r.error().message};
        const std::string line = d.world + ", " + d.condition + ", seed " +
                                 std::to_string(d.spec.drive_seed) + ": IoU " +
                                 Fixed(r->score.iou, 3) + ", nearest lethal max " +
                                 Fixed(r->max_distance_m, 2) + " m, false lethal " +
                                 std::to_string(r->score.false_lethal) + ", elevation RMS " +
                                 Fixed(r->score.elevation_rms_m, 3) + " m";
        results[k].emplace(std::move(*r));
        return line;
      });
  if (!st) return st.error();
  std::vector<Row> rows;
  for (std::size_t k = 0; k < results.size(); ++k) {
    const DriftDrive& d = drives_in_order[k];
    rows.push_back({d.world, d.condition, d.spec.drive_seed, std::move(*results[k])});
  }
  return rows;
}

/// runs.csv and obstacles.csv.
std::pair<std::string, std::string> DriftTables(const std::vector<Row>& rows) {
  std::ostringstream runs, obstacles;
  runs << "world,condition,seed,frames,distance_m,final_position_error_m,final_yaw_error_deg,"
          "final_tilt_error_deg,iou,lethal_cells,true_cells,false_lethal_cells,seen_obstacles,"
          "within_0_3_m,max_nearest_lethal_m,mean_nearest_lethal_m,elevation_rms_m,"
          "elevation_cells,refined_frames\n";
  obstacles << "world,condition,seed,obstacle,first_seen_distance_m,nearest_lethal_m\n";
  for (const Row& row : rows) {
    const DriftRunResult& r = row.result;
    const PoseError& last = r.pose_errors.back();
    runs << row.world << "," << row.condition << "," << row.seed << "," << r.frames << ","
         << Fixed(r.distance_m, 2) << "," << Fixed(last.position_m, 3) << ","
         << Fixed(last.yaw_rad / kDegToRad, 3) << "," << Fixed(last.tilt_rad / kDegToRad, 3) << ","
         << Fixed(r.score.iou, 3) << "," << r.score.lethal_cells.size() << ","
         << r.score.obstacle_cells.size() << "," << r.score.false_lethal << ","
         << r.obstacles.size() << "," << r.found_0_3 << "," << Fixed(r.max_distance_m, 2) << ","
         << Fixed(r.mean_distance_m, 3) << "," << Fixed(r.score.elevation_rms_m, 4) << ","
         << r.score.elevation_cells << "," << r.refined_frames << "\n";
    for (const auto& o : r.obstacles) {
      obstacles << row.world << "," << row.condition << "," << row.seed << "," << o.name << ","
                << Fixed(o.first_seen_distance_m, 2) << "," << Fixed(o.nearest_lethal_m, 2) << "\n";
    }
  }
  return {runs.str(), obstacles.str()};
}

/// The figures of the drift study; returns their names.
Expected<std::vector<std::string>> DriftFigures(const std::vector<Row>& rows, const fs::path& out) {
  // Figures: the cost grid of poles_and_rocks at true poses and at 3 % drift (seed 1), and
  // error growth per world.
  std::vector<std::string> figures;
  for (const Row& row : rows) {
    if (row.world != "poles_and_rocks" || row.seed != 1) continue;
    if (row.condition != "true poses" && row.condition != "odometry 3%") continue;
    const std::string name = std::string("cost_poles_and_rocks_") +
                             (row.condition == "true poses" ? "true_poses" : "drift_3pct") + ".png";
    if (Status st = WriteCostFigure(row.result, out / "figures" / name); !st) return st.error();
    figures.push_back(name);
  }
  for (const WorldRoute& world : DriftWorlds()) {
    const std::string name = "growth_" + world.world + ".png";
    if (Status st = WriteGrowthFigure(rows, world.world, out / "figures" / name); !st) {
      return st.error();
    }
    figures.push_back(name);
  }
  return figures;
}

/// The report's head: the command, the set-up and how the drift study scores a map.
void Introduction(const MapStudyOptions& options, std::ostringstream& md) {
  md << "# TerrainMap under odometry drift and IMU bias\n\n"
     << "Made by one command (from the source tree, build dir `build`):\n\n"
     << "```\n"
     << options.command << "\n```\n\n"
     << "It ran in @SECONDS@ s here (@THREADS@) and wrote this file, `runs.csv` (one row "
     << "per drive), `obstacles.csv` (one row per seen obstacle per drive) and `figures/`. "
     << "The claims below are asserted by `tests/map/drift_test.cpp` (`map_drift_test`).\n\n"
     << "## Set-up\n\n"
     << "- Worlds from `datasets/worlds`: `poles_and_rocks` (16 m straight), `sideways_mounds` "
     << "(20 m along y = 40, between mounds 5-8), `uphill_tilted` (30 m up a 12 deg slope, "
     << "3 deg side lean). A 320 x 240 range camera (the worlds' own), pitched 8 "
     << "deg down on the body, 1.5 m up; 2 m/s, 2 frames/s; detector and rules of "
     << "`config/default.yaml`; `MapConfig` defaults (0.1 m cells).\n"
     << "- The sensor renders from the true pose. The map is fused at the pose the robot "
     << "believes: x, y, yaw from libsim's wheel odometry (`SimulateDrive`: a scale error "
     << "s ~ N(0, sigma), a heading drift b ~ N(0, yaw sigma) per metre, plus a random walk), "
     << "roll and pitch from the IMU, height dead-reckoned from the odometry steps and the "
     << "IMU pitch; the range image is levelled with the believed up vector. `odometry N%` is "
     << "sigma = N % of the distance and yaw sigma = N x 0.5 deg / 10 m, three drives "
     << "(seeds 1-3); `odometry 0%` isolates the dead-reckoned height. `IMU bias 2 deg` adds "
     << "2 deg to roll and pitch, true x, y, yaw; `+ tilt refiner` runs `map::RefineTilt` on "
     << "every frame's ground points against the elevation fused so far "
     << "(`TerrainMap::PatchAround`), carrying the correction to the next frame as "
     << "`cairn map` does.\n"
     << "- Truth as in `terrain_map_sim_test`: true obstacle cells are observed cells where an "
     << "obstacle rises 0.15 m or more (rays cast down through the scene). IoU of the lethal "
     << "cells with them; for each obstacle seen well (120 pixels in a frame, 0.16 % of the "
     << "view), the distance "
     << "from its true cells to the nearest lethal cell (max and mean over obstacles; "
     << "`<=0.3` counts those within 0.3 m); false lethal = lethal cells more than 0.5 m from "
     << "every true obstacle cell; elevation RMS over cells with ground, 0.3 m or more from "
     << "any object. `pos err` is the believed sensor position's horizontal error at the end "
     << "of the drive.\n\n"
     << "## Results (mean over drives; worst drive in brackets)\n\n";
}

/// Per world and condition, the mean over the drives (worst in brackets).
void WorldTables(const std::vector<Row>& rows, std::ostringstream& md) {
  for (const WorldRoute& world : DriftWorlds()) {
    md << "### " << world.world << "\n\n"
       << "| condition | drives | pos err end [m] | IoU | nearest lethal max [m] | mean [m] | "
          "<=0.3 | false lethal | elevation RMS [m] |\n"
       << "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
    for (const Condition& condition : Conditions(world.sloped)) {
      int n = 0, within = 0, seen = 0, worst_false = 0;
      double pos = 0, worst_pos = 0, iou = 0, worst_iou = 1, max_d = 0, worst_max_d = 0, mean_d = 0,
             false_lethal = 0, rms = 0, worst_rms = 0;
      for (const Row& row : rows) {
        if (row.world != world.world || row.condition != condition.label) continue;
        const DriftRunResult& r = row.result;
        ++n;
        pos += r.pose_errors.back().position_m;
        worst_pos = std::max(worst_pos, r.pose_errors.back().position_m);
        iou += r.score.iou;
        worst_iou = std::min(worst_iou, r.score.iou);
        max_d += r.max_distance_m;
        worst_max_d = std::max(worst_max_d, r.max_distance_m);
        mean_d += r.mean_distance_m;
        within += r.found_0_3;
        seen += static_cast<int>(r.obstacles.size());
        false_lethal += r.score.false_lethal;
        worst_false = std::max(worst_false, r.score.false_lethal);
        rms += r.score.elevation_rms_m;
        worst_rms = std::max(worst_rms, r.score.elevation_rms_m);
      }
      if (n == 0) continue;
      md << "| " << condition.label << " | " << n << " | " << Fixed(pos / n, 2) << " ("
         << Fixed(worst_pos, 2) << ") | " << Fixed(iou / n, 3) << " (" << Fixed(worst_iou, 3)
         << ") | " << Fixed(max_d / n, 2) << " (" << Fixed(worst_max_d, 2) << ") | "
         << Fixed(mean_d / n, 2) << " | " << within << "/" << seen << " | "
         << Fixed(false_lethal / n, 1) << " (" << worst_false << ") | " << Fixed(rms / n, 3) << " ("
         << Fixed(worst_rms, 3) << ") |\n";
    }
    md << "\n";
  }
}

void GrowthTable(const std::vector<Row>& rows, std::ostringstream& md) {
  // Growth: nearest-lethal distance of the obstacles binned by distance driven at first
  // sight, per drift level, over all worlds and drives.
  md << "## How the errors grow with distance driven\n\n"
     << "Obstacle to nearest lethal cell [m], mean (max) over the obstacles first seen well "
     << "within each stretch of the drive, all worlds and drives, odometry conditions only; "
     << "and the mean horizontal error of the believed sensor position at the end of the "
     << "stretch.\n\n"
     << "| condition | 0-5 m | 5-10 m | 10-15 m | 15-20 m | 20-30 m | pos err at 10 m | at 20 m | "
        "at 30 m |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  const double bins[] = {0.0, 5.0, 10.0, 15.0, 20.0, 30.01};
  for (const char* label : {"true poses", "odometry 0%", "odometry 1%", "odometry 3%"}) {
    md << "| " << label;
    for (int b = 0; b < 5; ++b) {
      double sum = 0, worst = 0;
      int n = 0;
      for (const Row& row : rows) {
        if (row.condition != label) continue;
        for (const auto& o : row.result.obstacles) {
          if (o.first_seen_distance_m < bins[b] || o.first_seen_distance_m >= bins[b + 1]) continue;
          sum += o.nearest_lethal_m;
          worst = std::max(worst, o.nearest_lethal_m);
          ++n;
        }
      }
      md << " | " << (n ? Fixed(sum / n, 2) + " (" + Fixed(worst, 2) + ")" : "-");
    }
    for (const double at : {10.0, 20.0, 30.0}) {
      double sum = 0;
      int n = 0;
      for (const Row& row : rows) {
        if (row.condition != label || row.result.distance_m + 0.5 < at) continue;
        for (const auto& e : row.result.pose_errors) {
          if (std::abs(e.distance_m - at) < 0.51) {
            sum += e.position_m;
            ++n;
            break;
          }
        }
      }
      md << " | " << (n ? Fixed(sum / n, 2) : "-");
    }
    md << " |\n";
  }
}

void SummaryTable(const std::vector<Row>& rows, std::ostringstream& md) {
  // Summary over all worlds, per condition.
  md << "\n## Summary over the worlds\n\n"
     << "| condition | drives | final position error / distance | drives with every seen "
        "obstacle within 0.3 m of a lethal cell | worst nearest lethal [m] | false lethal per "
        "drive | final tilt error [deg] |\n| --- | --- | --- | --- | --- | --- | --- |\n";
  std::vector<std::string> labels;
  for (const Row& row : rows) {
    if (std::find(labels.begin(), labels.end(), row.condition) == labels.end()) {
      labels.push_back(row.condition);
    }
  }
  for (const std::string& label : labels) {
    int n = 0, all_within = 0;
    double ratio = 0, worst = 0, false_lethal = 0, tilt = 0;
    for (const Row& row : rows) {
      if (row.condition != label) continue;
      const DriftRunResult& r = row.result;
      ++n;
      ratio += r.pose_errors.back().position_m / std::max(1.0, r.distance_m);
      all_within += r.found_0_3 == static_cast<int>(r.obstacles.size());
      worst = std::max(worst, r.max_distance_m);
      false_lethal += r.score.false_lethal;
      tilt += r.pose_errors.back().tilt_rad / kDegToRad;
    }
    md << "| " << label << " | " << n << " | " << Fixed(100.0 * ratio / n, 1) << " % | "
       << all_within << "/" << n << " | " << Fixed(worst, 2) << " | " << Fixed(false_lethal / n, 1)
       << " | " << Fixed(tilt / n, 2) << " |\n";
  }
  md << "\nReading: the map degrades with the horizontal pose error, not with the distance "
     << "itself: an obstacle is put where the robot believed it was when it saw it, so its "
     << "nearest lethal cell is off by about the pose error at that moment (growth figures), "
     << "and an obstacle seen over several metres of drift is smeared, which lowers the IoU "
     << "and adds lethal cells beside it. A constant IMU roll/pitch bias present from the "
     << "first frame leaves the obstacles in place (the detector levels with the biased up "
     << "vector, a 2 deg error is far under theta) but the dead-reckoned height drifts by "
     << "d tan(bias), which is the elevation RMS of the `IMU bias` rows. The tilt refiner "
     << "matches each frame to the terrain fused so far, which the first, biased frame "
     << "built: it keeps the frames consistent with one another (see `refined_frames` in "
     << "`runs.csv`) but cannot observe a bias present from the start (the final tilt error "
     << "column); it needs an absolute reference (a level start, or gravity from a static "
     << "IMU) for that.\n";
}

}  // namespace
}  // namespace study

namespace {

using util::Fixed;

// Real data: the estimator's IMU terms on EuRoC V1_01 against its truth, and what that truth
// says of its own gravity.
Status EurocSection(const std::filesystem::path& dir, std::ostringstream& md) {
  Expected<EurocGravityResult> r = RunEurocGravity(dir);
  if (!r) return r.error();
  Expected<EurocStereoUpResult> up = RunEurocStereoUp(dir);
  if (!up) return up.error();
  md << "\n## Real data: EuRoC V1_01 (`cairn eval --euroc`)\n\n"
     << "The gravity estimator's IMU terms alone on EuRoC V1_01 (`" << dir.filename().string()
     << "` in `../shared/datasets`): its real 200 Hz accelerometer and gyro, the ground "
     << "truth's velocity and heading standing in for odometry, no attitude prior and no scene "
     << "cues; " << r->frames << " frames over " << Fixed(r->duration_s, 1) << " s. Roll and "
     << "pitch against the truth's:\n\n"
     << "| frames | tilt median [deg] | tilt 95th [deg] | roll median / 95th [deg] | pitch median "
        "/ 95th [deg] |\n"
     << "| --- | --- | --- | --- | --- |\n"
     << "| all " << r->frames << " | " << Fixed(r->tilt_median_deg, 3) << " | "
     << Fixed(r->tilt_p95_deg, 3) << " | " << Fixed(r->roll_median_deg, 3) << " / "
     << Fixed(r->roll_p95_deg, 3) << " | " << Fixed(r->pitch_median_deg, 3) << " / "
     << Fixed(r->pitch_p95_deg, 3) << " |\n";
  if (r->observed_frames > 0) {
    md << "| the " << r->observed_frames << " where the accelerometer bias is not flagged (from "
       << Fixed(r->bias_observed_from_s, 1) << " s) | " << Fixed(r->observed_tilt_median_deg, 3)
       << " | " << Fixed(r->observed_tilt_p95_deg, 3) << " | | |\n";
  } else {
    md << "| none where the accelerometer bias is not flagged | | | | |\n";
  }
  md << "\n"
     << "At rest the estimator flags the accelerometer bias (it cannot be told from a tilt "
     << "there). The truth against its own IMU (its attitude, velocity and accelerometer bias, "
     << "0.2 s spans) puts gravity " << Fixed(r->truth_gravity_tilt_deg, 3)
     << " deg from its world z, the spans scattered by (" << Fixed(r->truth_gravity_rms_mps2.x(), 3)
     << ", " << Fixed(r->truth_gravity_rms_mps2.y(), 3) << ", "
     << Fixed(r->truth_gravity_rms_mps2.z(), 3) << ") m/s^2: an estimator of the true gravity "
     << "would score about that against this truth, so the 0.2 deg median goal cannot be "
     << "shown on it. At rest the accelerometer's mean direction is "
     << Fixed(r->rest_accel_tilt_deg, 3) << " deg from the truth (its bias uncorrected).\n\n"
     << "On its " << up->pairs << " stereo pairs at rest (rectified, matched by "
     << "`od::io::ComputeStereoDepth`), the floor's normal is " << Fixed(up->floor_median_deg, 3)
     << " deg median (" << Fixed(up->floor_max_deg, 3) << " max) from the true up, the "
     << "accelerometer's mean direction " << Fixed(up->accel_median_deg, 3) << " deg, the two "
     << Fixed(up->floor_vs_accel_median_deg, 3) << " deg apart.\n";
  return Status::Ok();
}

}  // namespace

Status WriteMapStudy(const MapStudyOptions& options, const std::filesystem::path& out) {
  using namespace study;
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  std::filesystem::create_directories(out / "figures", ec);
  if (ec) return Error{(out / "figures").string() + ": cannot create: " + ec.message()};
  const std::vector<DriftDrive> drift_drives = DriftDrivesInOrder(options);
  Drives drives(options, static_cast<int>(drift_drives.size()) + TiltStudyDrives());
  Expected<std::vector<Row>> rows = DriftStudy(drift_drives, drives);
  if (!rows) return rows.error();
  const auto [runs, obstacles] = DriftTables(*rows);
  Expected<std::vector<std::string>> figures = DriftFigures(*rows, out);
  if (!figures) return figures.error();

  std::ostringstream md, tilt_csv;
  Introduction(options, md);
  WorldTables(*rows, md);
  GrowthTable(*rows, md);
  SummaryTable(*rows, md);
  if (Status st = TiltStudy(options, drives, md, tilt_csv); !st) return st;
  if (!options.euroc.empty()) {
    if (Status st = EurocSection(options.euroc, md); !st) return st;
  }
  md << "\n## Figures\n\n";
  // The whole run's time, tilt study included.
  std::string report = md.str();
  const double total_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report.replace(report.find("@SECONDS@"), 9, Fixed(total_s, 0));
  const int threads = od::ThreadCount(options.threads);
  report.replace(report.find("@THREADS@"), 9,
                 std::to_string(threads) + (threads == 1 ? " drive" : " drives") + " at a time");
  md.str(report);
  md.seekp(0, std::ios_base::end);
  for (const std::string& f : *figures) md << "![" << f << "](figures/" << f << ")\n\n";
  md << "Cost grids: grey = cost (light free, dark high), red = lethal, black = unknown, "
     << "green outline = true obstacle cell; x to the right, y up, 4 px per 0.1 m cell. "
     << "Growth plots: lines = horizontal error of the believed sensor position against "
     << "distance driven, dots = each seen obstacle's distance to the nearest lethal cell at "
     << "the distance where it was first seen well (capped at the plot top), colour = "
     << "odometry drift level, all drives.\n";
  const std::pair<std::string, std::string> files[] = {{"runs.csv", runs},
                                                       {"obstacles.csv", obstacles},
                                                       {"tilt.csv", tilt_csv.str()},
                                                       {"REPORT.md", md.str()}};
  for (const auto& [name, text] : files) {
    if (Status st = util::WriteFileAtomic(out / name, text); !st) return st;
  }
  return Status::Ok();
}

}  // namespace cairn::eval
