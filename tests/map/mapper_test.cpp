// Mapper: the per-frame pipeline as one object. It fuses exactly what the hand-written loop
// (od::Detect, od::Classify, TerrainMap::Integrate) fuses; a Mapper saved after some frames,
// restored into a new one and fed the rest writes the same map files, byte for byte, as the
// one never interrupted (prior and refine_to_map tilt); frames it cannot use come back with
// their reason and change nothing; bad settings are refused naming the field.
#include "cairn/map/mapper.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "cairn/map/checkpoint.hpp"
#include "cairn/map/map_files.hpp"
#include "cairn/map/mapper_config_file.hpp"
#include "cairn/map/tilt_refiner.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "io/temp_dir.hpp"
#include "sim_frames.hpp"

namespace cairn::map {
namespace {

namespace fs = std::filesystem;
fs::path TempDir(const std::string& name) {
  return test::FreshDir("cairn_mapper_test", name);
}

/// A frame as a source gives it: points in the sensor frame, the odometry pose (here the
/// true pose tilted by a constant roll and pitch bias), the stamp.
struct InputFrame {
  od::RangeImage image;
  Eigen::Isometry3d T_world_sensor;
  double stamp_s = 0.0;
};

// A drive along +x past boxes and poles on a gentle slope: 12 frames of a small camera,
// 0.5 m apart, seen from the true pose and placed by a pose biased by `bias_rad`.
std::vector<InputFrame> Drive(double bias_rad) {
  sim::Scene scene(sim::Terrain::Slope(0.0, 4.0 * kDegToRad, 0.0));
  scene.AddBox(4.0, 0.5, {1.0, 1.0, 0.8}, 0.3, true, "box");
  scene.AddPole(6.0, 2.0, 0.1, 1.2, true, "pole");
  scene.AddBox(8.5, -1.5, {0.6, 0.8, 0.5}, 0.0, true, "rock");
  const sim::RangeCameraSpec spec = sim::RangeCameraSpec::Default().Scaled(120);
  std::vector<InputFrame> frames;
  for (int k = 0; k < 12; ++k) {
    const double x = 0.5 * k, y = 0.05 * k;
    const Eigen::Vector3d position(x, y, scene.terrain().Height(x, y) + 1.5);
    const double yaw = (1.0 * k - 4.0) * kDegToRad;
    sim::Camera camera =
        sim::Camera::FromAttitude(spec.model, position, yaw, 15.0 * kDegToRad, 0.0);
    Expected<sim::DepthFrame> depth = sim::RenderRangeCamera(scene, spec, camera, 11 + k);
    EXPECT_TRUE(depth.ok()) << (depth ? "" : depth.error().message);
    if (!depth) return {};
    const Eigen::Isometry3d believed = ApplyTiltCorrection(camera.T_world_camera, bias_rad, bias_rad, 0.0);
    // Levelled with any up vector: the Mapper replaces it with its prior's.
    Expected<od::RangeImage> image =
        od::RangeImage::FromDepth(depth->depth_m, depth->model, Eigen::Vector3d(0, -1, 0));
    EXPECT_TRUE(image.ok());
    if (!image) return {};
    frames.push_back({std::move(*image), believed, 0.5 * k});
  }
  return frames;
}

MapperConfig Config(TiltMode mode) {
  const Expected<od::io::DetectSettings> settings = test::DefaultDetectSettings();
  EXPECT_TRUE(settings.ok());
  MapperConfig config;
  if (settings) {
    config.detector = settings->detector;
    config.rules = settings->rules;
  }
  config.tilt.mode = mode;
  config.tilt.refiner.max_range_m = 12.0;
  return config;
}

std::string ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Every map file of `a` and `b`, byte for byte.
void ExpectSameMapFiles(const TerrainMap& a, const TerrainMap& b, const std::string& name) {
  const fs::path da = TempDir(name + "_a"), db = TempDir(name + "_b");
  ASSERT_TRUE(WriteMapFiles(a, da).ok());
  ASSERT_TRUE(WriteMapFiles(b, db).ok());
  int files = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(da)) {
    EXPECT_TRUE(ReadBytes(e.path()) == ReadBytes(db / e.path().filename()))
        << e.path().filename() << " differs";
    ++files;
  }
  EXPECT_EQ(files, 9);  // WriteMapFiles' nine
  fs::remove_all(da);
  fs::remove_all(db);
}

Expected<MapperRecord> Feed(Mapper& mapper, const InputFrame& f) {
  return mapper.Process(f.image, f.T_world_sensor, f.stamp_s);
}

// Prior tilt: the Mapper fuses exactly what the loop it replaces fused by hand.
TEST(Mapper, PriorTiltFusesWhatTheHandWrittenLoopFuses) {
  const std::vector<InputFrame> frames = Drive(0.0);
  ASSERT_EQ(frames.size(), 12u);
  const MapperConfig config = Config(TiltMode::kPrior);
  Expected<Mapper> mapper = Mapper::Create(config);
  ASSERT_TRUE(mapper.ok()) << mapper.error().message;
  Expected<TerrainMap> by_hand = TerrainMap::Create(config.map);
  ASSERT_TRUE(by_hand.ok());
  int kept = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const Expected<MapperRecord> r = Feed(*mapper, frames[k]);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->used());
    EXPECT_EQ(r->index, static_cast<std::int64_t>(k));
    EXPECT_FALSE(r->tilt.estimated);
    EXPECT_TRUE(r->T_world_sensor.matrix() == frames[k].T_world_sensor.matrix());
    od::RangeImage image = frames[k].image;
    const Eigen::Vector3d up =
        frames[k].T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    ASSERT_TRUE(image.SetUp(up).ok());
    const Expected<od::Detection> detection = od::Detect(image, config.detector);
    ASSERT_TRUE(detection.ok());
    const Expected<od::Classification> classes = od::Classify(*detection, config.rules);
    ASSERT_TRUE(classes.ok());
    EXPECT_EQ(r->segments, static_cast<int>(detection->segments.size()));
    EXPECT_EQ(r->kept, classes->kept);
    EXPECT_EQ(r->rejected, r->segments - r->kept);
    kept += r->kept;
    const Expected<FrameSummary> fused = by_hand->Integrate(
        image, *detection, *classes, frames[k].T_world_sensor, frames[k].stamp_s,
        static_cast<std::int64_t>(k));
    ASSERT_TRUE(fused.ok());
    EXPECT_EQ(r->fused.obstacle_points, fused->obstacle_points);
    EXPECT_EQ(r->fused.lethal_cells, fused->lethal_cells);
  }
  EXPECT_GT(kept, 5);
  EXPECT_EQ(mapper->frames_fused(), 12);
  EXPECT_FALSE(mapper->map().obstacles().empty());
  ExpectSameMapFiles(mapper->map(), *by_hand, "by_hand");
}

