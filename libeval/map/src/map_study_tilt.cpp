// The tilt study of the map report: each frame fused at the tilt of the odometry prior, the
// frame-to-map refiner or the gravity estimator, per error source, on the worlds of
// TiltWorlds().
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"
#include "map_study_parts.hpp"

namespace cairn::eval::study {
namespace {

using util::Fixed;

struct TiltSource {
  std::string label;
  DriftRunSpec spec;  // errors only
};

// Every error source is driven this many times on every world (seeds 1-3: the odometry's and
// the IMU's draws and the sensor's noise differ).
constexpr int kTiltSeeds = 3;

std::vector<TiltSource> TiltSources() {
  std::vector<TiltSource> out;
  for (const double bias_deg : {0.0, 1.0, 2.0, 3.0}) {
    TiltSource t{"attitude bias " + Fixed(bias_deg, 0) + " deg", {}};
    t.spec.imu_bias_rad = bias_deg * kDegToRad;
    out.push_back(t);
  }
  TiltSource accel{"bias 2 deg + accelerometer bias 0.1 m/s^2", {}};
  accel.spec.imu_bias_rad = 2.0 * kDegToRad;
  accel.spec.imu.accel_bias_mps2 = Eigen::Vector3d(0.1, -0.1, 0.05);
  out.push_back(accel);
  TiltSource gyro{"bias 2 deg + gyro drift 0.2 deg/s", {}};
  gyro.spec.imu_bias_rad = 2.0 * kDegToRad;
  gyro.spec.imu.gyro_bias_radps = Eigen::Vector3d(0.2, -0.2, 0.1) * kDegToRad;
  out.push_back(gyro);
  // About the camera's x axis (optical frame: x right), i.e. the camera pitched 2.5 deg
  // more than the mount says.
  TiltSource mount{"mount misaligned 2.5 deg (pitch)", {}};
  mount.spec.sensor_misalignment_rad = Eigen::Vector3d(2.5 * kDegToRad, 0.0, 0.0);
  out.push_back(mount);
  for (const double drift : {0.01, 0.03}) {
    TiltSource t{"bias 2 deg + odometry " + Fixed(drift * 100, 0) + "%", {}};
    t.spec.imu_bias_rad = 2.0 * kDegToRad;
    DriftOdometryBy(t.spec, drift);
    out.push_back(t);
  }
  for (TiltSource& t : out) t.spec.imu_sigma_rad = 0.3 * kDegToRad;
  return out;
}

// "floor" is no mode of the Mapper: the true roll, pitch and height with the odometry's x, y
// and heading (DriftRunSpec::truth_tilt_height), what every mode would reach with a perfect
// tilt; it is run where the odometry drifts.
// "smoothed" is the gravity mode's run posed again by its smoother once it is over and fused
// again at those poses (DriftRunSpec::smooth), as an offline map is built; "smoothed_free" the
// same without the frame-to-map ground heights (tilt.smooth_ground_sigma_m 0).
const char* const kTiltModes[] = {"prior",    "refine_to_map", "gravity",
                                  "smoothed", "smoothed_free", "floor"};
constexpr int kTiltModeCount = sizeof(kTiltModes) / sizeof(kTiltModes[0]);

// Mean |cost - cost at the true poses| over the cells both maps know, and the cells lethal
// here but free (below lethal) at the true poses.
std::pair<double, int> CostError(const DriftRunResult& r, const DriftRunResult& truth) {
  const std::optional<map::CellBox> box = truth.map().ObservedBounds();
  if (!box) return {0.0, 0};
  double sum = 0.0;
  int n = 0, false_lethal = 0;
  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      const map::Cell& t = truth.map().grid().At({i, j});
      const map::Cell& c = r.map().grid().At({i, j});
      if (t.cost == map::kUnknownCost || c.cost == map::kUnknownCost) continue;
      sum += std::abs(static_cast<int>(c.cost) - static_cast<int>(t.cost));
      ++n;
      false_lethal += c.lethal && !t.lethal;
    }
  }
  return {n > 0 ? sum / n : 0.0, false_lethal};
}

struct TiltWorld {
  std::string label, world;
  std::vector<Eigen::Vector2d> waypoints;
  double turn_radius_m = 0.0;  // 0: the corners sharp
  std::string note;            // printed under the world's table
};

