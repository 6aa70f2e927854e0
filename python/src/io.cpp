// Readers a Python user needs, each the library's own: point files, labels, depth images and
// intrinsics, the images `cairn detect` writes, KITTI sequences, and the recorded sequences
// of cairn::sources (KITTI, MRPT rawlogs, depth folders) as iterators of cairn.Frame.
#include <memory>
#include <string>
#include <utility>

#include "cairn/map/frame_imu.hpp"
#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/detection_files.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/kitti.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/sources/frame_source.hpp"
#include "cairn/sources/rawlog_frames.hpp"
#include "types.hpp"

namespace cairn::python {
namespace {

py::array_t<float> ReadPoints(const std::string& path) {
  od::PointCloud cloud;
  {
    py::gil_scoped_release release;
    cloud = Unwrap(od::io::ReadPointFile(path));
  }
  std::vector<float> xyzi(cloud.points.size() * 4);
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    xyzi[4 * i] = cloud.points[i].x();
    xyzi[4 * i + 1] = cloud.points[i].y();
    xyzi[4 * i + 2] = cloud.points[i].z();
    xyzi[4 * i + 3] = i < cloud.intensity.size() ? cloud.intensity[i] : 0.0f;
  }
  return Take(std::move(xyzi), {static_cast<py::ssize_t>(cloud.points.size()), 4});
}

py::array_t<std::uint32_t> ReadLabels(const std::string& path) {
  std::vector<std::uint32_t> labels;
  {
    py::gil_scoped_release release;
    labels = Unwrap(od::io::ReadLabelFile(path));
  }
  const auto n = static_cast<py::ssize_t>(labels.size());
  return Take(std::move(labels), {n});
}

void WriteLabels(const std::string& path, const InArray<std::uint32_t>& labels) {
  if (labels.ndim() != 1) throw CairnError(path + ": labels: expected an (N,) array");
  std::vector<std::uint32_t> data(labels.data(), labels.data() + labels.size());
  py::gil_scoped_release release;
  Check(od::io::WriteLabelFile(path, data));
}

template <typename T>
py::array_t<T> GridArray(od::Grid<T>&& grid) {
  const int h = grid.height, w = grid.width;
  return Take(std::move(grid.data), {h, w});
}

std::shared_ptr<DetectionResult> DetectFrame(const Frame& frame, const Settings* settings,
                                             const std::string& method, bool rules, bool feet) {
  if (!frame.skip.empty()) {
    throw CairnError(frame.name + ": " + frame.skip + " (" + frame.skip_detail +
                     "): a skipped frame has no image to detect on");
  }
  const od::io::DetectRunOptions options = RunOptions(method, rules, feet);
  static const Settings kDefaults;
  const Settings& s = settings != nullptr ? *settings : kDefaults;
  py::gil_scoped_release release;
  od::io::RunDescription run;
  run.depth_file = frame.name;
  return std::make_shared<DetectionResult>(DetectOn(frame.image, s, options, run));
}

/// A sources::FrameSource as a Python iterator of cairn.Frame.
struct FrameIterator {
  std::unique_ptr<sources::FrameSource> source;
};

Frame NextFrame(FrameIterator& it) {
  std::optional<sources::SequenceFrame> next;
  {
    py::gil_scoped_release release;
    next = Unwrap(it.source->Next());
  }
  if (!next) throw py::stop_iteration();
  Frame f;
  f.index = next->index;
  f.stamp_s = next->stamp_s;
  f.name = next->name;
  f.T_world_sensor = next->T_world_sensor;
  f.T_world_body = next->T_world_body;
  f.tilt_from_imu = next->tilt_from_imu;
  // As `cairn map` hands the IMU readings to the Mapper.
  f.imu = map::ImuSamplesOf(*next);
  f.skip = next->used() ? std::string() : std::string(sources::SourceSkipName(next->skip));
  f.skip_detail = next->skip_detail;
  f.image = std::move(next->image);
  return f;
}

py::array_t<double> Pose(const Eigen::Isometry3d& T) {
  return py::cast(Eigen::Matrix4d(T.matrix()));
}

}  // namespace