// Saved after 5 frames, restored into a new Mapper and fed the other 7: the same map files
// and the same fused poses as the run that was never interrupted, in both tilt modes (the
// refiner's correction is carried through the checkpoint).
void ExpectResumeGivesTheSameMap(TiltMode mode, double bias_rad,
                                 const std::function<void(MapperConfig&)>& tweak = {}) {
  const std::vector<InputFrame> frames = Drive(bias_rad);
  ASSERT_EQ(frames.size(), 12u);
  MapperConfig config = Config(mode);
  if (tweak) tweak(config);
  Expected<Mapper> whole = Mapper::Create(config);
  ASSERT_TRUE(whole.ok()) << whole.error().message;
  std::vector<MapperRecord> records;
  for (const InputFrame& f : frames) {
    Expected<MapperRecord> r = Feed(*whole, f);
    ASSERT_TRUE(r.ok()) << r.error().message;
    records.push_back(*r);
  }
  const fs::path dir = TempDir(std::string("resume_") + TiltModeName(mode));
  Expected<Mapper> first = Mapper::Create(config);
  ASSERT_TRUE(first.ok());
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(Feed(*first, frames[k]).ok());
  if (config.tilt.smooth) {
    // Smoothing changes nothing that is carried: twice the same, and saved after it the same.
    const Expected<std::vector<SmoothedFrame>> once = first->SmoothTilt();
    const Expected<std::vector<SmoothedFrame>> twice = first->SmoothTilt();
    ASSERT_TRUE(once.ok() && twice.ok());
    ASSERT_EQ(once->size(), 5u);
    for (std::size_t k = 0; k < once->size(); ++k) {
      EXPECT_TRUE((*once)[k].T_world_sensor.matrix() == (*twice)[k].T_world_sensor.matrix());
    }
  }
  ASSERT_TRUE(first->SaveCheckpoint(dir, "the caller's state").ok());
  std::string app_data;
  Expected<Mapper> resumed = Mapper::FromCheckpoint(dir, config, &app_data);
  ASSERT_TRUE(resumed.ok()) << resumed.error().message;
  EXPECT_EQ(app_data, "the caller's state");
  EXPECT_EQ(resumed->frames_fused(), 5);
  int applied = 0;
  for (std::size_t k = 5; k < frames.size(); ++k) {
    Expected<MapperRecord> r = Feed(*resumed, frames[k]);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->index, records[k].index);
    EXPECT_TRUE(r->T_world_sensor.matrix() == records[k].T_world_sensor.matrix()) << "frame " << k;
    EXPECT_EQ(r->tilt.roll_rad, records[k].tilt.roll_rad);
    EXPECT_EQ(r->tilt.pitch_rad, records[k].tilt.pitch_rad);
    EXPECT_EQ(r->tilt.dz_m, records[k].tilt.dz_m);
    applied += r->tilt.applied ? 1 : 0;
  }
  if (mode != TiltMode::kPrior) {
    EXPECT_GT(applied, 3);  // the carried state mattered
    EXPECT_NE(records.back().tilt.roll_rad, 0.0);
  }
  ExpectSameMapFiles(whole->map(), resumed->map(), std::string("resume_") + TiltModeName(mode));
  if (config.tilt.smooth) {  // the smoother's frames came back too
    const Expected<std::vector<SmoothedFrame>> a = whole->SmoothTilt();
    const Expected<std::vector<SmoothedFrame>> b = resumed->SmoothTilt();
    ASSERT_TRUE(a.ok() && b.ok());
    ASSERT_EQ(a->size(), frames.size());
    ASSERT_EQ(b->size(), frames.size());
    for (std::size_t k = 0; k < frames.size(); ++k) {
      EXPECT_EQ((*b)[k].stamp_s, frames[k].stamp_s);
      EXPECT_LT(((*a)[k].T_world_sensor.matrix() - (*b)[k].T_world_sensor.matrix()).norm(), 1e-9)
          << "frame " << k;
    }
  }
  fs::remove_all(dir);
}