const std::vector<TiltWorld>& TiltWorlds() {
  static const std::vector<TiltWorld> worlds = {
      {"uphill_tilted, 60 m",
       "uphill_tilted",
       {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}},
       0.0,
       "A nearly straight drive (corners of 11 and 14 deg), with trunks and poles up to x = 32 "
       "m only: the accelerometer's bias cannot be told from a tilt here (the body's attitude "
       "under gravity hardly changes), so it is flagged on most frames, and a bias beyond what "
       "the priors allow tilts the climb and drifts the height (the accelerometer bias row). "
       "The weaving drive below shows it observed. Smoothing the drive does not observe it "
       "either (0.088 m `smoothed`, 0.064 m `smoothed_free`); in the other rows here the "
       "smoother's ground is within 2 mm of the window's or closer to the truth, and its tilt's "
       "95th percentile 0.08-0.19 deg instead of 0.13-0.35."},
      {"hill (hill_drive), 36 m",
       "datasets/sequences/hill_drive/world.yaml",
       {{0.0, 0.0}, {12.0, 1.0}, {24.0, -1.0}, {36.0, 1.0}},
       0.0,
       ""},
      // Weaving up the same slope, +-40 deg about +x (the turns let the
      // accelerometer's bias be told from a tilt), corners rounded as a vehicle steers.
      {
          "uphill_tilted weaving (turns of 6 m radius), 66 m",
          "uphill_tilted",
          {{0.0, 0.0}, {12.0, 5.0}, {24.0, -5.0}, {36.0, 5.0}, {48.0, -5.0}, {58.0, 0.0}},
          6.0,
          "The same slope weaving +-40 deg about +x (the slope climbs towards 15 deg), the "
          "corners rounded as a vehicle steers (libsim's `turn_radius`; a sharp corner is a "
          "velocity jump no accelerometer reads). Each turn changes the body's attitude under "
          "gravity, which the gyro follows, so the accelerometer's bias is told from a tilt "
          "once the first turn is behind it (`accel flagged` against the straight drive's). The "
          "tilt's 95th percentile (0.22-0.28 deg, 0.44 with 3 % odometry) comes from the first "
          "frames, while the first trunks teach the mount and the turns the biases (a per-frame "
          "look at six of these drives, outside this report, found every frame more than 0.2 "
          "deg off among the first nine). With the camera scaled to 160 x 120, as this study "
          "had it until 2026-12-05, the trunks' axes lean three times as far from the vertical, "
          "and the mount row's 95th percentile was 0.78 deg and its ground 0.055 m in this "
          "report then. The height is worse than on the straight drive where no bias is added: "
          "the climb integrated over the first 20 m, while the biases are still unobserved, at "
          "a body pitch about 0.1 deg off, stays (the estimator's window slides past those "
          "frames, and nothing later sees the absolute height), and the odometry scale, which "
          "only the climbs observe, wanders by a few tenths of a percent. Its height error "
          "varies much from one drive (seed) to the next. The `smoothed` rows are what that "
          "costs an offline map: solved as a whole, the first frames have the biases and the "
          "mount learned later. Without odometry errors the tilt's 95th percentile falls to "
          "0.05-0.06 deg and the ground to 0.016-0.032 m; the frame-to-map heights, measured "
          "against the window's map, hold it back by a few millimetres on the attitude and gyro "
          "rows (not on the accelerometer's or the mount's), and `smoothed_free`, without them, "
          "is at 0.023-0.027 m. With 1 % odometry the ground is 0.017 m (0.013 free), with 3 % "
          "0.069 m (0.070).",
      },
      {"side slope (10 deg, uphill to the left) through sparse trees, 60 m",
       "datasets/maps/worlds/side_slope.yaml",
       {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}},
       0.0,
       ""},
      {"open field (no structure), 60 m",
       "datasets/maps/worlds/open_field.yaml",
       {{0.0, 0.0}, {20.0, 1.0}, {40.0, -2.0}, {60.0, 0.0}},
       0.0,
       ""},
  };
  return worlds;
}

/// One drive of the study: a world, an error source, a mode and a seed.
struct TiltDrive {
  int world = 0, source = 0, mode = 0, seed = 1;
};

std::vector<TiltDrive> TiltDrivesInOrder() {
  std::vector<TiltDrive> out;
  const std::vector<TiltSource> sources = TiltSources();
  for (int w = 0; w < static_cast<int>(TiltWorlds().size()); ++w) {
    for (int s = 0; s < static_cast<int>(sources.size()); ++s) {
      for (int m = 0; m < kTiltModeCount; ++m) {
        const bool floor = std::string(kTiltModes[m]) == "floor";
        if (floor && sources[s].spec.odom_sigma_per_m == 0.0) continue;
        for (int k = 1; k <= kTiltSeeds; ++k) out.push_back({w, s, m, k});
      }
    }
  }
  return out;
}

