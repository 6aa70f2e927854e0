// cairn.Mapper, cairn.CostGrid, cairn.MapperRecord: the library's map::Mapper, one call per
// frame, as `cairn map` drives it; cost grid and elevation as map::ExportGrid gives them
// (the arrays the map files hold), map files by map::WriteMapFiles.
#include <filesystem>
#include <optional>
#include <string>
#include <utility>

#include "cairn/map/cost.hpp"
#include "cairn/map/map_files.hpp"
#include "cairn/map/mapper.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "types.hpp"

namespace cairn::python {
namespace {

py::array_t<double> PoseArray(const Eigen::Isometry3d& T) {
  const Eigen::Matrix4d m = T.matrix();
  py::array_t<double> out({4, 4});
  auto a = out.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) a(r, c) = m(r, c);
  }
  return out;
}

py::dict RecordDict(const map::MapperRecord& r) {
  py::dict d;
  d["index"] = r.index;
  d["stamp_s"] = r.stamp_s;
  d["used"] = r.used();
  d["skip"] = r.used() ? std::string() : std::string(map::FrameSkipName(r.skip));
  d["skip_detail"] = r.skip_detail;
  d["T_world_sensor_odometry"] = PoseArray(r.T_world_sensor_odometry);
  d["T_world_sensor"] = PoseArray(r.T_world_sensor);
  d["valid_points"] = r.valid_points;
  d["segments"] = r.segments;
  d["kept"] = r.kept;
  d["rejected"] = r.rejected;
  d["obstacle_points"] = r.fused.obstacle_points;
  d["ground_points"] = r.fused.ground_points;
  d["obstacles_created"] = r.fused.obstacles_created;
  d["tilt_roll_rad"] = r.tilt.roll_rad;
  d["tilt_pitch_rad"] = r.tilt.pitch_rad;
  d["tilt_dz_m"] = r.tilt.dz_m;
  d["tilt_applied"] = r.tilt.applied;
  if (r.tilt.gravity) {  // tilt mode "gravity": the estimator's answer for this frame
    const map::GravityEstimate& g = *r.tilt.gravity;
    py::dict e;
    e["roll_rad"] = g.roll_rad;
    e["pitch_rad"] = g.pitch_rad;
    e["height_m"] = g.height_m;
    e["attitude_covariance"] = py::cast(Eigen::Matrix3d(g.attitude_covariance));
    e["accel_bias_mps2"] = std::vector<double>{g.accel_bias_mps2.x(), g.accel_bias_mps2.y(),
                                               g.accel_bias_mps2.z()};
    e["mount_rad"] = std::vector<double>{g.mount_rad.x(), g.mount_rad.y()};
    e["verticals"] = g.cues.verticals;
    e["accel_terms"] = g.cues.accel_terms;
    std::vector<std::string> flags;
    for (const map::GravityDegeneracy& f : g.degeneracies) flags.push_back(f.reason);
    e["not_observable"] = flags;
    e["report"] = g.BriefReport();
    d["gravity"] = e;
  }
  d["detect_s"] = r.detect_s;
  d["tilt_s"] = r.tilt_s;
  d["fuse_s"] = r.fuse_s;
  return d;
}

/// The Python object: the Mapper and the settings it was made with.
struct PyMapper {
  explicit PyMapper(map::Mapper m) : mapper(std::move(m)) {}
  map::Mapper mapper;
};

std::unique_ptr<PyMapper> MakeMapper(const Settings* settings, std::optional<double> window_m,
                                     std::optional<bool> refine_tilt,
                                     const std::optional<std::string>& tilt) {
  map::MapperConfig config = settings != nullptr ? settings->map.mapper : map::MapperConfig{};
  // The overrides of `cairn map --window / --offline / --refine-tilt / --no-refine-tilt`.
  if (window_m) config.map.window_size_m = *window_m;
  if (refine_tilt) config.tilt.mode = *refine_tilt ? map::TiltMode::kRefineToMap
                                                   : map::TiltMode::kPrior;
  if (tilt) config.tilt.mode = Unwrap(map::ParseTiltMode(*tilt));
  if (Status s = config.map.Validate(); !s) throw CairnError("window: " + s.message());
  py::gil_scoped_release release;
  return std::make_unique<PyMapper>(Unwrap(map::Mapper::Create(config)));
}