// Each frame told ahead (Expect), so that it is levelled and detected while the one before
// is fused: the same records and map files as one Process call after the other, in every
// tilt mode (the prior the look-ahead levels with must be the one after the previous
// frame's estimate). A frame told wrongly (another stamp) is detected afresh.
void ExpectLookaheadChangesNothing(TiltMode mode, double bias_rad) {
  const std::vector<InputFrame> frames = Drive(bias_rad);
  ASSERT_EQ(frames.size(), 12u);
  const MapperConfig config = Config(mode);
  Expected<Mapper> plain = Mapper::Create(config);
  Expected<Mapper> ahead = Mapper::Create(config);
  ASSERT_TRUE(plain.ok() && ahead.ok());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (k + 1 < frames.size()) {
      const InputFrame& next = frames[k + 1];
      // Frame 6 is told with another stamp: its look-ahead must not be taken.
      ahead->Expect(next.image, next.T_world_sensor, next.stamp_s + (k + 1 == 6 ? 0.01 : 0.0));
    }
    const Expected<MapperRecord> a = Feed(*plain, frames[k]);
    const Expected<MapperRecord> b = Feed(*ahead, frames[k]);
    ASSERT_TRUE(a.ok() && b.ok());
    EXPECT_EQ(a->valid_points, b->valid_points) << "frame " << k;
    EXPECT_EQ(a->segments, b->segments) << "frame " << k;
    EXPECT_EQ(a->kept, b->kept) << "frame " << k;
    EXPECT_TRUE(a->T_world_sensor.matrix() == b->T_world_sensor.matrix()) << "frame " << k;
    EXPECT_EQ(a->fused.obstacle_points, b->fused.obstacle_points) << "frame " << k;
    EXPECT_EQ(a->fused.voxels_free, b->fused.voxels_free) << "frame " << k;
  }
  ExpectSameMapFiles(plain->map(), ahead->map(), std::string("ahead_") + TiltModeName(mode));
}

TEST(Mapper, FramesToldAheadGiveTheSameMapInEveryTiltMode) {
  ExpectLookaheadChangesNothing(TiltMode::kPrior, 0.0);
  ExpectLookaheadChangesNothing(TiltMode::kRefineToMap, 1.5 * kDegToRad);
  ExpectLookaheadChangesNothing(TiltMode::kGravity, 1.0 * kDegToRad);
}