/// What one drive adds to the report.
struct TiltOutcome {
  std::vector<double> tilt_deg;
  double elevation_rms_m = 0.0, ground_rms_m = 0.0, cost_error = 0.0;
  int lethal_more = 0, degenerate_frames = 0, accel_flagged_frames = 0, frames = 0;
  std::vector<map::GravityDegeneracy> last_flags;
  double height_sigma_m = NAN;  // gravity: the estimator's own, at the end
  // Gravity: the estimator's tilt sigma per frame that has its covariance
  // (PoseError::tilt_sigma_rad), and how many of those frames have their tilt error in its 95 %
  // region (PoseError::tilt_nees <= kChiSquare2Dof95).
  std::vector<double> tilt_sigma_deg;
  int tilt_covered = 0;
};

// The 95 % quantile of the chi-square distribution with two degrees of freedom: -2 ln 0.05.
constexpr double kChiSquare2Dof95 = 5.991;

}  // namespace

int TiltStudyDrives() { return static_cast<int>(TiltWorlds().size() + TiltDrivesInOrder().size()); }

Status TiltStudy(const MapStudyOptions& options, Drives& drives, std::ostringstream& md,
                 std::ostringstream& csv) {
  const std::vector<TiltWorld>& worlds = TiltWorlds();
  const std::vector<TiltSource> sources = TiltSources();
  // The maps at the true poses, which the cost error is measured against.
  std::vector<std::optional<DriftRunResult>> truths(worlds.size());
  Status st = drives.Run(static_cast<int>(worlds.size()), [&](int w) -> Expected<std::string> {
    DriftRunSpec spec;
    spec.world = WorldFile(options, worlds[w].world);
    spec.settings = options.settings;
    spec.waypoints = worlds[w].waypoints;
    spec.turn_radius_m = worlds[w].turn_radius_m;
    spec.true_poses = true;
    Expected<DriftRunResult> r = RunDrift(spec);
    if (!r) return Error{worlds[w].label + ", true poses: " + r.error().message};
    truths[w].emplace(std::move(*r));
    return worlds[w].label + ", true poses";
  });
  if (!st) return st;
  const std::vector<TiltDrive> order = TiltDrivesInOrder();
  std::vector<TiltOutcome> outcomes(order.size());
  st = drives.Run(static_cast<int>(order.size()), [&](int k) -> Expected<std::string> {
    const TiltDrive& d = order[k];
    const TiltWorld& world = worlds[d.world];
    const std::string mode = kTiltModes[d.mode];
    DriftRunSpec spec = sources[d.source].spec;
    spec.world = WorldFile(options, world.world);
    spec.settings = options.settings;
    spec.waypoints = world.waypoints;
    spec.turn_radius_m = world.turn_radius_m;
    spec.drive_seed = static_cast<std::uint64_t>(d.seed);
    spec.refine_tilt = mode == "refine_to_map";
    spec.smooth = mode == "smoothed" || mode == "smoothed_free";
    spec.gravity = mode == "gravity" || spec.smooth;
    if (mode == "smoothed_free") {
      spec.configure = [](map::MapperConfig& c) { c.tilt.smooth_ground_sigma_m = 0.0; };
    }
    spec.truth_tilt_height = mode == "floor";
    Expected<DriftRunResult> r = RunDrift(spec);
    if (!r) {
      return Error{world.label + ", " + sources[d.source].label + ", " + mode + ": " +
                   r.error().message};
    }
    TiltOutcome& o = outcomes[k];
    for (const PoseError& e : r->pose_errors) {
      o.tilt_deg.push_back(e.tilt_rad / kDegToRad);
      if (std::isfinite(e.tilt_nees)) {
        o.tilt_covered += e.tilt_nees <= kChiSquare2Dof95 ? 1 : 0;
        o.tilt_sigma_deg.push_back(e.tilt_sigma_rad / kDegToRad);
      }
    }
    std::tie(o.cost_error, o.lethal_more) = CostError(*r, *truths[d.world]);
    o.elevation_rms_m = r->score.elevation_rms_m;
    o.ground_rms_m = r->ground_height_rms_m;
    o.degenerate_frames = r->degenerate_frames;
    o.accel_flagged_frames = r->accel_bias_flagged_frames;
    o.frames = r->frames;
    o.last_flags = r->last_degeneracies;
    o.height_sigma_m = r->final_height_sigma_m;
    return world.label + ", " + sources[d.source].label + ", " + mode + ", seed " +
           std::to_string(d.seed) + ": tilt " + Fixed(Quantile(o.tilt_deg, 0.5), 2) + " / " +
           Fixed(Quantile(o.tilt_deg, 0.95), 2) + " deg, elevation RMS " +
           Fixed(o.elevation_rms_m, 3) + " m, ground RMS " + Fixed(o.ground_rms_m, 3) + " m";
  });
  if (!st) return st;

  csv << "world,drive,error_source,mode,seed,frames,tilt_median_deg,tilt_p95_deg,elevation_rms_m,"
         "ground_height_rms_m,cost_error,false_lethal_vs_truth,degenerate_frames,"
         "accel_bias_flagged_frames,"
         "final_height_sigma_m,tilt_stated_frames,tilt_covered_frames,last_flags\n";
  md << "## Tilt: the odometry prior, the frame-to-map refiner and the gravity estimator\n\n"
     << "Each frame is fused at the tilt one of three modes gives (`tilt.mode`, "
     << "`cairn map --tilt`): `prior` (the odometry pose: roll and pitch from the IMU's "
     << "attitude output, height dead-reckoned from it), `refine_to_map` (Ceres against the "
     << "terrain fused so far) and `gravity` (`map::GravityEstimator` over a 12-frame window: "
     << "the raw accelerometer and gyro at 100 Hz, the odometry, the IMU attitude as a prior, "
     << "the trunks, poles and walls the detector found, `map/gravity_cues.hpp`, and each "
     << "frame's ground against the ground the frame two before saw there, "
     << "`tilt.gravity.rise_frames_back`: a rise measured by the sensor, against the wheels' "
     << "climb, which tells the sensor's tilt from the body's), or the gravity mode's drive "
     << "smoothed: `smoothed` is that drive posed again once it is over (`tilt.smooth`, "
        "`map::GravitySmoother`: "
     << "every frame solved together, so the biases and the mount learned at the first turn "
     << "or the first trunks apply from the first frame on; `cairn map --smooth`) and fused "
     << "again at those poses, as an offline map is built; the smoother takes the frame-to-map "
     << "ground heights the gravity mode measured, against a map fused at the window's "
     << "estimates, with a sigma of their own (`tilt.gravity.smooth_ground_sigma_m`, 0.9 m), and "
     << "`smoothed_free` leaves them out (0). The "
     << "error sources are set one at a time on top of the IMU attitude noise (0.3 deg); "
     << "`tilt` is the angle between the fused and the true up vector of the sensor over "
     << "every frame of every drive (median and 95th percentile), `cost err` the mean "
     << "absolute difference of the cost grid from the one fused at the true poses (nav2 "
     << "values 0-254, cells both know), `lethal+` the cells lethal here but not at the true "
     << "poses, `flagged` the frames where the estimator said a state was not observable "
     << "(`accel flagged`: the accelerometer bias among them), "
     << "`height sigma` the estimator's own height sigma for the drive's last frame (what it "
     << "says it knows, to read against the ground RMS; mean over the drives), `stated tilt` "
     << "the median over the frames of the tilt error the estimator expects (the RMS its "
     << "covariance gives, to read against the tilt median), `tilt in 95 %` "
     << "the frames whose tilt error lies in the 95 % region of the estimator's own covariance "
     << "of the sensor's up vector (`GravityEstimate::up_sensor_covariance`, from the frame's "
     << "attitude, the mount and their cross terms; 95 % of them where that covariance is "
     << "right, fewer where the estimator is overconfident).\n\n"
     << "Two elevation errors: `elevation RMS` compares the grid with the true terrain at the "
     << "same x, y, so it also holds the odometry's horizontal drift, which no tilt corrects "
     << "(x, y and heading come from the odometry in every mode); `ground RMS` is the height "
     << "at which each frame's terrain returns within the map's range were fused against the "
     << "true terrain under their true position: the error the fused tilt and height put into "
     << "the map. Where the odometry drifts, `floor` fuses the true roll, pitch and height with "
     << "the odometry's x, y and heading: the elevation RMS a perfect tilt would leave.\n\n";
  std::size_t next = 0;  // outcomes are in the order of these loops
  for (std::size_t w = 0; w < worlds.size(); ++w) {
    const TiltWorld& world = worlds[w];
    md << "### " << world.label << "\n\n"
       << "| error source | mode | drives | tilt median [deg] | tilt 95th [deg] | elevation RMS "
          "[m] "
          "| ground RMS [m] | cost err | lethal+ | flagged | accel flagged | height sigma [m] "
          "| stated tilt [deg] | tilt in 95 % |\n"
       << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- "
          "|\n";
    // The states flagged at a gravity drive's end: by name, in how many drives.
    std::map<std::string, int> flags;
    int gravity_drives = 0;
    for (const TiltSource& source : sources) {
      for (const char* mode : kTiltModes) {
        if (std::string(mode) == "floor" && source.spec.odom_sigma_per_m == 0.0) continue;
        std::vector<double> tilt_deg;
        double rms = 0.0, ground = 0.0, cost = 0.0;
        int lethal_more = 0, flagged = 0, accel_flagged = 0, frames = 0;
        double height_sigma = 0.0;
        int tilt_covered = 0;
        std::vector<double> tilt_sigma_deg;
        const int n = kTiltSeeds;
        for (int k = 0; k < n; ++k) {
          const TiltOutcome& o = outcomes[next++];
          tilt_deg.insert(tilt_deg.end(), o.tilt_deg.begin(), o.tilt_deg.end());
          rms += o.elevation_rms_m;
          ground += o.ground_rms_m;
          cost += o.cost_error;
          lethal_more += o.lethal_more;
          flagged += o.degenerate_frames;
          accel_flagged += o.accel_flagged_frames;
          frames += o.frames;
          height_sigma += o.height_sigma_m;
          tilt_covered += o.tilt_covered;
          tilt_sigma_deg.insert(tilt_sigma_deg.end(), o.tilt_sigma_deg.begin(),
                                o.tilt_sigma_deg.end());
          if (std::string(mode) == "gravity") {
            ++gravity_drives;
            for (const map::GravityDegeneracy& f : o.last_flags) ++flags[map::StateName(f.state)];
          }
          std::string last;
          for (const map::GravityDegeneracy& f : o.last_flags) {
            last += (last.empty() ? "" : " | ") + f.reason;
          }
          csv << world.world << ",\"" << world.label << "\"," << source.label << "," << mode << ","
              << k + 1 << "," << o.frames << "," << Fixed(Quantile(o.tilt_deg, 0.5), 3) << ","
              << Fixed(Quantile(o.tilt_deg, 0.95), 3) << "," << Fixed(o.elevation_rms_m, 4) << ","
              << Fixed(o.ground_rms_m, 4) << "," << Fixed(o.cost_error, 2) << "," << o.lethal_more;
          if (std::string(mode).rfind("smoothed", 0) == 0) {
            csv << ",,,,,,\"\"\n";  // the flags and sigma are the window's: its own row has them
          } else {
            csv << "," << o.degenerate_frames << "," << o.accel_flagged_frames << ","
                << (std::isfinite(o.height_sigma_m) ? Fixed(o.height_sigma_m, 4) : std::string())
                << "," << o.tilt_sigma_deg.size() << "," << o.tilt_covered << ",\"" << last
                << "\"\n";
          }
        }
        md << "| " << source.label << " | " << mode << " | " << n << " | "
           << Fixed(Quantile(tilt_deg, 0.5), 2) << " | " << Fixed(Quantile(tilt_deg, 0.95), 2)
           << " | " << Fixed(rms / n, 3) << " | " << Fixed(ground / n, 3) << " | "
           << Fixed(cost / n, 1) << " | " << Fixed(static_cast<double>(lethal_more) / n, 1) << " | "
           << (std::string(mode) == "gravity"
                   ? std::to_string(flagged) + "/" + std::to_string(frames)
                   : std::string("-"))
           << " | "
           << (std::string(mode) == "gravity"
                   ? std::to_string(accel_flagged) + "/" + std::to_string(frames)
                   : std::string("-"))
           << " | "
           << (std::string(mode) == "gravity" && std::isfinite(height_sigma)
                   ? Fixed(height_sigma / n, 3)
                   : std::string("-"))
           << " | "
           << (tilt_sigma_deg.empty() ? std::string("-") : Fixed(Quantile(tilt_sigma_deg, 0.5), 2))
           << " | "
           << (!tilt_sigma_deg.empty()
                   ? std::to_string(tilt_covered) + "/" + std::to_string(tilt_sigma_deg.size())
                   : std::string("-"))
           << " |\n";
      }
    }
    md << "\n";
    if (!world.note.empty()) md << world.note << "\n\n";
    if (!flags.empty()) {
      md << "States the estimator flagged as not observable at the end of a drive here: ";
      bool first = true;
      for (const auto& [state, drives_flagged] : flags) {
        md << (first ? "" : "; ") << state << " (" << drives_flagged << " of " << gravity_drives
           << " gravity drives)";
        first = false;
      }
      md << "; `tilt.csv` gives each drive's reasons.\n\n";
    }
  }
  return Status::Ok();
}

}  // namespace cairn::eval::study