py::dict AddPoints(PyMapper& self, const InArray<float>& points, const InArray<double>& pose,
                   double stamp_s, const std::optional<std::string>& sensor,
                   const std::string& organised, int columns, const std::string& source) {
  od::PointCloud cloud;
  {
    PointsIn in = ReadPointsArray(points, source);
    cloud.points = std::move(in.points);
    cloud.intensity = std::move(in.intensity);
  }
  const Eigen::Isometry3d T_world_sensor = ReadPose(pose, "T_world_sensor");
  od::LayoutOptions layout;
  if (columns < 0) throw CairnError("columns: expected 0 (the sensor's) or a positive count");
  layout.columns = columns;
  layout.organised = ParseOrganised(organised);
  map::MapperRecord record;
  {
    py::gil_scoped_release release;
    if (sensor) layout.preset = Unwrap(od::SphericalModel::Preset(*sensor, columns));
    // The rows and columns as the KITTI source of `cairn map` finds them; the Mapper levels
    // the image with its tilt prior.
    od::FoundLayout found = Unwrap(od::FindLayout(cloud, layout, source));
    record = Unwrap(self.mapper.Process(cloud.points, found.model, T_world_sensor, stamp_s, {},
                                        found.rows, found.cols));
  }
  return RecordDict(record);
}

py::dict AddDepth(PyMapper& self, const InArray<float>& depth_m, const InArray<double>& pose,
                  double stamp_s, double fx, double fy, double cx, double cy) {
  if (depth_m.ndim() != 2) throw CairnError("depth_m: expected an (H, W) array of z-depth [m]");
  const od::PinholeModel model = PinholeOf(depth_m, fx, fy, cx, cy);
  const Eigen::Isometry3d T_world_sensor = ReadPose(pose, "T_world_sensor");
  std::vector<float> depth(depth_m.data(), depth_m.data() + depth_m.size());
  map::MapperRecord record;
  {
    py::gil_scoped_release release;
    // Any up vector will do: Process replaces it with the tilt step's prior.
    const Eigen::Vector3d up = T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    od::RangeImage image = Unwrap(od::RangeImage::FromDepth(depth, model, up));
    record = Unwrap(self.mapper.Process(std::move(image), T_world_sensor, stamp_s));
  }
  return RecordDict(record);
}

py::dict AddFrame(PyMapper& self, const Frame& frame) {
  if (!frame.skip.empty()) {
    throw CairnError(frame.name + ": " + frame.skip + " (" + frame.skip_detail +
                     "): a skipped frame has no image to map");
  }
  map::MapperRecord record;
  {
    py::gil_scoped_release release;
    if (Status st = self.mapper.SetSensorMount(frame.T_world_body.inverse() * frame.T_world_sensor);
        !st) {
      throw CairnError(frame.name + ": " + st.message());
    }
    Expected<map::MapperRecord> r =
        self.mapper.Process(frame.image, frame.T_world_sensor, frame.stamp_s, frame.imu);
    if (!r) throw CairnError(frame.name + ": " + r.error().message);  // as `cairn map` says it
    record = std::move(*r);
  }
  return RecordDict(record);
}

struct CostGrid {
  map::GridExport grid;
};

py::list Obstacles(const PyMapper& self) {
  py::list out;
  for (const map::Obstacle& o : self.mapper.map().obstacles()) {
    py::dict d;
    d["id"] = o.id;
    d["bbox_min_m"] = Eigen::Vector3d(o.bbox_min);
    d["bbox_max_m"] = Eigen::Vector3d(o.bbox_max);
    d["centroid_m"] = Eigen::Vector3d(o.centroid);
    d["height_m"] = o.height_m;
    d["point_count"] = o.point_count;
    d["cells"] = static_cast<int>(o.cells.size());
    d["footprint_min_m"] = Eigen::Vector2d(o.footprint_min);
    d["footprint_max_m"] = Eigen::Vector2d(o.footprint_max);
    d["footprint_area_m2"] = o.footprint_area_m2;
    d["first_seen_s"] = o.first_seen_s;
    d["last_seen_s"] = o.last_seen_s;
    d["frames"] = o.frames;
    d["merged_ids"] = o.merged_ids;
    out.append(d);
  }
  return out;
}

void Save(const PyMapper& self, const std::string& dir) {
  py::gil_scoped_release release;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw CairnError(dir + ": cannot create: " + ec.message());
  Check(map::WriteMapFiles(self.mapper.map(), dir));
}

}  // namespace

