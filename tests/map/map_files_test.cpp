// Map files read back by the libraries that own their formats: OctoMap reads the .bt and
// .ot files, OpenCV the images, nlohmann::json the obstacle list, and the cost grid's
// PGM + YAML give back, read as nav2's map_server reads them, the occupancy nav2 would
// publish for the cost grid.
#include "cairn/map/map_files.hpp"

#include <gtest/gtest.h>
#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "../io/temp_dir.hpp"
#include "map_scene.hpp"

namespace cairn::map {
namespace {

const TerrainMap& Map() {
  static const TerrainMap map = [] {
    Expected<TerrainMap> m = test::SmallMappedScene();
    if (!m) {
      ADD_FAILURE() << m.error().message;
      return TerrainMap::Create({}).value();
    }
    return std::move(m).value();
  }();
  return map;
}

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(MapFiles, WritesEveryFileAndNoTemporary) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteMapFiles(Map(), dir.path()).ok());
  EXPECT_EQ(dir.List(), (std::vector<std::string>{"cost.pgm", "cost.png", "cost.yaml",
                                                  "elevation.tiff", "elevation.yaml", "map.bt",
                                                  "map.ot", "obstacles.json", "obstacles.ot"}));
  // Writing again replaces the files, still without leftovers.
  ASSERT_TRUE(WriteMapFiles(Map(), dir.path(), PgmMode::kTrinary).ok());
  EXPECT_EQ(dir.List().size(), 9u);
}

TEST(MapFiles, BinaryTreeReadsBackAsAnOcTreeWithTheSameOccupancy) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteOctomapBinary(Map(), dir / "map.bt").ok());
  octomap::OcTree tree(0.5);
  ASSERT_TRUE(tree.readBinary((dir / "map.bt").string()));
  const TerrainOcTree& ours = Map().octree();
  EXPECT_DOUBLE_EQ(tree.getResolution(), ours.getResolution());
  int occupied = 0, leaves = 0;
  for (auto it = ours.begin_leafs(), end = ours.end_leafs(); it != end; ++it) {
    const octomap::OcTreeNode* node = tree.search(it.getKey(), it.getDepth());
    ASSERT_NE(node, nullptr);
    ASSERT_EQ(tree.isNodeOccupied(node), ours.isNodeOccupied(*it));
    occupied += ours.isNodeOccupied(*it);
    ++leaves;
  }
  EXPECT_GT(leaves, 1000);
  EXPECT_GT(occupied, 500);
}

TEST(MapFiles, FullTreeKeepsTheLogOddsAndTheObstacleTreeColoursObstacleVoxels) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteOctomapFull(Map(), dir / "map.ot").ok());
  ASSERT_TRUE(WriteObstacleOctomap(Map(), dir / "obstacles.ot").ok());
  std::unique_ptr<octomap::AbstractOcTree> full(
      octomap::AbstractOcTree::read((dir / "map.ot").string()));
  std::unique_ptr<octomap::AbstractOcTree> colour(
      octomap::AbstractOcTree::read((dir / "obstacles.ot").string()));
  ASSERT_NE(full, nullptr);
  ASSERT_NE(colour, nullptr);
  EXPECT_EQ(full->getTreeType(), "OcTree");
  EXPECT_EQ(colour->getTreeType(), "ColorOcTree");
  const auto* occupancy = dynamic_cast<const octomap::OcTree*>(full.get());
  const auto* coloured = dynamic_cast<const octomap::ColorOcTree*>(colour.get());
  ASSERT_NE(occupancy, nullptr);
  ASSERT_NE(coloured, nullptr);
  const TerrainOcTree& ours = Map().octree();
  EXPECT_EQ(occupancy->size(), ours.size());
  int obstacle_voxels = 0;
  for (auto it = ours.begin_leafs(), end = ours.end_leafs(); it != end; ++it) {
    const octomap::OcTreeNode* a = occupancy->search(it.getKey(), it.getDepth());
    const octomap::ColorOcTreeNode* b = coloured->search(it.getKey(), it.getDepth());
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    ASSERT_EQ(a->getLogOdds(), it->getLogOdds());
    ASSERT_EQ(b->getLogOdds(), it->getLogOdds());
    const bool red = b->getColor() == octomap::ColorOcTreeNode::Color(255, 0, 0);
    ASSERT_EQ(red, ours.IsObstacle(*it));
    obstacle_voxels += red;
  }
  EXPECT_GT(obstacle_voxels, 50);
}

