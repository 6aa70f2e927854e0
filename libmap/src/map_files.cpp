#include "cairn/map/map_files.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"

namespace cairn::map {
namespace {

// A tree of OctoMap's own types, built node by node with the structure of another tree.
template <class Tree>
class TreeBuilder : public Tree {
 public:
  explicit TreeBuilder(double resolution_m) : Tree(resolution_m) {}

  /// The node at `depth` on `key`'s path, created with its ancestors when missing.
  typename Tree::NodeType* NodeAt(const octomap::OcTreeKey& key, unsigned depth) {
    if (this->root == nullptr) {
      this->root = new typename Tree::NodeType();
      ++this->tree_size;
    }
    typename Tree::NodeType* node = this->root;
    for (unsigned d = 0; d < depth; ++d) {
      const unsigned pos =
          octomap::computeChildIdx(key, static_cast<int>(this->tree_depth - 1 - d));
      if (!this->nodeChildExists(node, pos)) this->createNodeChild(node, pos);
      node = this->getNodeChild(node, pos);
    }
    return node;
  }
};

template <class Tree>
void CopySensorModel(const TerrainOcTree& from, Tree& to) {
  to.setProbHit(from.getProbHit());
  to.setProbMiss(from.getProbMiss());
  to.setClampingThresMin(from.getClampingThresMin());
  to.setClampingThresMax(from.getClampingThresMax());
  to.setOccupancyThres(from.getOccupancyThres());
}

Status WriteBytes(const std::filesystem::path& path, const std::string& bytes) {
  return util::WriteFileAtomic(path, bytes);
}

// A grid image of `box` (map_server's orientation: row 0 is the top, highest y).
template <typename T, typename F>
cv::Mat GridImage(const TerrainMap& map, const CellBox& box, int type, F&& pixel) {
  const Eigen::Vector2i size = box.size();
  cv::Mat image(size.y(), size.x(), type);
  for (int r = 0; r < size.y(); ++r) {
    for (int c = 0; c < size.x(); ++c) {
      const CellIndex index(box.min.x() + c, box.max.y() - r);
      image.at<T>(r, c) = pixel(map.grid().Find(index));
    }
  }
  return image;
}

std::string Number(double value) {
  std::ostringstream out;
  out << std::setprecision(12) << value;
  return out.str();
}

std::string OriginText(const TerrainMap& map, const CellBox& box) {
  const double s = map.config().cell_size_m;
  return "[" + Number(box.min.x() * s) + ", " + Number(box.min.y() * s) + ", 0.0]";
}

std::uint8_t PgmValue(const Cell* cell, PgmMode mode) {
  const Cost cost = cell != nullptr ? cell->cost : kUnknownCost;
  if (mode == PgmMode::kRaw) {
    const std::int8_t occupancy = OccupancyFromCost(cost);
    return occupancy < 0 ? 255 : static_cast<std::uint8_t>(occupancy);
  }
  if (cost == kLethalCost) return 0;
  if (cost == kUnknownCost) return 205;
  return 254;
}

}  // namespace

Expected<CellBox> ExportBounds(const TerrainMap& map) {
  const TerrainGrid& grid = map.grid();
  if (grid.rolling()) {
    return CellBox{grid.min_index(), grid.min_index() + grid.extent() - CellIndex::Ones()};
  }
  const std::optional<CellBox> observed = map.ObservedBounds();
  if (!observed) return Error{"the map has observed nothing yet: no grid to write"};
  return *observed;
}

Expected<GridExport> ExportGrid(const TerrainMap& map) {
  Expected<CellBox> box = ExportBounds(map);
  if (!box) return box.error();
  GridExport out;
  out.box = *box;
  out.width = box->size().x();
  out.height = box->size().y();
  out.resolution_m = map.config().cell_size_m;
  out.origin_m = box->min.cast<double>() * out.resolution_m;
  const std::size_t cells = static_cast<std::size_t>(out.width) * out.height;
  out.cost.resize(cells);
  out.elevation_m.resize(cells);
  // The same cell for each pixel as GridImage, so that the arrays equal the files.
  for (int r = 0; r < out.height; ++r) {
    for (int c = 0; c < out.width; ++c) {
      const Cell* cell = map.grid().Find(CellIndex(box->min.x() + c, box->max.y() - r));
      const std::size_t i = static_cast<std::size_t>(r) * out.width + c;
      out.cost[i] = cell != nullptr ? cell->cost : kUnknownCost;
      out.elevation_m[i] = cell != nullptr && cell->has_elevation()
                               ? cell->elevation_mean_m
                               : std::numeric_limits<float>::quiet_NaN();
    }
  }
  return out;
}

std::unique_ptr<octomap::OcTree> ToOcTree(const TerrainOcTree& tree) {
  auto out = std::make_unique<TreeBuilder<octomap::OcTree>>(tree.getResolution());
  CopySensorModel(tree, *out);
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    out->NodeAt(it.getKey(), it.getDepth())->setLogOdds(it->getLogOdds());
  }
  out->updateInnerOccupancy();
  return out;
}