// The gravity step carries its estimate to the next frame's prior as a correction of the
// body (its roll, pitch and height) with the mount as estimated: the prior of the pose just fused
// is the pose the estimate fused it at, the sensor's position included. (Turning the sensor
// about itself instead left the sensor 1.5 m above the body where the odometry's tilt put
// it: 8 cm sideways for each 3 deg of tilt, which on a slope the frame-to-map ground height
// took for a height error.)
TEST(Mapper, TheGravityPriorPutsTheSensorWhereTheEstimateDid) {
  const std::vector<InputFrame> frames = Drive(3.0 * kDegToRad);
  ASSERT_EQ(frames.size(), 12u);
  Expected<Mapper> mapper = Mapper::Create(Config(TiltMode::kGravity));
  ASSERT_TRUE(mapper.ok()) << mapper.error().message;
  // A camera (optical frame: x right, y down, z forward) 1.5 m above the body, 0.4 m ahead.
  Eigen::Isometry3d T_body_sensor = Eigen::Isometry3d::Identity();
  T_body_sensor.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_body_sensor.translation() = Eigen::Vector3d(0.4, 0.0, 1.5);
  ASSERT_TRUE(mapper->SetSensorMount(T_body_sensor).ok());
  int applied = 0;
  for (const InputFrame& f : frames) {
    const Expected<MapperRecord> r = Feed(*mapper, f);
    ASSERT_TRUE(r.ok()) << r.error().message;
    if (!r->tilt.applied) continue;
    ++applied;
    const Eigen::Isometry3d prior = mapper->tilt().Prior(f.T_world_sensor);
    EXPECT_LT((prior.translation() - r->T_world_sensor.translation()).norm(), 1e-9);
    EXPECT_LT((prior.linear() - r->T_world_sensor.linear()).norm(), 1e-9);
    // The estimate moved the sensor sideways from where the odometry had it.
    EXPECT_GT((r->T_world_sensor.translation() - f.T_world_sensor.translation()).head<2>().norm(),
              0.01);

    // The correction is the roll and pitch added to the odometry's (the IMU's attitude
    // output, whose bias is in those angles): a pose turned by 90 deg gets the same added
    // angles. (A rotation about world axes, carried through the turn, would put a pitch
    // correction into the roll.)
    ASSERT_TRUE(r->tilt.gravity.has_value());
    const Eigen::Vector2d m = r->tilt.gravity->mount_rad;
    Eigen::Isometry3d mount = T_body_sensor;
    mount.linear() = Eigen::AngleAxisd(m.y(), Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(m.x(), Eigen::Vector3d::UnitX()) * T_body_sensor.linear();
    const auto added = [&](const Eigen::Isometry3d& T_world_sensor) {
      const Eigen::Matrix3d odometry = (T_world_sensor * T_body_sensor.inverse()).linear();
      const Eigen::Matrix3d corrected =
          (mapper->tilt().Prior(T_world_sensor) * mount.inverse()).linear();
      const auto roll_pitch = [](const Eigen::Matrix3d& R) {
        return Eigen::Vector2d(std::atan2(R(2, 1), R(2, 2)),
                               std::atan2(-R(2, 0), std::hypot(R(0, 0), R(1, 0))));
      };
      return Eigen::Vector2d(roll_pitch(corrected) - roll_pitch(odometry));
    };
    Eigen::Isometry3d turned = f.T_world_sensor;
    turned.linear() =
        Eigen::AngleAxisd(0.5 * kPi, Eigen::Vector3d::UnitZ()) * f.T_world_sensor.linear();
    EXPECT_LT((added(turned) - added(f.T_world_sensor)).norm(), 1e-9);
    EXPECT_GT(added(f.T_world_sensor).norm(), 0.5 * kDegToRad);  // there is a correction
  }
  EXPECT_GT(applied, 8);

  // A state saved by a cairn whose prior corrected the tilt about world axes (a rotation
  // matrix, "correction") is refused with the reason, not read as angles.
  const std::string saved = mapper->tilt().SaveState();
  Expected<std::unique_ptr<TiltStep>> step = MakeTiltStep(Config(TiltMode::kGravity).tilt);
  ASSERT_TRUE(step.ok()) << step.error().message;
  ASSERT_TRUE((*step)->RestoreState(saved).ok());
  std::string old = saved;
  const std::size_t key = old.find("\"attitude_correction\"");
  ASSERT_NE(key, std::string::npos);
  old.replace(key, std::string("\"attitude_correction\"").size(), "\"correction\"");
  const Status refused = (*step)->RestoreState(old);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("earlier cairn"), std::string::npos) << refused.message();
}

TEST(Mapper, ResumedWithPriorTiltGivesTheSameMap) {
  ExpectResumeGivesTheSameMap(TiltMode::kPrior, 0.0);
}

TEST(Mapper, ResumedWithTheTiltRefinerGivesTheSameMap) {
  ExpectResumeGivesTheSameMap(TiltMode::kRefineToMap, 1.0 * kDegToRad);
}

// The gravity step's estimator state (its window, priors and slow states) comes back from the
// checkpoint: the resumed run fuses at bit-identical poses. (Saved here before the window
// fills; GravityEstimator.ARestoredState... saves one that has marginalised frames.)
TEST(Mapper, ResumedWithTheGravityEstimatorGivesTheSameMap) {
  ExpectResumeGivesTheSameMap(TiltMode::kGravity, 1.0 * kDegToRad);
}

// With tilt.smooth the checkpoint holds every frame the smoother was given: the resumed run's
// smoothed poses are those of the run never interrupted. A checkpoint saved without it cannot
// be smoothed and is refused; a step that keeps no record says so.
TEST(Mapper, ResumedWithTheSmootherGivesTheSameSmoothedPoses) {
  ExpectResumeGivesTheSameMap(TiltMode::kGravity, 1.0 * kDegToRad, [](MapperConfig& c) {
    c.tilt.gravity.window_frames = 4;
    c.tilt.smooth = true;
  });
  const std::vector<InputFrame> frames = Drive(1.0 * kDegToRad);
  Expected<Mapper> plain = Mapper::Create(Config(TiltMode::kGravity));
  ASSERT_TRUE(plain.ok());
  for (int k = 0; k < 3; ++k) ASSERT_TRUE(Feed(*plain, frames[k]).ok());
  const Expected<std::vector<SmoothedFrame>> none = plain->SmoothTilt();
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("tilt.smooth"), std::string::npos) << none.error().message;
  const fs::path dir = TempDir("resume_unsmoothed");
  ASSERT_TRUE(plain->SaveCheckpoint(dir).ok());
  MapperConfig smoothing = Config(TiltMode::kGravity);
  smoothing.tilt.smooth = true;
  const Expected<Mapper> refused = Mapper::FromCheckpoint(dir, smoothing);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("tilt.smooth"), std::string::npos)
      << refused.error().message;
  fs::remove_all(dir);
  Expected<Mapper> prior = Mapper::Create(Config(TiltMode::kPrior));
  ASSERT_TRUE(prior.ok());
  ASSERT_TRUE(Feed(*prior, frames[0]).ok());
  EXPECT_FALSE(prior->SmoothTilt().ok());
}