void RegisterIo(py::module_& m) {
  m.def("read_points", &ReadPoints, py::arg("path"),
        "Reads a LiDAR scan as `cairn detect --points` does (KITTI .bin, PLY, x y z text, "
        "optionally .bz2): (N, 4) float32 x, y, z [m] (sensor frame) and intensity.");
  m.def("read_labels", &ReadLabels, py::arg("path"),
        "Reads a SemanticKITTI .label file: (N,) uint32 (low 16 bits class, high 16 id).");
  m.def("write_labels", &WriteLabels, py::arg("path"), py::arg("labels"),
        "Writes a .label file (uint32 per point, little-endian), atomically.");
  py::class_<od::io::CameraIntrinsics>(m, "Intrinsics",
                                       "A camera YAML as `cairn detect --intrinsics` reads it.")
      .def_property_readonly("width", [](const od::io::CameraIntrinsics& c) { return c.model.width; })
      .def_property_readonly("height", [](const od::io::CameraIntrinsics& c) { return c.model.height; })
      .def_property_readonly("fx", [](const od::io::CameraIntrinsics& c) { return c.model.fx; },
                             "[px]")
      .def_property_readonly("fy", [](const od::io::CameraIntrinsics& c) { return c.model.fy; },
                             "[px]")
      .def_property_readonly("cx", [](const od::io::CameraIntrinsics& c) { return c.model.cx; },
                             "[px]")
      .def_property_readonly("cy", [](const od::io::CameraIntrinsics& c) { return c.model.cy; },
                             "[px]")
      .def_property_readonly("depth_scale_m",
                             [](const od::io::CameraIntrinsics& c) { return c.depth_scale_m; },
                             "Metres per PNG unit.")
      .def_property_readonly(
          "up", [](const od::io::CameraIntrinsics& c) { return std::vector<double>{c.up.x(), c.up.y(), c.up.z()}; },
          "Gravity's unit up vector in the optical frame (x right, y down, z forward).");
  m.def(
      "load_intrinsics",
      [](const std::string& path) {
        py::gil_scoped_release release;
        return Unwrap(od::io::LoadIntrinsics(path));
      },
      py::arg("path"), "Reads and validates a camera YAML (width, height, fx, fy, cx, cy, "
                       "depth_scale, up or pitch_deg).");
  m.def(
      "read_depth",
      [](const std::string& path, const od::io::CameraIntrinsics& intrinsics) {
        od::Grid<float> depth;
        {
          py::gil_scoped_release release;
          depth = Unwrap(od::io::ReadDepthImage(path, intrinsics));
        }
        return GridArray(std::move(depth));
      },
      py::arg("path"), py::arg("intrinsics"),
      "Reads a 16-bit depth PNG (value * depth_scale) or a float TIFF: (H, W) float32 z-depth "
      "[m], 0 = no return.");
  m.def(
      "read_segments_png",
      [](const std::string& path) {
        od::Grid<std::int32_t> g;
        {
          py::gil_scoped_release release;
          g = Unwrap(od::io::ReadSegmentsPng(path));
        }
        return GridArray(std::move(g));
      },
      py::arg("path"), "segments.png of `cairn detect`: (H, W) int32 segment ids.");
  m.def(
      "read_classes_png",
      [](const std::string& path) {
        od::Grid<std::uint8_t> g;
        {
          py::gil_scoped_release release;
          g = Unwrap(od::io::ReadClassesPng(path));
        }
        return GridArray(std::move(g));
      },
      py::arg("path"), "classes.png of `cairn detect`: (H, W) uint8, 0 none, 1 kept, 2 rejected.");

  py::class_<od::io::KittiFrame>(m, "KittiScan", "One scan of a KITTI odometry sequence.")
      .def_readonly("index", &od::io::KittiFrame::index, "The scan's number (its file name).")
      .def_readonly("stamp_s", &od::io::KittiFrame::stamp_s, "times.txt [s].")
      .def_property_readonly("path", [](const od::io::KittiFrame& f) { return f.scan.string(); },
                             "velodyne/NNNNNN.bin")
      .def_property_readonly(
          "T_map_velodyne",
          [](const od::io::KittiFrame& f) -> py::object {
            if (!f.T_map_velodyne) return py::none();
            return Pose(*f.T_map_velodyne);
          },
          "(4, 4) the velodyne's pose in the z-up map frame (velodyne of scan 0), from "
          "poses.txt (Tr^-1 * Pose * Tr); None without poses.txt.");
  m.def(
      "open_kitti",
      [](const std::string& folder, const std::string& range) {
        py::gil_scoped_release release;
        od::io::KittiSequence sequence = Unwrap(od::io::OpenKittiSequence(folder));
        if (range.empty()) return sequence.frames;
        return Unwrap(od::io::SelectKittiFrames(sequence, range));
      },
      py::arg("folder"), py::arg("range") = "",
      "The scans of a KITTI odometry sequence folder (velodyne/, calib.txt, times.txt, "
      "poses.txt), optionally those of range \"A:B\" (inclusive): a list of cairn.KittiScan.");

  py::class_<Frame>(m, "Frame", "One frame of a recorded sequence, placed in the world.")
      .def_readonly("index", &Frame::index, "Among the source's frames, skipped ones included.")
      .def_readonly("stamp_s", &Frame::stamp_s, "[s]")
      .def_readonly("name", &Frame::name, "For messages.")
      .def_property_readonly("T_world_sensor", [](const Frame& f) { return Pose(f.T_world_sensor); },
                             "(4, 4) odometry pose of the sensor in the world (z up) [m].")
      .def_property_readonly("T_world_body", [](const Frame& f) { return Pose(f.T_world_body); })
      .def_property_readonly("used", [](const Frame& f) { return f.skip.empty(); })
      .def_readonly("skip", &Frame::skip, "\"\" when used, else \"missing\" or \"truncated\".")
      .def_readonly("skip_detail", &Frame::skip_detail)
      .def_property_readonly("width", [](const Frame& f) { return f.image.width(); })
      .def_property_readonly("height", [](const Frame& f) { return f.image.height(); })
      .def_property_readonly(
          "xyz",
          [](const Frame& f) { return ImageXyz(f.image); },
          "(rows, cols, 3) float32 range image in the sensor frame [m], NaN where no return.")
      .def("__repr__", [](const Frame& f) {
        return "cairn.Frame(" + std::to_string(f.index) + ", '" + f.name + "'" +
               (f.skip.empty() ? std::string() : ", skipped: " + f.skip) + ")";
      });

  py::class_<FrameIterator>(m, "FrameSource", "An iterator of cairn.Frame over a recording.")
      .def("__iter__", [](FrameIterator& it) -> FrameIterator& { return it; })
      .def("__next__", &NextFrame)
      .def("__len__", [](const FrameIterator& it) { return it.source->total(); },
           "Frames the source gives, skipped ones included.");
  m.def(
      "kitti_frames",
      [](const std::string& folder, const std::string& range, const std::string& lidar,
         const std::string& sequence) {
        py::gil_scoped_release release;
        return FrameIterator{Unwrap(sources::OpenKittiFrames(folder, sequence, range, lidar))};
      },
      py::arg("folder"), py::arg("range") = "", py::arg("lidar") = "HDL-64E",
      py::arg("sequence") = "",
      "The frames `cairn map --kitti` reads: scans placed by poses.txt, rings of preset "
      "`lidar`, scans `range` \"A:B\" (inclusive).");
  m.def(
      "rawlog_frames",
      [](const std::string& path, const std::string& label, const Settings* settings) {
        static const Settings kDefaults;
        const Settings& s = settings != nullptr ? *settings : kDefaults;
        py::gil_scoped_release release;
        return FrameIterator{Unwrap(sources::OpenRawlogFrames(path, label, s.map.stereo))};
      },
      py::arg("path"), py::arg("label") = "", py::arg("settings") = nullptr,
      "The range frames of an MRPT rawlog (of sensor `label`, or every one), as `cairn map "
      "--rawlog` reads them; stereo pairs matched with the settings' stereo section.");
  m.def(
      "depth_frames",
      [](const std::string& folder, const std::string& poses, const std::string& intrinsics) {
        py::gil_scoped_release release;
        return FrameIterator{Unwrap(sources::OpenDepthFolderFrames(folder, poses, intrinsics))};
      },
      py::arg("folder"), py::arg("poses"), py::arg("intrinsics") = "",
      "A folder of 16-bit depth PNGs with a TUM pose file, as `cairn map --frames` reads it.");
  m.def("detect_frame", &DetectFrame, py::arg("frame"), py::arg("settings") = nullptr,
        py::kw_only(), py::arg("method") = "cone", py::arg("rules") = true,
        py::arg("feet") = true, "Detects obstacles in a cairn.Frame's range image.");
}

}  // namespace cairn::python