std::unique_ptr<octomap::ColorOcTree> ToColorOcTree(const TerrainOcTree& tree) {
  auto out = std::make_unique<TreeBuilder<octomap::ColorOcTree>>(tree.getResolution());
  CopySensorModel(tree, *out);
  double min_x = 0, min_y = 0, min_z = 0, max_x = 0, max_y = 0, max_z = 0;
  tree.getMetricMin(min_x, min_y, min_z);
  tree.getMetricMax(max_x, max_y, max_z);
  const double span = std::max(max_z - min_z, 1e-6);
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    octomap::ColorOcTreeNode* node = out->NodeAt(it.getKey(), it.getDepth());
    node->setLogOdds(it->getLogOdds());
    if (tree.IsObstacle(*it)) {
      node->setColor(255, 0, 0);
    } else {
      const double t = std::clamp((it.getZ() - min_z) / span, 0.0, 1.0);
      node->setColor(static_cast<std::uint8_t>(40 + 215 * t),
                     static_cast<std::uint8_t>(160 + 80 * t),
                     static_cast<std::uint8_t>(140 * (1.0 - t)));
    }
  }
  out->updateInnerOccupancy();
  return out;
}

Status WriteOctomapBinary(const TerrainMap& map, const std::filesystem::path& path) {
  std::unique_ptr<octomap::OcTree> tree = ToOcTree(map.octree());
  std::ostringstream bytes;
  if (!tree->writeBinary(bytes)) return Error{path.string() + ": OctoMap cannot write the tree"};
  return WriteBytes(path, bytes.str());
}

Status WriteOctomapFull(const TerrainMap& map, const std::filesystem::path& path) {
  std::unique_ptr<octomap::OcTree> tree = ToOcTree(map.octree());
  std::ostringstream bytes;
  if (!tree->write(bytes)) return Error{path.string() + ": OctoMap cannot write the tree"};
  return WriteBytes(path, bytes.str());
}

Status WriteObstacleOctomap(const TerrainMap& map, const std::filesystem::path& path) {
  std::unique_ptr<octomap::ColorOcTree> tree = ToColorOcTree(map.octree());
  std::ostringstream bytes;
  if (!tree->write(bytes)) return Error{path.string() + ": OctoMap cannot write the tree"};
  return WriteBytes(path, bytes.str());
}

Status WriteCostGrid(const TerrainMap& map, const std::filesystem::path& yaml_path, PgmMode mode) {
  Expected<CellBox> box = ExportBounds(map);
  if (!box) return Error{yaml_path.string() + ": " + box.error().message};
  std::filesystem::path pgm_path = yaml_path;
  pgm_path.replace_extension(".pgm");
  if (pgm_path == yaml_path) return Error{yaml_path.string() + ": expected a .yaml file name"};
  const cv::Mat image = GridImage<std::uint8_t>(
      map, *box, CV_8UC1, [&](const Cell* cell) { return PgmValue(cell, mode); });
  if (Status s = util::WriteImageAtomic(pgm_path, image, ".pgm"); !s) return s;
  std::ostringstream yaml;
  yaml << "image: " << pgm_path.filename().string() << "\n"
       << "mode: " << (mode == PgmMode::kRaw ? "raw" : "trinary") << "\n"
       << "resolution: " << Number(map.config().cell_size_m) << "\n"
       << "origin: " << OriginText(map, *box) << "\n"
       << "negate: 0\n"
       << "occupied_thresh: 0.65\n"
       << "free_thresh: 0.196\n";
  return WriteBytes(yaml_path, yaml.str());
}

Status WriteCostColorPng(const TerrainMap& map, const std::filesystem::path& path) {
  Expected<CellBox> box = ExportBounds(map);
  if (!box) return Error{path.string() + ": " + box.error().message};
  const cv::Mat image = GridImage<cv::Vec3b>(map, *box, CV_8UC3, [](const Cell* cell) {
    const Cost cost = cell != nullptr ? cell->cost : kUnknownCost;
    if (cost == kUnknownCost) return cv::Vec3b(128, 128, 128);
    if (cost == kLethalCost) return cv::Vec3b(0, 0, 220);
    if (cost == kInscribedCost) return cv::Vec3b(160, 40, 140);
    // BGR: white (0) -> yellow (126) -> orange (252).
    const double t = cost / static_cast<double>(kMaxTerrainCost);
    const double blue = 255.0 * std::max(0.0, 1.0 - 2.0 * t);
    const double green = t <= 0.5 ? 255.0 : 255.0 - 2.0 * (t - 0.5) * 135.0;
    return cv::Vec3b(static_cast<std::uint8_t>(blue), static_cast<std::uint8_t>(green), 255);
  });
  return util::WriteImageAtomic(path, image, ".png");
}