// The odometry jumps 80 m at frame 6 and stays there: the first pass skips frame 6 and fuses
// the rest. Fused again at the smoothed poses, frame 7 follows frame 5, 80 m in 1 s: the second
// pass's settings (SmoothedPassConfig) take the frames the first pass vetted as they come,
// where a Mapper of the first pass's (50 m/s at most) would skip it as a jump. Each smoothed
// frame's roll and pitch correction is its fused body's against the odometry's, as the
// window's records have it (TiltOutcome).
TEST(Mapper, TheSmoothedPassFusesEveryFrameTheFirstPassFused) {
  std::vector<InputFrame> frames = Drive(1.0 * kDegToRad);
  for (std::size_t k = 6; k < frames.size(); ++k)
    frames[k].T_world_sensor.translation().x() += 80.0;
  MapperConfig config = Config(TiltMode::kGravity);
  config.tilt.smooth = true;
  Expected<Mapper> first = Mapper::Create(config);
  ASSERT_TRUE(first.ok());
  std::vector<double> fused_stamps;
  for (const InputFrame& f : frames) {
    const Expected<MapperRecord> r = Feed(*first, f);
    ASSERT_TRUE(r.ok()) << r.error().message;
    if (r->used()) fused_stamps.push_back(f.stamp_s);
  }
  ASSERT_EQ(fused_stamps.size(), frames.size() - 1);  // frame 6 skipped
  const Expected<std::vector<SmoothedFrame>> poses = first->SmoothTilt();
  ASSERT_TRUE(poses.ok()) << poses.error().message;
  ASSERT_EQ(poses->size(), fused_stamps.size());
  std::size_t next = 0;
  for (const InputFrame& f : frames) {
    if (next >= poses->size() || (*poses)[next].stamp_s != f.stamp_s) continue;
    // No mount set: the body is the sensor's frame.
    const sim::Attitude fused = sim::AttitudeFromRotation((*poses)[next].T_world_sensor.linear());
    const sim::Attitude odometry = sim::AttitudeFromRotation(f.T_world_sensor.linear());
    EXPECT_NEAR((*poses)[next].roll_rad, fused.roll_rad - odometry.roll_rad, 1e-9);
    EXPECT_NEAR((*poses)[next].pitch_rad, fused.pitch_rad - odometry.pitch_rad, 1e-9);
    ++next;
  }
  for (int plain = 0; plain < 2; ++plain) {
    MapperConfig second = SmoothedPassConfig(config);
    EXPECT_EQ(second.tilt.mode, TiltMode::kPrior);
    EXPECT_FALSE(second.tilt.smooth);
    if (plain == 1) second.frames = config.frames;
    Expected<Mapper> again = Mapper::Create(second);
    ASSERT_TRUE(again.ok()) << again.error().message;
    int used = 0;
    std::size_t k = 0;
    for (const InputFrame& f : frames) {
      if (k >= poses->size() || (*poses)[k].stamp_s != f.stamp_s) continue;
      const Expected<MapperRecord> r =
          again->Process(f.image, (*poses)[k].T_world_sensor, f.stamp_s);
      ASSERT_TRUE(r.ok()) << r.error().message;
      used += r->used() ? 1 : 0;
      if (r->used()) {
        EXPECT_TRUE(r->T_world_sensor.matrix() == (*poses)[k].T_world_sensor.matrix());
      }
      ++k;
    }
    if (plain == 0) {
      EXPECT_EQ(used, static_cast<int>(poses->size()));
    } else {
      EXPECT_EQ(used, static_cast<int>(poses->size()) - 1);  // frame 7, a jump from frame 5
    }
  }
}

