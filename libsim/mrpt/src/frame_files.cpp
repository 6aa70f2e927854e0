#include "cairn/sim/mrpt/frame_files.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/geometry.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"

namespace cairn::sim {
namespace {

namespace fs = std::filesystem;
Status MakeDirectory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error{dir.string() + ": cannot create the directory: " + ec.message()};
  return {};
}

Status WritePng(const fs::path& path, const cv::Mat& image) {
  return util::WriteImageAtomic(path, image, ".png", {cv::IMWRITE_PNG_COMPRESSION, 3});
}

template <typename T>
std::string_view Bytes(const std::vector<T>& v) {
  return {reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T)};
}

std::string Format(const char* fmt, double a, double b, double c) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c);
  return buf;
}

}  // namespace

int TruthNoHitLabel(const std::vector<std::int32_t>& object_ids) {
  const auto max_id =
      object_ids.empty() ? 0 : *std::max_element(object_ids.begin(), object_ids.end());
  return max_id <= 254 ? 255 : 65535;
}

Status WriteObjectIdPng(const fs::path& path, const od::Grid<std::int32_t>& ids) {
  if (ids.width <= 0 || ids.height <= 0 ||
      ids.data.size() != static_cast<std::size_t>(ids.width) * ids.height) {
    return Error{path.string() + ": " + std::to_string(ids.data.size()) + " ids for a " +
                 std::to_string(ids.width) + "x" + std::to_string(ids.height) + " image"};
  }
  for (std::size_t i = 0; i < ids.data.size(); ++i) {
    if (ids.data[i] < kNoHitId || ids.data[i] > 65534) {
      return Error{path.string() + ": object id " + std::to_string(ids.data[i]) +
                   " does not fit a 16-bit truth image (expected -1..65534)"};
    }
  }
  const int no_hit = TruthNoHitLabel(ids.data);
  cv::Mat image(ids.height, ids.width, no_hit == 255 ? CV_8UC1 : CV_16UC1);
  for (int r = 0; r < ids.height; ++r) {
    for (int c = 0; c < ids.width; ++c) {
      const int id = ids.at(r, c);
      const int label = id == kNoHitId ? no_hit : id;
      if (no_hit == 255) {
        image.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(label);
      } else {
        image.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(label);
      }
    }
  }
  return WritePng(path, image);
}

Expected<od::Grid<std::int32_t>> ReadObjectIdPng(const fs::path& path) {
  const cv::Mat image = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  if (image.empty()) return Error{path.string() + ": cannot read the image"};
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U)) {
    return Error{path.string() + ": expected an 8- or 16-bit single-channel truth image"};
  }
  const bool wide = image.depth() == CV_16U;
  const int no_hit = wide ? 65535 : 255;
  od::Grid<std::int32_t> ids;
  ids.width = image.cols;
  ids.height = image.rows;
  ids.data.resize(static_cast<std::size_t>(ids.width) * ids.height);
  for (int r = 0; r < ids.height; ++r) {
    for (int c = 0; c < ids.width; ++c) {
      const int label = wide ? image.at<std::uint16_t>(r, c) : image.at<std::uint8_t>(r, c);
      ids.at(r, c) = label == no_hit ? kNoHitId : label;
    }
  }
  return ids;
}