Status WriteElevationTiff(const TerrainMap& map, const std::filesystem::path& path) {
  Expected<CellBox> box = ExportBounds(map);
  if (!box) return Error{path.string() + ": " + box.error().message};
  const cv::Mat image = GridImage<float>(map, *box, CV_32FC1, [](const Cell* cell) {
    return cell != nullptr && cell->has_elevation() ? cell->elevation_mean_m
                                                    : std::numeric_limits<float>::quiet_NaN();
  });
  if (Status s = util::WriteImageAtomic(path, image, ".tiff"); !s) return s;
  std::filesystem::path yaml_path = path;
  yaml_path.replace_extension(".yaml");
  std::ostringstream yaml;
  yaml << "image: " << path.filename().string() << "\n"
       << "layer: elevation_mean  # ground elevation, world z [m]\n"
       << "units: m\n"
       << "nodata: .nan\n"
       << "resolution: " << Number(map.config().cell_size_m) << "\n"
       << "origin: " << OriginText(map, *box) << "\n";
  return WriteBytes(yaml_path, yaml.str());
}

Status WriteObstaclesJson(const TerrainMap& map, const std::filesystem::path& path) {
  using nlohmann::json;
  const auto vec = [](const auto& v) {
    json a = json::array();
    for (int i = 0; i < v.size(); ++i) a.push_back(v[i]);
    return a;
  };
  json doc;
  doc["frame"] = "world";
  doc["units"] = "m, s";
  doc["cell_size"] = map.config().cell_size_m;
  doc["frames_integrated"] = map.frames_integrated();
  doc["obstacles_retired"] = map.obstacles_retired();
  json list = json::array();
  for (const Obstacle& o : map.obstacles()) {
    json cells = json::array();
    for (const CellIndex& c : o.cells) cells.push_back({c.x(), c.y()});
    list.push_back({{"id", o.id},
                    {"bbox_min", vec(o.bbox_min)},
                    {"bbox_max", vec(o.bbox_max)},
                    {"centroid", vec(o.centroid)},
                    {"height", o.height_m},
                    {"point_count", o.point_count},
                    {"footprint_min", vec(o.footprint_min)},
                    {"footprint_max", vec(o.footprint_max)},
                    {"footprint_area", o.footprint_area_m2},
                    {"cells", cells},
                    {"first_seen", o.first_seen_s},
                    {"last_seen", o.last_seen_s},
                    {"frames", o.frames},
                    {"merged_ids", o.merged_ids}});
  }
  doc["obstacles"] = std::move(list);
  return WriteBytes(path, doc.dump(2) + "\n");
}

Status WriteMapFiles(const TerrainMap& map, const std::filesystem::path& dir, PgmMode mode) {
  if (Status s = WriteOctomapBinary(map, dir / "map.bt"); !s) return s;
  if (Status s = WriteOctomapFull(map, dir / "map.ot"); !s) return s;
  if (Status s = WriteObstacleOctomap(map, dir / "obstacles.ot"); !s) return s;
  if (Status s = WriteCostGrid(map, dir / "cost.yaml", mode); !s) return s;
  if (Status s = WriteCostColorPng(map, dir / "cost.png"); !s) return s;
  if (Status s = WriteElevationTiff(map, dir / "elevation.tiff"); !s) return s;
  return WriteObstaclesJson(map, dir / "obstacles.json");
}