TEST(MapFiles, CostGridReadsBackAsMapServerReadsIt) {
  const test::TempDir dir;
  for (const PgmMode mode : {PgmMode::kRaw, PgmMode::kTrinary}) {
    const std::filesystem::path yaml = dir / (mode == PgmMode::kRaw ? "raw.yaml" : "tri.yaml");
    ASSERT_TRUE(WriteCostGrid(Map(), yaml, mode).ok());
    const std::string text = ReadText(yaml);
    EXPECT_NE(text.find(mode == PgmMode::kRaw ? "mode: raw" : "mode: trinary"), std::string::npos);
    const Expected<OccupancyGrid> read = ReadMapServerMap(yaml);
    ASSERT_TRUE(read.ok()) << read.error().message;
    const Expected<OccupancyGrid> expected = ExpectedOccupancy(Map(), mode);
    ASSERT_TRUE(expected.ok());
    EXPECT_EQ(read->width, expected->width);
    EXPECT_EQ(read->height, expected->height);
    EXPECT_DOUBLE_EQ(read->resolution_m, 0.2);
    EXPECT_NEAR(read->origin.x(), expected->origin.x(), 1e-9);
    EXPECT_NEAR(read->origin.y(), expected->origin.y(), 1e-9);
    EXPECT_EQ(read->origin.z(), 0.0);
    ASSERT_EQ(read->data, expected->data);
    // By hand: the cell of the box's near face is occupied, the cell 0.6 m before it (cost
    // 186) is 1 + 97 * 185 / 251 = 72 in raw mode and free in trinary mode, and a cell
    // behind the box, never seen, is unknown.
    const auto at = [&](double x, double y) {
      const int col = static_cast<int>(std::floor((x - read->origin.x()) / 0.2));
      const int row = static_cast<int>(std::floor((y - read->origin.y()) / 0.2));
      return read->at(col, row);
    };
    ASSERT_EQ(Map().CostAt({2.9, 0.1}), 186);
    EXPECT_EQ(at(3.5, 0.1), 100);
    EXPECT_EQ(at(2.9, 0.1), mode == PgmMode::kRaw ? 72 : 0);
    int unknown = 0;
    for (int row = 0; row < read->height; ++row) {
      for (int col = 0; col < read->width; ++col) {
        const Eigen::Vector2d xy =
            read->origin.head<2>() + Eigen::Vector2d(col + 0.5, row + 0.5) * 0.2;
        if (Map().CostAt(xy) != kUnknownCost) continue;
        ASSERT_EQ(read->at(col, row), -1);
        ++unknown;
      }
    }
    EXPECT_GT(unknown, 10);
  }
}

