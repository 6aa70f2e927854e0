// cairn.Settings, cairn.load_settings, cairn.Detection, cairn.detect_points,
// cairn.detect_depth, cairn.detect_frame: one frame through the same library calls as
// `cairn detect` (od::PlaceScan, od::io::DetectAndClassify, od::io::PointLabels,
// od::io::SegmentsJsonText).
#include <chrono>
#include <string>
#include <utility>

#include "cairn/map/mapper_config_file.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/rules.hpp"
#include "cairn/od/sensor_model.hpp"
#include "cairn/util/format.hpp"
#include "types.hpp"

namespace cairn::python {

od::io::DetectRunOptions RunOptions(const std::string& method, bool rules, bool feet) {
  od::io::DetectRunOptions options;
  options.method = Unwrap(od::io::ParseDetectMethod(method));
  options.apply_rules = rules;
  options.keep_feet = feet;
  return options;
}

od::OrganisedMode ParseOrganised(const std::string& text) {
  if (text == "auto") return od::OrganisedMode::kAuto;
  if (text == "yes") return od::OrganisedMode::kYes;
  if (text == "no") return od::OrganisedMode::kNo;
  throw CairnError("organised: expected auto, yes or no, got '" + text + "'");
}

DetectionResult DetectOn(od::RangeImage image, const Settings& settings,
                         const od::io::DetectRunOptions& options, od::io::RunDescription run) {
  od::io::DetectRun done = Unwrap(od::io::DetectAndClassify(image, settings.detect, options));
  DetectionResult out;
  out.from_points = !image.cell_of_point().empty();
  if (out.from_points) {
    out.point_labels = Unwrap(od::io::PointLabels(image, done.detection, done.classification));
  }
  out.classes = od::ClassImage(done.detection, done.classification);
  run.method = od::io::DetectMethodName(options.method);
  run.rules_applied = options.apply_rules;
  run.settings = settings.detect;
  run.config_file = settings.path;
  out.segments_json = Unwrap(
      od::io::SegmentsJsonText("segments.json", done.detection, done.classification, run));
  out.method = run.method;
  out.detect_s = done.detect_s;
  out.image = std::move(image);
  out.detection = std::move(done.detection);
  out.classification = std::move(done.classification);
  return out;
}

namespace {

using Clock = std::chrono::steady_clock;
const Settings& SettingsOrDefaults(const Settings* settings) {
  static const Settings kDefaults;
  return settings != nullptr ? *settings : kDefaults;
}

Settings LoadSettings(const std::string& path) {
  py::gil_scoped_release release;
  Settings s;
  // The detect loader first: its message is the one `cairn detect --config` prints; the
  // map loader reads the same file again for the map, tilt and frames sections.
  s.detect = Unwrap(od::io::LoadDetectSettings(path, map::MapperSettingsSections()));
  s.map = Unwrap(map::LoadMapperSettings(path));
  s.path = path;
  return s;
}

Settings ParseSettings(const std::string& text, const std::string& source) {
  py::gil_scoped_release release;
  Settings s;
  s.detect = Unwrap(od::io::ParseDetectSettings(text, source, map::MapperSettingsSections()));
  s.map = Unwrap(map::ParseMapperSettings(text, source));
  return s;
}

std::shared_ptr<DetectionResult> DetectPoints(const InArray<float>& points,
                                              const std::optional<std::string>& sensor,
                                              const Settings* settings,
                                              const std::vector<double>& up,
                                              const std::string& organised, int columns,
                                              const std::string& method, bool rules, bool feet,
                                              const std::string& source) {
  od::PointCloud cloud;
  {
    PointsIn in = ReadPointsArray(points, source);
    cloud.points = std::move(in.points);
    cloud.intensity = std::move(in.intensity);
  }
  const Eigen::Vector3d up_sensor = ReadVector3(up, "up");
  if (columns < 0) throw CairnError("columns: expected 0 (the sensor's) or a positive count");
  od::LayoutOptions layout;
  layout.columns = columns;
  layout.organised = ParseOrganised(organised);
  const od::io::DetectRunOptions options = RunOptions(method, rules, feet);
  const Settings& s = SettingsOrDefaults(settings);
  py::gil_scoped_release release;
  const Clock::time_point start = Clock::now();
  if (sensor) layout.preset = Unwrap(od::SphericalModel::Preset(*sensor, columns));
  od::PlacedScan placed = Unwrap(od::PlaceScan(cloud, layout, up_sensor, source));
  od::io::RunDescription run;
  run.depth_file = source;
  // As `cairn detect --points` describes the layout in segments.json.
  run.intrinsics_file = (sensor ? "sensor " + *sensor : std::string("rings from the data")) + ", " +
                        std::to_string(placed.image.height()) + " rings (" +
                        od::RingSourceName(placed.layout.source) + ") x " +
                        std::to_string(placed.image.width()) + " columns";
  auto result = std::make_shared<DetectionResult>(
      DetectOn(std::move(placed.image), s, options, std::move(run)));
  result->cpp_s = util::SecondsSince(start);
  return result;
}

std::shared_ptr<DetectionResult> DetectDepth(const InArray<float>& depth_m, double fx, double fy,
                                             double cx, double cy, const std::vector<double>& up,
                                             const Settings* settings, const std::string& method,
                                             bool rules, bool feet, const std::string& source) {
  if (depth_m.ndim() != 2) {
    throw CairnError(source + ": expected an (H, W) array of z-depth [m], got " +
                     std::to_string(depth_m.ndim()) + " dimensions");
  }
  const od::PinholeModel model = PinholeOf(depth_m, fx, fy, cx, cy);
  const Eigen::Vector3d up_sensor = ReadVector3(up, "up");
  std::vector<float> depth(depth_m.data(), depth_m.data() + depth_m.size());
  const od::io::DetectRunOptions options = RunOptions(method, rules, feet);
  const Settings& s = SettingsOrDefaults(settings);
  py::gil_scoped_release release;
  const Clock::time_point start = Clock::now();
  od::RangeImage image = Unwrap(od::RangeImage::FromDepth(depth, model, up_sensor));
  od::io::RunDescription run;
  run.depth_file = source;
  auto result = std::make_shared<DetectionResult>(DetectOn(std::move(image), s, options, run));
  result->cpp_s = util::SecondsSince(start);
  return result;
}

py::object ParseJson(const std::string& text) {
  return py::module_::import("json").attr("loads")(text);
}

}  // namespace

void RegisterDetect(py::module_& m) {
  py::class_<Settings>(m, "Settings",
                       "Detection, rules, column, stereo, map, tilt and frame-check settings, "
                       "as a settings YAML sets them (config/default.yaml documents every key). "
                       "Settings() holds the built-in defaults.")
      .def(py::init<>())
      .def_property_readonly(
          "path",
          [](const Settings& s) -> py::object {
            return s.path.empty() ? py::object(py::none()) : py::object(py::str(s.path));
          },
          "The file it was loaded from, or None for the defaults.")
      .def_property_readonly(
          "min_height_m", [](const Settings& s) { return s.detect.detector.min_height_m; },
          "HT, least height of an obstacle [m].")
      .def_property_readonly(
          "max_height_m", [](const Settings& s) { return s.detect.detector.max_height_m; },
          "Hmax: bounds the search, splits obstacles [m].")
      .def_property_readonly(
          "min_slope_rad", [](const Settings& s) { return s.detect.detector.min_slope_rad; },
          "theta, least slope of an obstacle from the horizontal [rad].")
      .def_property_readonly(
          "min_range_m", [](const Settings& s) { return s.detect.detector.min_range_m; },
          "Returns nearer than this are ignored [m].")
      .def_property(
          "threads", [](const Settings& s) { return s.detect.detector.threads; },
          [](Settings& s, int threads) {
            od::DetectorConfig c = s.detect.detector;
            c.threads = threads;
            Check(c.Validate());
            s.detect.detector.threads = threads;
            s.map.mapper.detector.threads = threads;
          },
          "Detector worker threads, 0 = every core (the result does not depend on it).")
      .def_property_readonly(
          "cell_size_m", [](const Settings& s) { return s.map.mapper.map.cell_size_m; },
          "Side of a cost-grid cell [m].")
      .def_property_readonly(
          "window_size_m", [](const Settings& s) { return s.map.mapper.map.window_size_m; },
          "Side of the rolling map window, 0 = unbounded [m].")
      .def("__repr__", [](const Settings& s) {
        return "cairn.Settings(" + (s.path.empty() ? std::string("defaults") : "'" + s.path + "'") +
               ")";
      });

  m.def("load_settings", &LoadSettings, py::arg("path"),
        "Reads a settings YAML with the command line's strict loaders (an unknown key, a "
        "duplicate, a wrong type or an out-of-range value raises cairn.Error naming the file "
        "and the field). Degrees in the file, radians in the library.");
  m.def("parse_settings", &ParseSettings, py::arg("text"), py::arg("source") = "settings",
        "The same from YAML text; `source` names it in error messages.");

  py::class_<DetectionResult, std::shared_ptr<DetectionResult>>(
      m, "Detection",
      "One frame's obstacles: per-cell arrays of the range image (rows, cols), per-point labels "
      "for scans, and the per-segment measures of segments.json. Arrays share the result's "
      "memory (read-only).")
      .def_property_readonly("width", [](const DetectionResult& d) { return d.detection.width; })
      .def_property_readonly("height",
                             [](const DetectionResult& d) { return d.detection.height; })
      .def_property_readonly(
          "labels",
          [](py::object self) {
            const auto& d = self.cast<const DetectionResult&>();
            return View(d.detection.labels, {d.detection.height, d.detection.width}, self);
          },
          "(rows, cols) int32: segment id per cell, 0 = no obstacle point.")
      .def_property_readonly(
          "foot",
          [](py::object self) {
            const auto& d = self.cast<const DetectionResult&>();
            return View(d.detection.foot, {d.detection.height, d.detection.width}, self);
          },
          "(rows, cols) uint8: 1 where an obstacle point is its segment's foot.")
      .def_property_readonly(
          "classes",
          [](py::object self) {
            const auto& d = self.cast<const DetectionResult&>();
            return View(d.classes, {d.detection.height, d.detection.width}, self);
          },
          "(rows, cols) uint8: 0 none, 1 kept, 2 rejected (what classes.png holds).")
      .def_property_readonly(
          "point_labels",
          [](py::object self) -> py::object {
            const auto& d = self.cast<const DetectionResult&>();
            if (!d.from_points) return py::none();
            return View(d.point_labels, {static_cast<py::ssize_t>(d.point_labels.size())}, self);
          },
          "(N,) uint32 per input point, what labels.label holds: low 16 bits the class (0 "
          "none, 1 kept, 2 rejected), high 16 bits the segment id. None for depth images.")
      .def_property_readonly(
          "cell_of_point",
          [](py::object self) -> py::object {
            const auto& d = self.cast<const DetectionResult&>();
            if (!d.from_points) return py::none();
            const auto& cells = d.image.cell_of_point();
            return View(cells, {static_cast<py::ssize_t>(cells.size())}, self);
          },
          "(N,) int32 per input point: its cell (row * cols + col), -1 for no return.")
      .def_property_readonly(
          "xyz",
          [](const DetectionResult& d) { return ImageXyz(d.image); },
          "(rows, cols, 3) float32: each cell's point in the sensor frame [m], NaN where no "
          "return.")
      .def_property_readonly(
          "valid",
          [](py::object self) {
            const auto& d = self.cast<const DetectionResult&>();
            return View(d.image.valid_mask(), {d.image.height(), d.image.width()}, self);
          },
          "(rows, cols) uint8: 1 where the cell holds a return.")
      .def_property_readonly(
          "R_level_sensor",
          [](const DetectionResult& d) -> Eigen::Matrix3d { return d.image.R_level_sensor(); },
          "(3, 3): rotates sensor-frame points into the level frame (z up along gravity).")
      .def_property_readonly(
          "up", [](const DetectionResult& d) -> Eigen::Vector3d { return d.image.up(); },
          "(3,): gravity's unit up vector in the sensor frame.")
      .def_property_readonly(
          "segments_json", [](const DetectionResult& d) { return d.segments_json; },
          "The text of segments.json (format cairn-segments-2) for this detection.")
      .def_property_readonly(
          "segments",
          [](const DetectionResult& d) {
            const py::object doc = ParseJson(d.segments_json);
            return py::object(doc["segments"]);  // a new reference: doc goes out of scope
          },
          "One dict per segment, as segments.json lists them: id, class, reason and every "
          "measure, units in the key names (m, m^2, m^3, deg for slopes).")
      .def_property_readonly(
          "kept", [](const DetectionResult& d) { return d.classification.kept; },
          "Segments kept by the rules.")
      .def_property_readonly(
          "rejected", [](const DetectionResult& d) { return d.classification.rejected; },
          "Segments rejected by the rules.")
      .def_property_readonly(
          "obstacle_points",
          [](const DetectionResult& d) { return d.detection.stats.obstacle_points; },
          "Obstacle cells found.")
      .def_property_readonly(
          "valid_count", [](const DetectionResult& d) { return d.image.valid_count(); },
          "Cells with a return.")
      .def_property_readonly("method", [](const DetectionResult& d) { return d.method; },
                             "\"cone\" or \"column\".")
      .def_property_readonly(
          "detect_seconds", [](const DetectionResult& d) { return d.detect_s; },
          "Wall time of the C++ detection alone, as `cairn detect` reports it [s].")
      .def_property_readonly(
          "cpp_seconds", [](const DetectionResult& d) { return d.cpp_s; },
          "Wall time of all the C++ work of the call, without Python (layout, image, "
          "detection, rules, labels, segments.json) [s]; the rest of a call's time is the "
          "binding's overhead.")
      .def("__repr__", [](const DetectionResult& d) {
        return "cairn.Detection(" + std::to_string(d.detection.height) + "x" +
               std::to_string(d.detection.width) + ", " +
               std::to_string(d.detection.segments.size()) + " segments, " +
               std::to_string(d.classification.kept) + " kept)";
      });

  m.def("detect_points", &DetectPoints, py::arg("points"), py::arg("sensor") = py::none(),
        py::arg("settings") = nullptr, py::kw_only(),
        py::arg("up") = std::vector<double>{0.0, 0.0, 1.0}, py::arg("organised") = "auto",
        py::arg("columns") = 0, py::arg("method") = "cone", py::arg("rules") = true,
        py::arg("feet") = true, py::arg("source") = "points",
        "Detects obstacles in one LiDAR scan, as `cairn detect --points` does.\n\n"
        "points: (N, 3) or (N, 4) array, x, y, z [m] in the LiDAR frame (x forward, y left, z "
        "up) and optional intensity; (0, 0, 0) or all-NaN = no return. sensor: a preset "
        "(\"HDL-64E\", \"VLP-16\", \"VLP-32C\", \"OS1-64\") or None to find the rings from the "
        "data. up: gravity's up vector in the LiDAR frame. organised: \"auto\", \"yes\" or "
        "\"no\" (Ouster order, index = col * rings + ring). columns: azimuth steps of an "
        "unorganised scan (0: the sensor's). method: \"cone\" or \"column\" (the baseline). "
        "rules: False keeps every segment (--no-rules). feet: False counts each obstacle's foot "
        "as ground (--no-feet). source: names the scan in messages. Runs without the GIL.");
  m.def("detect_depth", &DetectDepth, py::arg("depth_m"), py::kw_only(), py::arg("fx"),
        py::arg("fy"), py::arg("cx"), py::arg("cy"),
        py::arg("up") = std::vector<double>{0.0, -1.0, 0.0}, py::arg("settings") = nullptr,
        py::arg("method") = "cone", py::arg("rules") = true, py::arg("feet") = true,
        py::arg("source") = "depth",
        "Detects obstacles in one z-depth image, as `cairn detect --depth` does.\n\n"
        "depth_m: (H, W) z-depth [m] (distance along the optical axis; 0, negative or "
        "non-finite = no return). fx, fy: focal lengths [px]; cx, cy: principal point [px] "
        "(integer coordinates are pixel centres). up: gravity's up vector in the optical frame "
        "(x right, y down, z forward). Other arguments as detect_points. Runs without the GIL.");
}

}  // namespace cairn::python