Expected<OccupancyGrid> ReadMapServerMap(const std::filesystem::path& yaml_path) {
  const std::string name = yaml_path.string();
  YAML::Node doc;
  try {
    doc = YAML::LoadFile(name);
  } catch (const YAML::BadFile&) {
    return Error{name + ": cannot open"};
  } catch (const YAML::Exception& e) {
    return Error{name + ":" + std::to_string(e.mark.line + 1) + ": invalid YAML: " + e.msg};
  }
  const auto field = [&](const char* key) -> Expected<YAML::Node> {
    const YAML::Node node = doc[key];
    if (!node) return Error{name + ": " + key + ": missing"};
    return node;
  };
  std::string image_name, mode = "trinary";
  double free_thresh = 0.0, occupied_thresh = 0.0;
  bool negate = false;
  std::vector<double> origin;
  OccupancyGrid out;
  const char* key = "image";
  try {
    Expected<YAML::Node> node = field(key);
    if (!node) return node.error();
    image_name = node->as<std::string>();
    if (image_name.empty()) return Error{name + ": image: empty"};
    key = "resolution";
    if (!(node = field(key))) return node.error();
    out.resolution_m = node->as<double>();
    key = "origin";
    if (!(node = field(key))) return node.error();
    origin = node->as<std::vector<double>>();
    if (origin.size() != 3) {
      return Error{name + ": origin: expected 3 values, got " + std::to_string(origin.size())};
    }
    key = "free_thresh";
    if (!(node = field(key))) return node.error();
    free_thresh = node->as<double>();
    key = "occupied_thresh";
    if (!(node = field(key))) return node.error();
    occupied_thresh = node->as<double>();
    key = "mode";
    if (doc[key]) mode = doc[key].as<std::string>();
    key = "negate";
    if (!(node = field(key))) return node.error();
    try {
      negate = node->as<int>() != 0;
    } catch (const YAML::Exception&) {
      negate = node->as<bool>();
    }
  } catch (const YAML::Exception& e) {
    return Error{name + ": " + key + ": " + e.msg};
  }
  if (mode != "trinary" && mode != "scale" && mode != "raw") {
    return Error{name + ": mode: expected trinary, scale or raw, got '" + mode + "'"};
  }
  out.origin = Eigen::Vector3d(origin[0], origin[1], origin[2]);

  std::filesystem::path image_path = image_name;
  if (image_path.is_relative()) image_path = yaml_path.parent_path() / image_path;
  cv::Mat image;
  try {
    image = cv::imread(image_path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) return Error{image_path.string() + ": cannot read the image"};
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    return Error{image_path.string() + ": expected an 8- or 16-bit image"};
  }
  const int channels = image.channels();
  if (channels != 1 && channels != 3 && channels != 4) {
    return Error{image_path.string() + ": expected 1, 3 or 4 channels"};
  }
  const double max_value = image.depth() == CV_8U ? 255.0 : 65535.0;
  out.width = image.cols;
  out.height = image.rows;
  out.data.assign(static_cast<std::size_t>(out.width) * out.height, -1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      double values[4] = {0, 0, 0, 0};
      for (int k = 0; k < channels; ++k) {
        values[k] = image.depth() == CV_8U ? image.ptr<std::uint8_t>(y)[x * channels + k]
                                           : image.ptr<std::uint16_t>(y)[x * channels + k];
      }
      // Grey, or the colour channels (alpha is the 4th in OpenCV's BGRA) averaged; map_io
      // adds opaqueness (alpha) to the average in trinary mode.
      double sum = channels == 1 ? values[0] : values[0] + values[1] + values[2];
      int count = channels == 1 ? 1 : 3;
      const bool has_alpha = channels == 4;
      if (mode == "trinary" && has_alpha) {
        sum += values[3];
        ++count;
      }
      const double shade = sum / count / max_value;
      const double occ = negate ? shade : 1.0 - shade;
      std::int8_t cell = -1;
      if (mode == "trinary") {
        cell = occupied_thresh < occ ? 100 : (occ < free_thresh ? 0 : -1);
      } else if (mode == "scale") {
        if (has_alpha && values[3] != max_value) {
          cell = -1;
        } else if (occupied_thresh < occ) {
          cell = 100;
        } else if (occ < free_thresh) {
          cell = 0;
        } else {
          cell = static_cast<std::int8_t>(
              std::rint((occ - free_thresh) / (occupied_thresh - free_thresh) * 100.0));
        }
      } else {
        const double percent = std::round(shade * 255.0);
        cell = percent >= 0.0 && percent <= 100.0 ? static_cast<std::int8_t>(percent) : -1;
      }
      out.data[static_cast<std::size_t>(out.height - y - 1) * out.width + x] = cell;
    }
  }
  return out;
}

Expected<OccupancyGrid> ExpectedOccupancy(const TerrainMap& map, PgmMode mode) {
  Expected<CellBox> box = ExportBounds(map);
  if (!box) return box.error();
  OccupancyGrid out;
  const Eigen::Vector2i size = box->size();
  out.width = size.x();
  out.height = size.y();
  out.resolution_m = map.config().cell_size_m;
  out.origin =
      Eigen::Vector3d(box->min.x() * out.resolution_m, box->min.y() * out.resolution_m, 0.0);
  out.data.resize(static_cast<std::size_t>(out.width) * out.height);
  for (int row = 0; row < out.height; ++row) {
    for (int col = 0; col < out.width; ++col) {
      const Cell* cell = map.grid().Find(box->min + CellIndex(col, row));
      const Cost cost = cell != nullptr ? cell->cost : kUnknownCost;
      std::int8_t value = OccupancyFromCost(cost);
      if (mode == PgmMode::kTrinary) {
        value = cost == kLethalCost ? 100 : (cost == kUnknownCost ? -1 : 0);
      }
      out.data[static_cast<std::size_t>(row) * out.width + col] = value;
    }
  }
  return out;
}

}  // namespace cairn::map