Status WriteTruthYaml(const fs::path& path, const Scene& scene) {
  YAML::Emitter out;
  out << YAML::BeginMap << YAML::Key << "objects" << YAML::Value << YAML::BeginSeq;
  for (const Object& object : scene.objects()) {
    const BoundingSphere bound = Bound(object.shape);
    const double ground = scene.terrain().Height(bound.centre.x(), bound.centre.y());
    const double height = std::round((Top(object.shape) - ground) * 1000.0) / 1000.0;
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << object.id
        << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << object.name << YAML::Key
        << "is_obstacle" << YAML::Value << object.is_obstacle << YAML::Key << "height_m"
        << YAML::Value << height << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  if (!out.good()) return Error{path.string() + ": cannot write YAML: " + out.GetLastError()};
  const std::string text =
      "# Ground truth of truth.png (made by cairn synth): 0 = terrain, 255 (8-bit) or 65535\n"
      "# (16-bit) = no return, else the object id. height_m: the object's top above the\n"
      "# ground under its centre.\n" +
      std::string(out.c_str()) + "\n";
  return util::WriteFileAtomic(path, text);
}

double DepthScaleFor(double max_depth_m) {
  constexpr double kMillimetre = 0.001;
  if (!(max_depth_m > 65535.0 * kMillimetre)) return kMillimetre;
  return std::ceil(max_depth_m / 65535.0 * 1e4) / 1e4;  // 0.1 mm steps
}

Expected<CameraFrameFiles> WriteCameraFrame(const fs::path& dir, const DepthFrame& frame,
                                            const Scene& scene) {
  if (Status s = MakeDirectory(dir); !s) return s.error();
  CameraFrameFiles files;
  files.depth_png = dir / "depth.png";
  files.intrinsics_yaml = dir / "intrinsics.yaml";
  files.truth_png = dir / "truth.png";
  files.truth_yaml = dir / "truth.yaml";

  od::Grid<float> depth;
  depth.width = frame.width();
  depth.height = frame.height();
  depth.data = frame.depth_m;
  float max_depth = 0.0f;
  for (float d : depth.data) {
    if (std::isfinite(d)) max_depth = std::max(max_depth, d);
  }
  files.depth_scale_m = DepthScaleFor(max_depth);
  od::Grid<std::int32_t> ids;
  ids.width = frame.width();
  ids.height = frame.height();
  ids.data = frame.object_id;

  if (Status s = od::io::WriteDepthPng(files.depth_png, depth, files.depth_scale_m); !s) {
    return s.error();
  }
  const od::io::CameraIntrinsics intrinsics{frame.model, files.depth_scale_m, frame.up_optical};
  if (Status s = od::io::WriteIntrinsics(files.intrinsics_yaml, intrinsics,
                                         "Camera of a synthetic frame (cairn synth); read by "
                                         "cairn detect.");
      !s) {
    return s.error();
  }
  if (Status s = WriteObjectIdPng(files.truth_png, ids); !s) return s.error();
  if (Status s = WriteTruthYaml(files.truth_yaml, scene); !s) return s.error();
  return files;
}

Status WriteKittiPoints(const fs::path& path, const LidarScan& scan) {
  std::vector<float> values;
  values.reserve(scan.points.size() * 4);
  for (const Eigen::Vector3f& p : scan.points) {
    values.insert(values.end(), {p.x(), p.y(), p.z(), 0.0f});
  }
  return util::WriteFileAtomic(path, Bytes(values));
}

Status WriteLidarLabels(const fs::path& path, const LidarScan& scan) {
  if (scan.object_id.size() != scan.points.size()) {
    return Error{path.string() + ": " + std::to_string(scan.object_id.size()) + " object ids for " +
                 std::to_string(scan.points.size()) + " points"};
  }
  std::vector<std::uint32_t> labels(scan.object_id.size());
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (scan.object_id[i] < 0 || scan.object_id[i] > 65535) {
      return Error{path.string() + ": object id " + std::to_string(scan.object_id[i]) +
                   " at point " + std::to_string(i) + " (expected 0..65535)"};
    }
    labels[i] = static_cast<std::uint32_t>(scan.object_id[i]);
  }
  return util::WriteFileAtomic(path, Bytes(labels));
}

Status WriteLidarRowCol(const fs::path& path, const LidarScan& scan) {
  if (scan.ring.size() != scan.points.size() || scan.column.size() != scan.points.size()) {
    return Error{path.string() + ": rings or columns do not match the " +
                 std::to_string(scan.points.size()) + " points"};
  }
  std::vector<std::uint16_t> rowcol(2 * scan.points.size());
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    rowcol[2 * i] = static_cast<std::uint16_t>(scan.ring[i]);
    rowcol[2 * i + 1] = static_cast<std::uint16_t>(scan.column[i]);
  }
  return util::WriteFileAtomic(path, Bytes(rowcol));
}

Expected<LidarFrameFiles> WriteLidarFrame(const fs::path& dir, const LidarScan& scan,
                                          const LidarSpec& lidar, const Eigen::Vector3d& up_lidar,
                                          const Scene& scene) {
  if (Status s = MakeDirectory(dir); !s) return s.error();
  LidarFrameFiles files;
  files.points_bin = dir / "points.bin";
  files.labels = dir / "labels.label";
  files.rowcol_bin = dir / "rowcol.bin";
  files.lidar_yaml = dir / "lidar.yaml";
  files.truth_yaml = dir / "truth.yaml";
  if (Status s = WriteKittiPoints(files.points_bin, scan); !s) return s.error();
  if (Status s = WriteLidarLabels(files.labels, scan); !s) return s.error();
  if (Status s = WriteLidarRowCol(files.rowcol_bin, scan); !s) return s.error();

  std::string text =
      "# LiDAR of a synthetic scan (cairn synth): points.bin in its frame (x forward, y left,\n"
      "# z up), one row of rowcol.bin per point.\n";
  text += "preset: \"" + lidar.preset + "\"\n";
  text += "azimuth_steps: " + std::to_string(lidar.azimuth_steps) + "\n";
  text += "elevations_deg: [";
  for (std::size_t i = 0; i < lidar.elevations_rad.size(); ++i) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%s%.6f", i ? ", " : "", lidar.elevations_rad[i] * kRadToDeg);
    text += buf;
  }
  text += "]\n";
  text += Format("up: [%.12f, %.12f, %.12f]  # gravity's up in the LiDAR frame\n", up_lidar.x(),
                 up_lidar.y(), up_lidar.z());
  if (Status s = util::WriteFileAtomic(files.lidar_yaml, text); !s) return s.error();
  if (Status s = WriteTruthYaml(files.truth_yaml, scene); !s) return s.error();
  return files;
}

}  // namespace cairn::sim