// ExportGrid holds what the files hold: each cell's cost (its occupancy is what map_server
// reads back from cost.pgm, top row first) and elevation, with the YAML's origin.
TEST(MapFiles, ExportedGridEqualsTheCostAndElevationFiles) {
  const Expected<GridExport> grid = ExportGrid(Map());
  ASSERT_TRUE(grid.ok()) << grid.error().message;
  const Expected<OccupancyGrid> expected = ExpectedOccupancy(Map(), PgmMode::kRaw);
  ASSERT_TRUE(expected.ok());
  ASSERT_EQ(grid->width, expected->width);
  ASSERT_EQ(grid->height, expected->height);
  EXPECT_DOUBLE_EQ(grid->resolution_m, 0.2);
  EXPECT_NEAR(grid->origin_m.x(), expected->origin.x(), 1e-12);
  EXPECT_NEAR(grid->origin_m.y(), expected->origin.y(), 1e-12);
  const test::TempDir dir;
  ASSERT_TRUE(WriteElevationTiff(Map(), dir / "elevation.tiff").ok());
  const cv::Mat tiff = cv::imread((dir / "elevation.tiff").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(tiff.rows, grid->height);
  int lethal = 0;
  for (int row = 0; row < grid->height; ++row) {
    for (int col = 0; col < grid->width; ++col) {
      const std::size_t i = static_cast<std::size_t>(row) * grid->width + col;
      // Row 0 of the export is the top; row 0 of an OccupancyGrid is the bottom.
      ASSERT_EQ(OccupancyFromCost(grid->cost[i]), expected->at(col, grid->height - 1 - row));
      const float e = tiff.at<float>(row, col);
      ASSERT_TRUE(std::isnan(e) ? std::isnan(grid->elevation_m[i]) : e == grid->elevation_m[i]);
      lethal += grid->cost[i] == kLethalCost;
    }
  }
  EXPECT_GT(lethal, 0);
}

// The reader follows map_server's rules for every mode, on pixels written by hand.
TEST(MapFiles, MapServerReaderFollowsMapIo) {
  const test::TempDir dir;
  const cv::Mat pixels = (cv::Mat_<std::uint8_t>(2, 4) << 0, 100, 101, 255,  // top row
                          254, 205, 128, 50);
  ASSERT_TRUE(cv::imwrite((dir / "hand.pgm").string(), pixels));
  const auto read = [&](const std::string& mode_lines) {
    dir.Write("hand.yaml",
              "image: hand.pgm\nresolution: 0.5\norigin: [1.0, -2.0, 0.3]\n"
              "occupied_thresh: 0.65\nfree_thresh: 0.196\n" +
                  mode_lines);
    return ReadMapServerMap(dir / "hand.yaml");
  };
  // Bottom row first: (254, 205, 128, 50), then (0, 100, 101, 255).
  Expected<OccupancyGrid> raw = read("mode: raw\nnegate: 1\n");  // raw ignores negate
  ASSERT_TRUE(raw.ok()) << raw.error().message;
  EXPECT_EQ(raw->data, (std::vector<std::int8_t>{-1, -1, -1, 50, 0, 100, -1, -1}));
  EXPECT_EQ(raw->origin, Eigen::Vector3d(1.0, -2.0, 0.3));
  // Trinary: occ = 1 - p / 255; > 0.65 occupied, < 0.196 free, else unknown.
  Expected<OccupancyGrid> trinary = read("negate: 0\n");  // trinary when mode is absent
  ASSERT_TRUE(trinary.ok());
  EXPECT_EQ(trinary->data, (std::vector<std::int8_t>{0, -1, -1, 100, 100, -1, -1, 0}));
  Expected<OccupancyGrid> negated = read("mode: trinary\nnegate: true\n");
  ASSERT_TRUE(negated.ok());
  // occ = p / 255: 50 / 255 = 0.19608 is not below free_thresh 0.196.
  EXPECT_EQ(negated->data, (std::vector<std::int8_t>{100, 100, -1, -1, 0, -1, -1, 100}));
  // Scale: in between, rint((occ - free) / (occupied - free) * 100).
  Expected<OccupancyGrid> scale = read("mode: scale\nnegate: 0\n");
  ASSERT_TRUE(scale.ok());
  const auto scaled = [](int p) {
    return static_cast<std::int8_t>(std::rint((1.0 - p / 255.0 - 0.196) / (0.65 - 0.196) * 100.0));
  };
  EXPECT_EQ(scale->data, (std::vector<std::int8_t>{0, scaled(205), scaled(128), 100, 100,
                                                   scaled(100), scaled(101), 0}));
  // What map_server rejects, the reader rejects, naming the field.
  Expected<OccupancyGrid> bad = read("mode: fancy\nnegate: 0\n");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("mode"), std::string::npos);
  dir.Write("short.yaml",
            "image: hand.pgm\norigin: [0, 0, 0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n");
  Expected<OccupancyGrid> missing = ReadMapServerMap(dir / "short.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("resolution"), std::string::npos);
  EXPECT_FALSE(ReadMapServerMap(dir / "none.yaml").ok());
}

TEST(MapFiles, ElevationTiffHoldsTheCellMeans) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteElevationTiff(Map(), dir / "elevation.tiff").ok());
  const cv::Mat image = cv::imread((dir / "elevation.tiff").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(image.type(), CV_32FC1);
  const Expected<CellBox> box = ExportBounds(Map());
  ASSERT_TRUE(box.ok());
  ASSERT_EQ(image.cols, box->size().x());
  ASSERT_EQ(image.rows, box->size().y());
  int known = 0;
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const Cell& cell = Map().grid().At({box->min.x() + c, box->max.y() - r});
      const float value = image.at<float>(r, c);
      if (cell.has_elevation()) {
        ASSERT_EQ(value, cell.elevation_mean_m);
        ++known;
      } else {
        ASSERT_TRUE(std::isnan(value));
      }
    }
  }
  EXPECT_GT(known, 500);
  const std::string yaml = ReadText(dir / "elevation.yaml");
  EXPECT_NE(yaml.find("image: elevation.tiff"), std::string::npos);
  EXPECT_NE(yaml.find("resolution: 0.2"), std::string::npos);
}