void RegisterMap(py::module_& m) {
  py::class_<CostGrid>(m, "CostGrid",
                       "The 2.5-D grid as the map files hold it (cost.pgm, elevation.tiff): "
                       "map_server's orientation, row 0 the top (highest world y), column 0 the "
                       "lowest world x.")
      .def_property_readonly(
          "cost",
          [](py::object self) {
            const auto& g = self.cast<const CostGrid&>().grid;
            return View(g.cost, {g.height, g.width}, self);
          },
          "(H, W) uint8 nav2 costmap values: 0 free .. 252 terrain, 253 inscribed, 254 lethal, "
          "255 unknown.")
      .def_property_readonly(
          "occupancy",
          [](const CostGrid& c) {
            std::vector<std::int8_t> occ(c.grid.cost.size());
            for (std::size_t i = 0; i < occ.size(); ++i) occ[i] = map::OccupancyFromCost(c.grid.cost[i]);
            return Take(std::move(occ), {c.grid.height, c.grid.width});
          },
          "(H, W) int8 as nav2 publishes the costmap (OccupancyGrid): -1 unknown, 0..100; "
          "cost.pgm holds these (255 for -1), top row first.")
      .def_property_readonly(
          "elevation",
          [](py::object self) {
            const auto& g = self.cast<const CostGrid&>().grid;
            return View(g.elevation_m, {g.height, g.width}, self);
          },
          "(H, W) float32 ground elevation, world z [m], NaN where unknown.")
      .def_property_readonly(
          "origin", [](const CostGrid& c) { return std::make_pair(c.grid.origin_m.x(), c.grid.origin_m.y()); },
          "(x, y) world position of the lower-left cell's outer corner [m] (cost.yaml's origin).")
      .def_property_readonly(
          "resolution", [](const CostGrid& c) { return c.grid.resolution_m; },
          "Cell side [m].")
      .def_property_readonly(
          "extent",
          [](const CostGrid& c) {
            const double x0 = c.grid.origin_m.x(), y0 = c.grid.origin_m.y();
            return py::make_tuple(x0, x0 + c.grid.width * c.grid.resolution_m, y0,
                                  y0 + c.grid.height * c.grid.resolution_m);
          },
          "(x_min, x_max, y_min, y_max) [m]: matplotlib's imshow extent for the arrays.")
      .def("__repr__", [](const CostGrid& c) {
        return "cairn.CostGrid(" + std::to_string(c.grid.height) + "x" +
               std::to_string(c.grid.width) + " cells of " + std::to_string(c.grid.resolution_m) +
               " m)";
      });

  py::class_<PyMapper>(m, "Mapper",
                       "The library's map::Mapper: one call per frame (check, level, detect, "
                       "tilt, fuse), the OctoMap and the cost grid owned inside. World frame z "
                       "up; metres, radians, seconds. Not thread-safe.")
      .def(py::init(&MakeMapper), py::arg("settings") = nullptr, py::kw_only(),
           py::arg("window_m") = py::none(), py::arg("refine_tilt") = py::none(),
           py::arg("tilt") = py::none(),
           "settings: cairn.Settings (None: the defaults). window_m: rolling window side [m], "
           "0 = unbounded (cairn map --window / --offline); None keeps the settings'. "
           "refine_tilt: True / False override tilt.refine (--refine-tilt / --no-refine-tilt). "
           "tilt: 'prior' | 'refine_to_map' | 'gravity' (cairn map --tilt).")
      .def("add_points", &AddPoints, py::arg("points"), py::arg("T_world_sensor"),
           py::kw_only(), py::arg("stamp"), py::arg("sensor") = py::none(),
           py::arg("organised") = "auto", py::arg("columns") = 0, py::arg("source") = "points",
           "Fuses one LiDAR scan. points: (N, 3) or (N, 4) in the LiDAR frame [m]; "
           "T_world_sensor: (4, 4) odometry pose; stamp [s]; sensor: preset for the rings "
           "(as cairn map --lidar), None to find them from the data. Returns the frame's "
           "record (dict). Runs without the GIL.")
      .def("add_depth", &AddDepth, py::arg("depth_m"), py::arg("T_world_sensor"), py::kw_only(),
           py::arg("stamp"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
           "Fuses one z-depth image [m] (optical frame) with its pose and pinhole intrinsics "
           "[px]. Returns the frame's record (dict).")
      .def("add_frame", &AddFrame, py::arg("frame"),
           "Fuses a cairn.Frame of a reader (kitti_frames, rawlog_frames, depth_frames) exactly "
           "as `cairn map` does. Returns the frame's record (dict).")
      .def(
          "cost_grid",
          [](const PyMapper& self) {
            py::gil_scoped_release release;
            return CostGrid{Unwrap(map::ExportGrid(self.mapper.map()))};
          },
          "The cost grid and elevation now (a copy): cairn.CostGrid.")
      .def("obstacles", &Obstacles,
           "The live persistent obstacles, one dict each (world frame [m], stamps [s]).")
      .def("save", &Save, py::arg("dir"),
           "Writes the map files of `cairn map` into dir (created when missing): map.bt, map.ot, "
           "obstacles.ot, cost.yaml + cost.pgm, cost.png, elevation.tiff + elevation.yaml, "
           "obstacles.json.")
      .def_property_readonly(
          "frames_processed", [](const PyMapper& s) { return s.mapper.frames_processed(); })
      .def_property_readonly("frames_fused",
                             [](const PyMapper& s) { return s.mapper.frames_fused(); });
}

}  // namespace cairn::python
