// World: a synthetic test world as described in a YAML file (datasets/worlds/*.yaml): a
// scene with ground truth, the sensors that look at it, single viewpoints, and an optional
// drive. Every claim about detection, mapping and tilt is measured on such worlds.
//
// Frames: world z up. Sensor noise is seeded, so a world and a seed give the same frames.
//
// The file format is documented in datasets/worlds/README.md. In files, angles are degrees
// and keys are the member names below without their unit suffix (`speed` for speed_mps,
// `pitch` in degrees for pitch_rad); Validate() messages name those keys.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::sim {

/// Stereo-like depth noise of a range camera.
struct StereoNoise {
  /// Depth standard deviation sigma_z = k * z^2 [1/m]: from disparity noise sigma_d [px],
  /// k = sigma_d / (fx * baseline). 0 = no noise.
  double depth_sigma_per_m2 = 0.0;
  double dropout_probability = 0.0;  ///< each valid pixel becomes "no return", in [0, 1)
  /// Depth edges are smeared: a pixel within this many pixels of a depth discontinuity
  /// larger than `edge_jump_m` takes a depth interpolated across it (a mixed pixel) [px].
  int edge_smear_px = 0;
  double edge_jump_m = 0.5;
  /// Names the first bad field: sigma >= 0, dropout in [0, 1), smear in 0..32 px, jump > 0.
  Status Validate() const;
  bool IsZero() const {
    return depth_sigma_per_m2 == 0.0 && dropout_probability == 0.0 && edge_smear_px == 0;
  }
};

struct RangeCameraSpec {
  od::PinholeModel model;
  StereoNoise noise;
  double max_range_m = 60.0;  ///< farther surfaces are no return (distance along the ray) [m]
  Status Validate() const;
  /// The gallery's camera: 320 x 240, fx = fy = 260 px (63 deg across), centred, no noise.
  static RangeCameraSpec Default();
  /// The same field of view at `width` pixels across (height, fx and fy scaled, centred).
  RangeCameraSpec Scaled(int width) const;
};

/// Applies stereo-like noise to a clean rendered frame, in this order: mixed pixels at depth
/// edges (horizontal and vertical jumps between valid neighbours larger than edge_jump_m;
/// the 2 * edge_smear_px pixels straddling a jump take depths interpolated linearly from the
/// near to the far side, each pixel from its nearest jump), Gaussian depth noise with
/// sigma = k z^2 (z the clean or smeared depth), then dropouts. A dropped pixel, or one whose
/// noisy depth is not positive, reads depth 0, id kNoHitId and a zero normal, like sky; every
/// other pixel keeps the ground-truth id and normal of the surface its ray hit. Deterministic
/// for a seed (portable draws).
DepthFrame ApplyStereoNoise(DepthFrame frame, const StereoNoise& noise, std::uint64_t seed);

/// Renders `scene` through `camera` (the spec's model is used, camera.model ignored) up to the
/// spec's range and applies its noise with `seed`. Fails when the spec, the camera's pose or
/// the scene does not validate.
Expected<DepthFrame> RenderRangeCamera(const Scene& scene, const RangeCameraSpec& spec,
                                       const Camera& camera, std::uint64_t seed);

/// A spinning multi-ring LiDAR (x forward, y left, z up). Presets: "HDL-64E", "VLP-16".
///
/// Ring r looks up at elevations_rad[r] from the horizontal plane of the sensor (ring 0 is
/// the top beam, elevations decrease). Column c looks at azimuth pi * (1 - 2 c / N)
/// (counter-clockwise from +x, N = azimuth_steps): column 0 looks backwards, N/4 left, N/2
/// forward, 3N/4 right, so that a range image laid out by (ring, column) shows the scene as
/// seen from the sensor with forward in the middle (the usual spherical projection).
/// All rays of a revolution start at the sensor origin at the same instant (no motion
/// distortion).
struct LidarSpec {
  std::string preset;                  ///< informative name
  std::vector<double> elevations_rad;  ///< one per ring, ring 0 = top beam
  int azimuth_steps = 1024;            ///< columns per revolution
  double range_sigma_m = 0.0;          ///< Gaussian range noise
  double max_range_m = 100.0;
  /// "HDL-64E": 64 rings in the sensor's two blocks, upper 32 from +2.0 deg down every 1/3
  /// deg (to -8.33), lower 32 evenly from -8.83 to -24.8 deg (about 0.52 deg apart; the
  /// real lasers are individually calibrated, this spacing is the data sheet's); 2048 steps,
  /// 120 m, 2 cm noise. "VLP-16": 16 rings from +15 to -15 deg every 2 deg, 1024 steps,
  /// 100 m, 3 cm noise.
  static Expected<LidarSpec> Preset(const std::string& name);  ///< "HDL-64E", "VLP-16"
  /// Names the first bad field: at least one ring, elevations finite in (-90, 90) deg,
  /// azimuth_steps in 1..65536, range_sigma >= 0, max_range > 0.
  Status Validate() const;
  int rings() const { return static_cast<int>(elevations_rad.size()); }
  /// Azimuth of a column [rad], counter-clockwise from +x.
  double AzimuthRad(int column) const;
  /// Unit direction of the ray of (ring, column) in the sensor frame.
  Eigen::Vector3d RayDirection(int ring, int column) const;
};