// With a 4-frame window the ground rises begin at the 5th frame: the checkpoint after it holds
// the last frames' ground and a rise in the window, and the resumed run, fitting its rises
// to the restored ground, still fuses at bit-identical poses.
TEST(Mapper, ResumedWithTheGravityEstimatorsGroundRisesGivesTheSameMap) {
  ExpectResumeGivesTheSameMap(TiltMode::kGravity, 1.0 * kDegToRad, [](MapperConfig& c) {
    c.tilt.gravity.window_frames = 4;
    c.tilt.gravity_rise_frames_back = 2;
  });
  // The rises were there.
  const std::vector<InputFrame> frames = Drive(1.0 * kDegToRad);
  MapperConfig config = Config(TiltMode::kGravity);
  config.tilt.gravity.window_frames = 4;
  Expected<Mapper> mapper = Mapper::Create(config);
  ASSERT_TRUE(mapper.ok());
  int rises = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    Expected<MapperRecord> r = Feed(*mapper, frames[k]);
    ASSERT_TRUE(r.ok()) << r.error().message;
    ASSERT_TRUE(r->tilt.gravity.has_value());
    if (k < 4) {
      EXPECT_EQ(r->tilt.gravity->cues.ground_rises, 0) << "frame " << k;
    }
    rises += r->tilt.gravity->cues.ground_rises;
  }
  EXPECT_GT(rises, 5);
}

TEST(Mapper, ACheckpointOfAnotherTiltModeIsRefused) {
  const std::vector<InputFrame> frames = Drive(0.0);
  ASSERT_FALSE(frames.empty());
  Expected<Mapper> mapper = Mapper::Create(Config(TiltMode::kRefineToMap));
  ASSERT_TRUE(mapper.ok());
  ASSERT_TRUE(Feed(*mapper, frames[0]).ok());
  const fs::path dir = TempDir("mode");
  ASSERT_TRUE(mapper->SaveCheckpoint(dir).ok());
  const Expected<Mapper> other = Mapper::FromCheckpoint(dir, Config(TiltMode::kPrior));
  ASSERT_FALSE(other.ok());
  EXPECT_NE(other.error().message.find("refine_to_map"), std::string::npos)
      << other.error().message;
  EXPECT_NE(other.error().message.find((dir / kCheckpointFileName).string()), std::string::npos)
      << other.error().message;
  fs::remove_all(dir);
}

// A frame without a valid return, and one whose pose jumps 40 m in half a second, come back
// skipped with their reason; the map is the one made without them.
TEST(Mapper, FramesItCannotUseAreSkippedWithTheirReasonAndChangeNothing) {
  const std::vector<InputFrame> frames = Drive(0.0);
  ASSERT_EQ(frames.size(), 12u);
  const MapperConfig config = Config(TiltMode::kPrior);
  Expected<Mapper> clean = Mapper::Create(config);
  Expected<Mapper> with_bad = Mapper::Create(config);
  ASSERT_TRUE(clean.ok() && with_bad.ok());
  const od::PinholeModel& model = std::get<od::PinholeModel>(frames[0].image.model());
  const std::vector<float> no_returns(static_cast<std::size_t>(model.width) * model.height, 0.0f);
  Expected<od::RangeImage> empty = od::RangeImage::FromDepth(no_returns, model, Eigen::Vector3d(0, -1, 0));
  ASSERT_TRUE(empty.ok());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    ASSERT_TRUE(Feed(*clean, frames[k]).ok());
    if (k == 4) {
      // Between frames 4 and 5 (in time), no returns at all.
      const Expected<MapperRecord> r =
          (*with_bad).Process(*empty, frames[k].T_world_sensor, frames[k].stamp_s + 0.25);
      ASSERT_TRUE(r.ok()) << r.error().message;
      EXPECT_EQ(r->skip, FrameSkip::kNoValidPoints);
      EXPECT_STREQ(FrameSkipName(r->skip), "no valid points");
      EXPECT_EQ(r->valid_points, 0);
    }
    if (k == 8) {
      // A pose 40 m off, 0.25 s after frame 7: 160 m/s.
      Eigen::Isometry3d jumped = frames[k].T_world_sensor;
      jumped.translation().x() += 40.0;
      const Expected<MapperRecord> r =
          (*with_bad).Process(frames[k].image, jumped, frames[k].stamp_s - 0.25);
      ASSERT_TRUE(r.ok()) << r.error().message;
      EXPECT_EQ(r->skip, FrameSkip::kPoseJump);
      EXPECT_NE(r->skip_detail.find("m in 0.250 s"), std::string::npos) << r->skip_detail;
      // The next frame jumps back from the skipped one's pose: skipped too, then the drive
      // goes on.
      const Expected<MapperRecord> back = Feed(*with_bad, frames[k]);
      ASSERT_TRUE(back.ok());
      EXPECT_EQ(back->skip, FrameSkip::kPoseJump);
      continue;
    }
    const Expected<MapperRecord> r = Feed(*with_bad, frames[k]);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_TRUE(r->used()) << "frame " << k << ": " << FrameSkipName(r->skip);
  }
  EXPECT_EQ(with_bad->frames_processed(), 14);
  EXPECT_EQ(with_bad->frames_fused(), 11);
  // The clean run without frame 8.
  Expected<Mapper> reference = Mapper::Create(config);
  ASSERT_TRUE(reference.ok());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (k == 8) continue;
    ASSERT_TRUE(Feed(*reference, frames[k]).ok());
  }
  ExpectSameMapFiles(reference->map(), with_bad->map(), "skips");
}

