// LoadWorld: the strict reader of world files (datasets/worlds/README.md has the format).
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cairn/od/units.hpp"
#include "cairn/sim/world.hpp"
#include "sampling.hpp"
#include "yaml_reader.hpp"

namespace cairn::sim {
namespace {

using detail::ErrorSink;
using detail::MapReader;
Expected<std::string> ReadText(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{path + ": no such file"};
  if (std::filesystem::is_directory(path, ec)) {
    return Error{path + ": is a directory, expected a world file"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path + ": cannot open for reading"};
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) return Error{path + ": read error"};
  return text.str();
}

// ---- terrain ---------------------------------------------------------------------------

Terrain ReadTerrain(ErrorSink& sink, const YAML::Node& node, std::uint64_t world_seed) {
  MapReader m(sink, node, "terrain",
              {"height", "slope", "uphill_heading", "waves", "roughness", "grid"});
  const double height = m.Number("height", 0.0);
  const double slope = m.Degrees("slope", 0.0);
  m.Check(std::abs(slope) < 80.0 * kDegToRad, "slope", "must be in (-80, 80) deg");
  const double uphill = m.Degrees("uphill_heading", 0.0);
  Terrain terrain = Terrain::Slope(height, slope, uphill);

  if (m.Has("waves")) {
    const YAML::Node waves = m.Node("waves");
    if (!waves.IsSequence()) {
      sink.Fail("terrain.waves", "expected a sequence of waves, got " + detail::Describe(waves));
    } else {
      for (std::size_t i = 0; i < waves.size(); ++i) {
        MapReader w(sink, waves[i], "terrain.waves[" + std::to_string(i) + "]",
                    {"amplitude", "wavelength", "direction", "phase"});
        SineWave wave;
        wave.amplitude_m = w.Number("amplitude");
        wave.wavelength_m = w.Number("wavelength");
        w.Check(wave.wavelength_m > 0.0, "wavelength", "must be > 0");
        wave.direction_rad = w.Degrees("direction", 0.0);
        wave.phase_rad = w.Degrees("phase", 0.0);
        if (!sink.failed()) terrain.AddWave(wave);
      }
    }
  }
  if (m.Has("roughness")) {
    // Small random waves: `count` of them, amplitudes summing (in quadrature) to `amplitude`.
    MapReader r(sink, m.Node("roughness"), "terrain.roughness",
                {"amplitude", "wavelength", "count", "seed"});
    const double amplitude = r.Number("amplitude");
    r.Check(amplitude >= 0.0, "amplitude", "must be >= 0");
    const double wavelength = r.Number("wavelength");
    r.Check(wavelength > 0.0, "wavelength", "must be > 0");
    const std::int64_t count = r.Integer("count", 8);
    r.Check(count >= 1 && count <= 64, "count", "must be in 1..64");
    const std::int64_t seed = r.Integer("seed", static_cast<std::int64_t>(world_seed));
    if (!sink.failed()) {
      Random rng(detail::Mix(static_cast<std::uint64_t>(seed), 0x726f756768ULL));  // "rough"
      for (int k = 0; k < count; ++k) {
        SineWave wave;
        wave.amplitude_m = amplitude / std::sqrt(static_cast<double>(count));
        wave.wavelength_m = wavelength * rng.Uniform(0.6, 1.4);
        wave.direction_rad = rng.Uniform(-kPi, kPi);
        wave.phase_rad = rng.Uniform(-kPi, kPi);
        terrain.AddWave(wave);
      }
    }
  }
  if (m.Has("grid")) {
    MapReader g(sink, m.Node("grid"), "terrain.grid",
                {"origin", "resolution", "cols", "rows", "heights"});
    HeightGrid grid;
    grid.origin = g.Vec2("origin");
    grid.resolution_m = g.Number("resolution");
    grid.cols = static_cast<int>(g.Integer("cols", 0));
    grid.rows = static_cast<int>(g.Integer("rows", 0));
    grid.heights = g.Numbers("heights");
    if (!sink.failed()) {
      Expected<Terrain> grid_terrain = Terrain::FromGrid(grid);
      if (!grid_terrain.ok()) {
        sink.Fail("terrain.grid", grid_terrain.error().message);
      } else {
        // The grid joins the plane and the waves read above.
        Terrain sum = std::move(grid_terrain).value();
        sum.AddPlane(height, std::tan(slope) * Eigen::Vector2d(std::cos(uphill), std::sin(uphill)));
        if (m.Has("waves") || m.Has("roughness")) {
          sink.Fail("terrain.grid", "cannot be combined with waves or roughness");
        }
        terrain = std::move(sum);
      }
    }
  }
  return terrain;
}

// ---- sensors -----------------------------------------------------------------------------

RangeCameraSpec ReadCamera(ErrorSink& sink, const YAML::Node& node) {
  MapReader m(sink, node, "camera",
              {"width", "height", "fx", "fy", "cx", "cy", "hfov", "max_range", "noise"});
  RangeCameraSpec spec = RangeCameraSpec::Default();
  od::PinholeModel& model = spec.model;
  model.width = static_cast<int>(m.Integer("width", 320));
  m.Check(model.width >= 2 && model.width <= 8192, "width", "must be in 2..8192");
  model.height = static_cast<int>(m.Integer("height", 240));
  m.Check(model.height >= 2 && model.height <= 8192, "height", "must be in 2..8192");
  m.Check(!(m.Has("fx") && m.Has("hfov")), "hfov", "give either fx or hfov, not both");
  if (m.Has("hfov")) {
    const double hfov = m.Degrees("hfov");
    m.Check(hfov > 0.0 && hfov < 170.0 * kDegToRad, "hfov", "must be in (0, 170) deg");
    model.fx = 0.5 * model.width / std::tan(0.5 * hfov);
  } else {
    model.fx = m.Number("fx", 260.0 * model.width / 320.0);
  }
  m.Check(model.fx > 0.0, "fx", "must be > 0");
  model.fy = m.Number("fy", model.fx);
  m.Check(model.fy > 0.0, "fy", "must be > 0");
  model.cx = m.Number("cx", 0.5 * (model.width - 1));
  model.cy = m.Number("cy", 0.5 * (model.height - 1));
  spec.max_range_m = m.Number("max_range", 60.0);
  m.Check(spec.max_range_m > 0.0, "max_range", "must be > 0");
  if (m.Has("noise")) {
    MapReader n(sink, m.Node("noise"), "camera.noise",
                {"depth_sigma_per_m2", "disparity_sigma_px", "baseline", "dropout_probability",
                 "edge_smear_px", "edge_jump"});
    StereoNoise& noise = spec.noise;
    // Either k directly or from the stereo rig: k = sigma_d / (fx * baseline).
    if (n.Has("disparity_sigma_px") || n.Has("baseline")) {
      n.Check(!n.Has("depth_sigma_per_m2"), "depth_sigma_per_m2",
              "give either depth_sigma_per_m2 or disparity_sigma_px and baseline");
      const double sigma_d = n.Number("disparity_sigma_px");
      n.Check(sigma_d >= 0.0, "disparity_sigma_px", "must be >= 0");
      const double baseline = n.Number("baseline");
      n.Check(baseline > 0.0, "baseline", "must be > 0");
      if (!sink.failed()) noise.depth_sigma_per_m2 = sigma_d / (model.fx * baseline);
    } else {
      noise.depth_sigma_per_m2 = n.Number("depth_sigma_per_m2", 0.0);
    }
    noise.dropout_probability = n.Number("dropout_probability", 0.0);
    noise.edge_smear_px = static_cast<int>(n.Integer("edge_smear_px", 0));
    noise.edge_jump_m = n.Number("edge_jump", noise.edge_jump_m);
    if (!sink.failed()) {
      if (Status s = noise.Validate(); !s.ok()) sink.Fail("camera.noise." + s.message(), "");
    }
  }
  if (!sink.failed()) {
    if (Status s = spec.model.Validate(); !s.ok()) sink.Fail("camera", s.message());
  }
  return spec;
}

LidarSpec ReadLidar(ErrorSink& sink, const YAML::Node& node) {
  MapReader m(sink, node, "lidar",
              {"preset", "elevations", "azimuth_steps", "range_sigma", "max_range"});
  LidarSpec spec;
  if (m.Has("preset")) {
    m.Check(!m.Has("elevations"), "elevations", "give either a preset or elevations, not both");
    const std::string name = m.String("preset");
    Expected<LidarSpec> preset = LidarSpec::Preset(name);
    if (!preset.ok()) {
      sink.Fail("lidar.preset", "unknown preset '" + name + "' (expected HDL-64E or VLP-16)");
    } else {
      spec = *preset;
    }
  } else {
    spec.preset = "custom";
    for (double e : m.Numbers("elevations")) spec.elevations_rad.push_back(e * kDegToRad);
  }
  spec.azimuth_steps = static_cast<int>(m.Integer("azimuth_steps", spec.azimuth_steps));
  spec.range_sigma_m = m.Number("range_sigma", spec.range_sigma_m);
  spec.max_range_m = m.Number("max_range", spec.max_range_m);
  if (!sink.failed()) {
    if (Status s = spec.Validate(); !s.ok()) sink.Fail("lidar." + s.message(), "");
  }
  return spec;
}

// ---- views and drive ------------------------------------------------------------------

std::vector<Viewpoint> ReadViews(ErrorSink& sink, const YAML::Node& node) {
  std::vector<Viewpoint> views;
  if (!node.IsSequence() || node.size() == 0) {
    sink.Fail("views", "expected a sequence of at least one view, got " + detail::Describe(node));
    return views;
  }
  for (std::size_t i = 0; i < node.size(); ++i) {
    MapReader m(sink, node[i], "views[" + std::to_string(i) + "]",
                {"x", "y", "height", "heading", "pitch", "roll", "follow_terrain"});
    Viewpoint v;
    v.x_m = m.Number("x");
    v.y_m = m.Number("y");
    v.height_m = m.Number("height", v.height_m);
    m.Check(v.height_m > 0.0, "height", "must be > 0 (above the ground)");
    v.heading_rad = m.Degrees("heading", 0.0);
    v.pitch_rad = m.Degrees("pitch", 0.0);
    m.Check(std::abs(v.pitch_rad) < 90.0 * kDegToRad, "pitch", "must be in (-90, 90) deg");
    v.roll_rad = m.Degrees("roll", 0.0);
    m.Check(std::abs(v.roll_rad) < 90.0 * kDegToRad, "roll", "must be in (-90, 90) deg");
    v.follow_terrain = m.Bool("follow_terrain", false);
    views.push_back(v);
  }
  return views;
}

DriveSpec ReadDrive(ErrorSink& sink, const YAML::Node& node) {
  MapReader m(
      sink, node, "drive",
      {"waypoints", "speed", "frame_rate", "wheelbase", "track", "sensor_xyz", "sensor_pitch",
       "odom_sigma_per_m", "odom_yaw_sigma_per_m", "imu_sigma", "imu_bias", "turn_radius"});
  DriveSpec d;
  const YAML::Node points = m.Node("waypoints");
  if (!m.Has("waypoints")) {
    sink.Fail("drive.waypoints", "missing (required)");
  } else if (!points.IsSequence()) {
    sink.Fail("drive.waypoints",
              "expected a sequence of [x, y] points, got " + detail::Describe(points));
  } else {
    for (std::size_t i = 0; i < points.size(); ++i) {
      const std::string field = "drive.waypoints[" + std::to_string(i) + "]";
      const YAML::Node p = points[i];
      if (!p.IsSequence() || p.size() != 2) {
        sink.Fail(field, "expected [x, y], got " + detail::Describe(p));
        break;
      }
      Eigen::Vector2d xy;
      for (int k = 0; k < 2; ++k) {
        try {
          xy[k] = p[k].as<double>();
        } catch (const YAML::Exception&) {
          sink.Fail(field, "expected [x, y] numbers, got " + detail::Describe(p[k]));
        }
      }
      d.waypoints.push_back(xy);
    }
  }
  d.speed_mps = m.Number("speed", d.speed_mps);
  d.frame_rate_hz = m.Number("frame_rate", d.frame_rate_hz);
  d.wheelbase_m = m.Number("wheelbase", d.wheelbase_m);
  d.track_m = m.Number("track", d.track_m);
  d.turn_radius_m = m.Number("turn_radius", d.turn_radius_m);
  d.T_body_sensor_xyz = m.Vec3("sensor_xyz", d.T_body_sensor_xyz);
  d.sensor_pitch_rad = m.Degrees("sensor_pitch", d.sensor_pitch_rad);
  d.odom_sigma_per_m = m.Number("odom_sigma_per_m", d.odom_sigma_per_m);
  d.odom_yaw_sigma_rad_per_m = m.Degrees("odom_yaw_sigma_per_m", d.odom_yaw_sigma_rad_per_m);
  d.imu_sigma_rad = m.Degrees("imu_sigma", d.imu_sigma_rad);
  d.imu_bias_rad = m.Degrees("imu_bias", d.imu_bias_rad);
  if (!sink.failed()) {
    if (Status s = d.Validate(); !s.ok()) sink.Fail("drive." + s.message(), "");
  }
  return d;
}

// ---- objects -----------------------------------------------------------------------------

// The keys of each kind besides the common ones; aliases only change the default name.
const std::map<std::string, std::vector<std::string>>& KindKeys() {
  static const std::map<std::string, std::vector<std::string>> keys = {
      {"pole", {"x", "y", "radius", "height"}},
      {"rock", {"x", "y", "radii", "height", "yaw"}},
      {"bush", {"x", "y", "radii", "height", "yaw", "lumps", "lump_scale", "seed"}},
      {"box", {"x", "y", "size", "yaw"}},
      {"ridge",
       {"x", "y", "yaw", "top_length", "top_width", "height", "left_slope", "right_slope",
        "end_slope"}},
      {"rod", {"start", "end", "radius"}},
      {"ditch", {"start", "end", "depth", "top_width", "wall_slope"}},
      {"bank", {"x", "y", "uphill_heading", "rise", "face_slope"}},
  };
  return keys;
}

const std::map<std::string, std::string>& Aliases() {
  static const std::map<std::string, std::string> aliases = {
      {"tree", "pole"}, {"wall", "box"}, {"mound", "ridge"}, {"branch", "rod"}, {"wire", "rod"}};
  return aliases;
}

std::string KindList() {
  std::string list;
  for (const auto& [kind, keys] : KindKeys()) list += (list.empty() ? "" : ", ") + kind;
  for (const auto& [alias, kind] : Aliases()) list += ", " + alias;
  return list;
}

// A slope of a face read in degrees: (0, max] deg.
double ReadSlope(MapReader& m, const std::string& key, double fallback_rad, double max_deg) {
  const double slope = m.Degrees(key, fallback_rad);
  m.Check(slope > 0.0 && slope <= max_deg * kDegToRad + 1e-12, key,
          "must be in (0, " + std::to_string(static_cast<int>(max_deg)) + "] deg");
  return slope;
}

// Reads objects[index] into the scene with the id chosen for it (see LoadWorld).
void ReadObject(ErrorSink& sink, const YAML::Node& node, int index, int id,
                std::uint64_t world_seed, Scene& scene) {
  const std::string path = "objects[" + std::to_string(index) + "]";
  if (!node.IsMap()) {
    sink.Fail(path, "expected a mapping with a kind, got " + detail::Describe(node));
    return;
  }
  const YAML::Node kind_node = node["kind"];
  if (!kind_node) {
    sink.Fail(path + ".kind", "missing (required; one of: " + KindList() + ")");
    return;
  }
  if (!kind_node.IsScalar()) {
    sink.Fail(path + ".kind", "expected a kind name, got " + detail::Describe(kind_node));
    return;
  }
  const std::string written = kind_node.Scalar();
  std::string kind = written;
  if (auto alias = Aliases().find(written); alias != Aliases().end()) kind = alias->second;
  const auto keys = KindKeys().find(kind);
  if (keys == KindKeys().end()) {
    sink.Fail(path + ".kind",
              "unknown kind '" + written + "' (expected one of: " + KindList() + ")");
    return;
  }
  std::vector<std::string> allowed = {"kind", "obstacle", "name", "id"};
  allowed.insert(allowed.end(), keys->second.begin(), keys->second.end());
  MapReader m(sink, node, path, allowed);
  const bool is_obstacle = m.Bool("obstacle");
  const std::string name = m.String("name", written);
  Shape shape;
  if (kind == "pole") {
    const double x = m.Number("x"), y = m.Number("y");
    const double radius = m.Number("radius"), height = m.Number("height");
    m.Check(radius > 0.0, "radius", "must be > 0");
    m.Check(height > 0.0, "height", "must be > 0");
    if (sink.failed()) return;
    const double base = scene.terrain().MinHeightOver({x, y}, radius);
    shape = Cylinder{{x, y, base}, radius, scene.terrain().Height(x, y) + height - base};
  } else if (kind == "rock") {
    const double x = m.Number("x"), y = m.Number("y");
    const Eigen::Vector3d radii = m.Vec3("radii");
    const double height = m.Number("height");
    const double yaw = m.Degrees("yaw", 0.0);
    m.Check(radii.minCoeff() > 0.0, "radii", "must all be > 0");
    m.Check(height > 0.0 && height <= 2.0 * radii.z(), "height",
            "must be in (0, 2 * radii[2]] (the rock is sunk to stand this tall)");
    if (sink.failed()) return;
    shape = Ellipsoid{{x, y, scene.terrain().Height(x, y) + height - radii.z()}, radii, yaw};
  } else if (kind == "bush") {
    const double x = m.Number("x"), y = m.Number("y");
    const Eigen::Vector3d radii = m.Vec3("radii");
    const double height = m.Number("height");
    const double yaw = m.Degrees("yaw", 0.0);
    const std::int64_t lumps = m.Integer("lumps", 6);
    const double lump_scale = m.Number("lump_scale", 0.5);
    const std::int64_t seed =
        m.Integer("seed", static_cast<std::int64_t>(detail::Mix(world_seed, index) >> 1));
    m.Check(radii.minCoeff() > 0.0, "radii", "must all be > 0");
    m.Check(height > 0.0 && height <= 2.0 * radii.z(), "height",
            "must be in (0, 2 * radii[2]] (the core is sunk to stand this tall)");
    m.Check(lumps >= 0 && lumps <= 64, "lumps", "must be in 0..64");
    m.Check(lump_scale > 0.0 && lump_scale <= 1.0, "lump_scale", "must be in (0, 1]");
    if (sink.failed()) return;
    shape = MakeBush(x, y, scene.terrain().Height(x, y) + height, radii, yaw,
                     static_cast<int>(lumps), lump_scale, static_cast<std::uint64_t>(seed));
  } else if (kind == "box") {
    const double x = m.Number("x"), y = m.Number("y");
    const Eigen::Vector3d size = m.Vec3("size");
    const double yaw = m.Degrees("yaw", 0.0);
    m.Check(size.minCoeff() > 0.0, "size", "must all be > 0");
    if (sink.failed()) return;
    const double base = scene.terrain().MinHeightOver({x, y}, 0.5 * size.head<2>().norm());
    const double top = scene.terrain().Height(x, y) + size.z();
    shape = Box{{x, y, 0.5 * (base + top)}, {size.x(), size.y(), top - base}, yaw};
  } else if (kind == "ridge") {
    Ridge r;
    r.base_centre = Eigen::Vector3d(m.Number("x"), m.Number("y"), 0.0);
    r.yaw_rad = m.Degrees("yaw", 0.0);
    r.top_length_m = m.Number("top_length");
    m.Check(r.top_length_m > 0.0, "top_length", "must be > 0");
    r.top_width_m = m.Number("top_width");
    m.Check(r.top_width_m > 0.0, "top_width", "must be > 0");
    r.height_m = m.Number("height");
    m.Check(r.height_m > 0.0, "height", "must be > 0");
    r.left_slope_rad = ReadSlope(m, "left_slope", r.left_slope_rad, 90.0);
    r.right_slope_rad = ReadSlope(m, "right_slope", r.right_slope_rad, 90.0);
    r.end_slope_rad = ReadSlope(m, "end_slope", r.end_slope_rad, 90.0);
    if (sink.failed()) return;
    // As Scene::AddRidge: the top where asked, the base sunk under the footprint.
    const double top = scene.terrain().Height(r.base_centre.x(), r.base_centre.y()) + r.height_m;
    const double base = scene.terrain().MinHeightOver(r.base_centre.head<2>(), Bound(r).radius_m);
    r.base_centre.z() = base;
    r.height_m = top - base;
    shape = r;
  } else if (kind == "rod") {
    Eigen::Vector3d start = m.Vec3("start"), end = m.Vec3("end");
    const double radius = m.Number("radius");
    m.Check(radius > 0.0, "radius", "must be > 0");
    m.Check((end - start).norm() > 0.0, "end", "must differ from start");
    if (sink.failed()) return;
    start.z() += scene.terrain().Height(start.x(), start.y());
    end.z() += scene.terrain().Height(end.x(), end.y());
    shape = Rod{start, end, radius};
  } else if (kind == "ditch") {
    Ditch d;
    d.start = m.Vec2("start");
    d.end = m.Vec2("end");
    m.Check((d.end - d.start).norm() > 0.0, "end", "must differ from start");
    d.depth_m = m.Number("depth");
    m.Check(d.depth_m > 0.0, "depth", "must be > 0");
    d.top_width_m = m.Number("top_width");
    m.Check(d.top_width_m > 0.0, "top_width", "must be > 0");
    d.wall_slope_rad = ReadSlope(m, "wall_slope", d.wall_slope_rad, 85.0);
    m.Check(sink.failed() || d.FloorWidth() >= 0.0, "top_width",
            "too narrow for this depth and wall slope (needs >= " +
                std::to_string(2.0 * d.depth_m / std::tan(d.wall_slope_rad)) + " m)");
    if (sink.failed()) return;
    shape = d;
  } else if (kind == "bank") {
    Bank b;
    b.centre = Eigen::Vector2d(m.Number("x"), m.Number("y"));
    b.uphill_heading_rad = m.Degrees("uphill_heading");
    b.rise_m = m.Number("rise");
    m.Check(b.rise_m > 0.0, "rise", "must be > 0");
    b.face_slope_rad = ReadSlope(m, "face_slope", b.face_slope_rad, 85.0);
    if (sink.failed()) return;
    shape = b;
  }
  if (sink.failed()) return;
  if (Status s = ValidateShape(shape); !s.ok()) {
    sink.Fail(path, s.message());
    return;
  }
  if (Status s = scene.Add(Object{id, is_obstacle, shape, name}); !s.ok()) {
    sink.Fail(path, s.message());
  }
}

}  // namespace

Expected<World> LoadWorld(const std::string& path) {
  Expected<std::string> text = ReadText(path);
  if (!text.ok()) return text.error();
  YAML::Node root;
  try {
    root = YAML::Load(*text);
  } catch (const YAML::Exception& e) {
    return Error{path + ":" + std::to_string(e.mark.line + 1) + ":" +
                 std::to_string(e.mark.column + 1) + ": invalid YAML: " + e.msg};
  }
  ErrorSink sink(path);
  MapReader top(sink, root, "",
                {"description", "seed", "terrain", "camera", "lidar", "views", "drive", "objects"});
  World world;
  world.name = std::filesystem::path(path).stem().string();
  world.description = top.String("description");
  top.Check(sink.failed() || !world.description.empty(), "description",
            "must say what the world shows");
  const std::int64_t seed = top.Integer("seed", 1);
  top.Check(seed >= 0, "seed", "must be >= 0");
  world.seed = static_cast<std::uint64_t>(seed);
  if (top.Has("terrain")) world.scene = Scene(ReadTerrain(sink, top.Node("terrain"), world.seed));
  world.camera =
      top.Has("camera") ? ReadCamera(sink, top.Node("camera")) : RangeCameraSpec::Default();
  if (top.Has("lidar")) world.lidar = ReadLidar(sink, top.Node("lidar"));
  if (top.Has("views")) {
    world.views = ReadViews(sink, top.Node("views"));
  } else {
    sink.Fail("views", "missing (required: at least one viewpoint)");
  }
  if (top.Has("drive")) world.drive = ReadDrive(sink, top.Node("drive"));
  if (top.Has("objects")) {
    const YAML::Node objects = top.Node("objects");
    if (!objects.IsSequence()) {
      sink.Fail("objects", "expected a sequence of objects, got " + detail::Describe(objects));
    } else {
      // Ids in file order: explicit ones as given (once each), the others the least ids
      // left free, so that adding a ditch does not renumber the objects listed before it.
      const int count = static_cast<int>(objects.size());
      std::vector<int> ids(count, 0);
      std::map<int, int> owner;  // explicit id -> index of the object that gives it
      for (int i = 0; i < count && !sink.failed(); ++i) {
        if (!objects[i].IsMap() || !objects[i]["id"]) continue;
        const std::string field = "objects[" + std::to_string(i) + "].id";
        const YAML::Node id = objects[i]["id"];
        std::int64_t value = 0;
        bool ok = id.IsScalar();
        try {
          if (ok) value = id.as<std::int64_t>();
        } catch (const YAML::Exception&) {
          ok = false;
        }
        if (!ok || value <= 0 || value >= (1 << 30)) {
          sink.Fail(field, "expected an integer in 1..2^30, got " + detail::Describe(id));
        } else if (auto [at, fresh] = owner.emplace(static_cast<int>(value), i); !fresh) {
          sink.Fail(field, "is already used by objects[" + std::to_string(at->second) + "]");
        } else {
          ids[i] = static_cast<int>(value);
        }
      }
      int next = 1;
      for (int i = 0; i < count; ++i) {
        if (ids[i] != 0) continue;
        while (owner.count(next) != 0) ++next;
        ids[i] = next++;
      }
      // Terrain features first, so that solids stand on the carved terrain.
      for (int pass = 0; pass < 2; ++pass) {
        for (int i = 0; i < count && !sink.failed(); ++i) {
          const YAML::Node kind = objects[i].IsMap() ? objects[i]["kind"] : YAML::Node();
          const bool feature =
              kind && kind.IsScalar() && (kind.Scalar() == "ditch" || kind.Scalar() == "bank");
          if (feature == (pass == 0)) {
            ReadObject(sink, objects[i], i, ids[i], world.seed, world.scene);
          }
        }
      }
    }
  }
  if (sink.failed()) return sink.error();
  if (Status s = world.scene.Validate(); !s.ok()) return Error{path + ": objects: " + s.message()};
  return world;
}

}  // namespace cairn::sim