/// One LiDAR revolution: the returns only, in the sensor frame, each with its ring and
/// azimuth column (so labels can go back to points) and its ground truth.
struct LidarScan {
  std::vector<Eigen::Vector3f> points;  ///< sensor frame (x forward, y left, z up) [m]
  std::vector<std::int32_t> ring;       ///< 0 = top beam
  std::vector<std::int32_t> column;     ///< azimuth step, 0..azimuth_steps-1
  std::vector<std::int32_t> object_id;  ///< kTerrainId or an object id
};

/// Casts one revolution from T_world_lidar with the spec's range noise (seeded): one exact
/// ray per (ring, column) through RayCaster, each return kept at its true range plus
/// N(0, range_sigma) along its ray; rays that meet nothing within max_range (or whose noisy
/// range is not positive) give no point. Points come ring by ring, column by column. Fails
/// when the spec or the scene does not validate.
Expected<LidarScan> RenderLidar(const Scene& scene, const LidarSpec& lidar,
                                const Eigen::Isometry3d& T_world_lidar, std::uint64_t seed);

/// Where a single frame is taken: the sensor `height_m` above the terrain at (x, y).
struct Viewpoint {
  double x_m = 0.0, y_m = 0.0;
  double height_m = 1.6;
  double heading_rad = 0.0;  ///< 0 = world +x, counter-clockwise
  double pitch_rad = 0.0;    ///< optical axis below the horizontal is positive
  double roll_rad = 0.0;     ///< x axis dipping below the horizontal is positive
  /// When true, pitch and roll are relative to the ground under (x, y), as for a camera on
  /// a vehicle standing there: the camera is first levelled on the terrain's tangent plane
  /// (its heading projected onto it), then pitched and rolled; `height_m` stays vertical.
  bool follow_terrain = false;
};

/// A vehicle drive over the terrain: the body follows the ground (pitches and rolls with
/// it); odometry drifts and the IMU attitude is noisy and biased.
struct DriveSpec {
  std::vector<Eigen::Vector2d> waypoints;  ///< world xy, driven in order [m]
  double speed_mps = 2.0;
  double frame_rate_hz = 10.0;
  /// Each corner between waypoints rounded by a circular arc of this radius (smaller where a
  /// segment is too short), as a vehicle steers through it; 0 keeps the corners sharp,
  /// which a real vehicle cannot drive (the velocity jumps there) [m].
  double turn_radius_m = 0.0;
  double wheelbase_m = 1.5;  ///< front-rear axle distance, for pitch
  double track_m = 1.2;      ///< left-right wheel distance, for roll
  Eigen::Vector3d T_body_sensor_xyz = Eigen::Vector3d(0.5, 0.0, 1.5);  ///< sensor on body
  double sensor_pitch_rad = 0.14;           ///< sensor tilt on the body (down positive)
  double odom_sigma_per_m = 0.01;           ///< translation drift per metre driven
  double odom_yaw_sigma_rad_per_m = 0.002;  ///< heading drift per metre
  double imu_sigma_rad = 0.005;             ///< attitude noise per sample
  double imu_bias_rad = 0.01;               ///< constant roll/pitch bias
  /// Speed changes: speed(t) = speed_mps + speed_wave_mps sin(2 pi t / speed_wave_period_s)
  /// [m/s], so that the accelerometer sees along-track acceleration; 0 keeps the speed
  /// constant. Must be below speed_mps. Not read from world files yet (C++ only).
  double speed_wave_mps = 0.0;
  double speed_wave_period_s = 8.0;  ///< [s], > 0
  /// The sensor's true mount differs from the nominal one (T_body_sensor_xyz,
  /// sensor_pitch_rad) by Rz(yaw) Ry(pitch) Rx(roll) of these (roll, pitch, yaw) [rad],
  /// applied on the sensor side: T_body_sensor_true = T_body_sensor_nominal * R. A mapper
  /// knows only the nominal mount. C++ only.
  Eigen::Vector3d sensor_misalignment_rad = Eigen::Vector3d::Zero();
  /// Names the first bad field: at least two waypoints, finite, not all the same; speed,
  /// frame_rate, wheelbase, track > 0; sigmas and turn_radius >= 0; everything finite.
  Status Validate() const;
};

struct World {
  std::string name;         ///< file stem
  std::string description;  ///< what the world isolates (the claim it tests)
  Scene scene;
  RangeCameraSpec camera;
  std::optional<LidarSpec> lidar;
  std::vector<Viewpoint> views;  ///< at least one
  std::optional<DriveSpec> drive;
  std::uint64_t seed = 1;  ///< noise seed
};

/// Reads and validates a world file. Unknown keys, missing required fields, bad values and
/// unknown object kinds give an Error naming the file and the field.
Expected<World> LoadWorld(const std::string& path);

/// The camera of view `index` (0 <= index < views.size(), asserted), placed on the terrain.
Camera ViewCamera(const World& world, int index);

/// Renders view `index` with the world's camera noise (seeded by world.seed and index):
/// depth, object ids (ground truth per pixel) and the up vector. See ApplyStereoNoise for
/// what noise does to ids. Fails on an index out of range or a world that does not render.
Expected<DepthFrame> RenderView(const World& world, int index);

/// The noise seed RenderView uses for view `index` (a splitmix64 mix of the two).
std::uint64_t ViewNoiseSeed(std::uint64_t world_seed, int index);

}  // namespace cairn::sim