TEST(Mapper, ANonFinitePoseIsAnErrorAndChangesNothing) {
  const std::vector<InputFrame> frames = Drive(0.0);
  ASSERT_FALSE(frames.empty());
  Expected<Mapper> mapper = Mapper::Create(Config(TiltMode::kPrior));
  ASSERT_TRUE(mapper.ok());
  Eigen::Isometry3d bad = frames[0].T_world_sensor;
  bad.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE((*mapper).Process(frames[0].image, bad, 0.0).ok());
  EXPECT_EQ(mapper->frames_processed(), 0);
}

TEST(MapperConfig, ValidateNamesTheBadField) {
  MapperConfig config;
  EXPECT_TRUE(config.Validate().ok());
  config.frames.max_speed_mps = 0.0;
  ASSERT_FALSE(config.Validate().ok());
  EXPECT_NE(config.Validate().message().find("max_speed"), std::string::npos);
  config = MapperConfig{};
  config.tilt.refiner.min_points = 1;
  ASSERT_FALSE(config.Validate().ok());
  EXPECT_NE(config.Validate().message().find("min_points"), std::string::npos);
  config = MapperConfig{};
  config.map.cell_size_m = -1.0;
  EXPECT_NE(config.Validate().message().find("cell_size"), std::string::npos);
  EXPECT_FALSE(Mapper::Create(config).ok());
}

TEST(MapperSettings, EverySectionOfTheFileIsReadStrictly) {
  const Expected<MapperSettings> s = ParseMapperSettings(
      "detector:\n  min_height: 0.25\nmap:\n  cell_size: 0.25\ntilt:\n  refine: true\n"
      "  prior_sigma: 1.5\n  max_points: 900\nframes:\n  max_speed: 20\n  max_turn_rate: 90\n"
      "  min_valid_points: 100\n",
      "test.yaml");
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_DOUBLE_EQ(s->mapper.detector.min_height_m, 0.25);
  EXPECT_DOUBLE_EQ(s->mapper.map.cell_size_m, 0.25);
  EXPECT_EQ(s->mapper.tilt.mode, TiltMode::kRefineToMap);
  EXPECT_DOUBLE_EQ(s->mapper.tilt.refiner.prior_sigma_rad, 1.5 * kDegToRad);
  EXPECT_EQ(s->mapper.tilt.refiner.max_points, 900);
  EXPECT_DOUBLE_EQ(s->mapper.frames.max_speed_mps, 20.0);
  EXPECT_DOUBLE_EQ(s->mapper.frames.max_turn_rate_radps, 90.0 * kDegToRad);
  EXPECT_EQ(s->mapper.frames.min_valid_points, 100);
  EXPECT_TRUE(ParseMapperSettings("", "empty.yaml").ok());
  EXPECT_TRUE(ParseMapperSettings("tilt:\n  refine: false\n", "only_tilt.yaml").ok());
  const auto fails_naming = [](const std::string& text, const std::string& field) {
    const Expected<MapperSettings> bad = ParseMapperSettings(text, "bad.yaml");
    ASSERT_FALSE(bad.ok()) << text;
    EXPECT_NE(bad.error().message.find("bad.yaml"), std::string::npos) << bad.error().message;
    EXPECT_NE(bad.error().message.find(field), std::string::npos) << bad.error().message;
  };
  fails_naming("tilt:\n  prior_sigm: 2\n", "tilt.prior_sigm");
  fails_naming("tilt:\n  refine: maybe\n", "tilt.refine");
  fails_naming("tilt:\n  min_points: 2\n", "min_points");
  fails_naming("frames:\n  max_speed: -1\n", "frames.max_speed");
  fails_naming("frames:\n  min_valid_points: 0\n", "frames.min_valid_points");
  fails_naming("frames:\n  speed: 3\n", "frames.speed");
  fails_naming("map:\n  cel_size: 0.2\n", "map.cel_size");
  fails_naming("detector:\n  min_hieght: 0.3\n", "detector.min_hieght");
  fails_naming("tlit:\n  refine: true\n", "tlit");
}