TEST(MapFiles, ColourImageShowsLethalAndUnknownCells) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteCostColorPng(Map(), dir / "cost.png").ok());
  const cv::Mat image = cv::imread((dir / "cost.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(image.type(), CV_8UC3);
  const Expected<CellBox> box = ExportBounds(Map());
  ASSERT_TRUE(box.ok());
  int lethal = 0, unknown = 0;
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const Cost cost = Map().grid().At({box->min.x() + c, box->max.y() - r}).cost;
      const cv::Vec3b bgr = image.at<cv::Vec3b>(r, c);
      if (cost == kLethalCost) {
        ASSERT_EQ(bgr, cv::Vec3b(0, 0, 220));
        ++lethal;
      }
      if (cost == kUnknownCost) {
        ASSERT_EQ(bgr, cv::Vec3b(128, 128, 128));
        ++unknown;
      }
      if (cost == kFreeCost) {
        ASSERT_EQ(bgr, cv::Vec3b(255, 255, 255));
      }
    }
  }
  EXPECT_GT(lethal, 30);
  EXPECT_GT(unknown, 10);
}

TEST(MapFiles, ObstaclesJsonListsTheLiveObstacles) {
  const test::TempDir dir;
  ASSERT_TRUE(WriteObstaclesJson(Map(), dir / "obstacles.json").ok());
  const nlohmann::json doc = nlohmann::json::parse(ReadText(dir / "obstacles.json"));
  EXPECT_EQ(doc.at("frame"), "world");
  EXPECT_EQ(doc.at("frames_integrated"), 2);
  const auto& list = doc.at("obstacles");
  ASSERT_EQ(list.size(), Map().obstacles().size());
  ASSERT_EQ(list.size(), 2u);  // the box and the pole
  for (std::size_t k = 0; k < list.size(); ++k) {
    const Obstacle& o = Map().obstacles()[k];
    EXPECT_EQ(list[k].at("id"), o.id);
    EXPECT_EQ(list[k].at("cells").size(), o.cells.size());
    EXPECT_EQ(list[k].at("point_count"), o.point_count);
    EXPECT_DOUBLE_EQ(list[k].at("height").get<double>(), o.height_m);
    EXPECT_EQ(list[k].at("frames").get<std::vector<std::int64_t>>(), o.frames);
    EXPECT_DOUBLE_EQ(list[k].at("bbox_max")[2].get<double>(), o.bbox_max.z());
  }
}

TEST(MapFiles, ErrorsNameTheFile) {
  const test::TempDir dir;
  const std::filesystem::path missing_dir = dir / "no" / "such";
  const Status s = WriteOctomapBinary(Map(), missing_dir / "map.bt");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find((missing_dir / "map.bt").string()), std::string::npos) << s.message();
  const Status pgm = WriteCostGrid(Map(), dir / "cost.pgm");
  ASSERT_FALSE(pgm.ok());
  EXPECT_NE(pgm.message().find(".yaml"), std::string::npos) << pgm.message();
  const Status all = WriteMapFiles(Map(), missing_dir);
  EXPECT_FALSE(all.ok());
  EXPECT_TRUE(dir.List().empty()) << "nothing half-written";
  // An unbounded map that has seen nothing has no grid to write.
  const TerrainMap empty = TerrainMap::Create({}).value();
  const Status nothing = WriteCostGrid(empty, dir / "cost.yaml");
  ASSERT_FALSE(nothing.ok());
  EXPECT_NE(nothing.message().find("observed nothing"), std::string::npos) << nothing.message();
}

}  // namespace
}  // namespace cairn::map