TEST(MapperSettings, TheGravityEstimatorsNoisesAndTheVerticalCuesAreSetInTheFile) {
  const Expected<MapperSettings> s = ParseMapperSettings(
      "tilt:\n  mode: gravity\n  smooth: true\n  gravity:\n    window_frames: 16\n"
      "    accel_sigma_mps2: 0.05\n"
      "    odometry_walk_sigma: 0.03\n    gyro_sigma_radps: 0.004\n"
      "    attitude_prior_sigma_rad: 0.02\n    estimate_mount: false\n    covariance: false\n"
      "    ground_sigma_m: 0.2\n    ground_min_verticals: 3\n"
      "    rise_frames_back: 5\n    rise_sigma_m: 0.03\n    smooth_ground_sigma_m: 1.5\n"
      "  verticals:\n    min_height: 1.5\n    max_angle: 10\n    min_points: 60\n"
      "    walls: false\n",
      "test.yaml");
  ASSERT_TRUE(s.ok()) << s.error().message;
  const TiltConfig& t = s->mapper.tilt;
  EXPECT_EQ(t.mode, TiltMode::kGravity);
  EXPECT_TRUE(t.smooth);
  EXPECT_EQ(t.gravity.window_frames, 16);
  EXPECT_DOUBLE_EQ(t.gravity.accel_sigma_mps2, 0.05);
  EXPECT_DOUBLE_EQ(t.gravity.odometry_walk_sigma, 0.03);
  EXPECT_DOUBLE_EQ(t.gravity.gyro_sigma_radps, 0.004);
  EXPECT_DOUBLE_EQ(t.gravity.attitude_prior_sigma_rad, 0.02);
  EXPECT_FALSE(t.gravity.estimate_mount);
  EXPECT_TRUE(t.gravity.estimate_accel_bias);  // not given: the default
  EXPECT_FALSE(t.gravity.covariance);
  EXPECT_DOUBLE_EQ(t.gravity_ground_sigma_m, 0.2);
  EXPECT_EQ(t.gravity_ground_min_verticals, 3);
  EXPECT_EQ(t.gravity_rise_frames_back, 5);
  EXPECT_DOUBLE_EQ(t.gravity_rise_sigma_m, 0.03);
  EXPECT_DOUBLE_EQ(t.smooth_ground_sigma_m, 1.5);
  EXPECT_DOUBLE_EQ(t.verticals.min_height_m, 1.5);
  EXPECT_DOUBLE_EQ(t.verticals.max_angle_rad, 10.0 * kDegToRad);
  EXPECT_EQ(t.verticals.min_points, 60);
  EXPECT_FALSE(t.verticals.walls);
  EXPECT_TRUE(ParseMapperSettings("tilt:\n  gravity:\n  verticals:\n", "empty.yaml").ok());
  const auto fails_naming = [](const std::string& text, const std::string& field) {
    const Expected<MapperSettings> bad = ParseMapperSettings(text, "bad.yaml");
    ASSERT_FALSE(bad.ok()) << text;
    EXPECT_NE(bad.error().message.find("bad.yaml: " + field + ":"), std::string::npos)
        << bad.error().message;
  };
  fails_naming("tilt:\n  gravity:\n    accel_sigma: 0.05\n", "tilt.gravity.accel_sigma");
  fails_naming("tilt:\n  gravity:\n    odometry_walk_sigma: -0.01\n",
               "tilt.gravity.odometry_walk_sigma");
  fails_naming("tilt:\n  gravity:\n    ground_sigma_m: 0\n", "tilt.gravity.ground_sigma_m");
  fails_naming("tilt:\n  gravity:\n    rise_sigma_m: -0.1\n", "tilt.gravity.rise_sigma_m");
  fails_naming("tilt:\n  gravity:\n    rise_frames_back: 12\n", "tilt.gravity.rise_frames_back");
  fails_naming("tilt:\n  gravity:\n    rise_frames_back: -1\n", "tilt.gravity.rise_frames_back");
  fails_naming("tilt:\n  gravity:\n    accel_sigma_mps2: -1\n", "tilt.gravity.accel_sigma_mps2");
  fails_naming("tilt:\n  gravity:\n    odometry_walk_sigma: nan\n",
               "tilt.gravity.odometry_walk_sigma");
  fails_naming("tilt:\n  gravity:\n    estimate_mount: sometimes\n", "tilt.gravity.estimate_mount");
  fails_naming("tilt:\n  gravity:\n    window_frames: 1\n", "tilt.gravity.window_frames");
  fails_naming("tilt:\n  gravity: 3\n", "tilt.gravity");
  fails_naming("tilt:\n  verticals:\n    min_height: -1\n", "tilt.verticals.min_height");
  fails_naming("tilt:\n  verticals:\n    walls: 2\n", "tilt.verticals.walls");
  fails_naming("tilt:\n  verticals:\n    max_radius: 0\n", "tilt.verticals.max_radius");
  fails_naming("tilt:\n  mode: gravity\n  smooth: often\n", "tilt.smooth");
  fails_naming("tilt:\n  gravity:\n    smooth_ground_sigma_m: -1\n",
               "tilt.gravity.smooth_ground_sigma_m");
  fails_naming("tilt:\n  mode: refine_to_map\n  smooth: true\n", "tilt.smooth");
  fails_naming("tilt:\n  smooth: true\n", "tilt.smooth");  // the mode's default is prior
  TiltConfig prior_smoothed;
  prior_smoothed.smooth = true;
  EXPECT_NE(prior_smoothed.Validate().message().find("smooth"), std::string::npos);
}

}  // namespace
}  // namespace cairn::map
