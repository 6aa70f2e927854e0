// Map files: what a TerrainMap writes for planners, viewers and OctoMap's tools, and a
// reader of map_server maps for checking them.
//
// Every writer builds the whole file in memory and writes it atomically (a temporary in the
// same directory, renamed over the destination; util::WriteFileAtomic). Errors name the
// file and the reason; nothing is printed.
//
// Images of the grid (cost PGM, colour PNG, elevation TIFF) share one extent and one
// orientation, map_server's: column c, row r shows cell (min.x + c, max.y - r), so north
// (+y) is up and the YAML's origin is the world xy of the lower-left cell's outer corner.
// The extent is the rolling window, or in unbounded mode the box of the cells observed.
#pragma once

#include <octomap/ColorOcTree.h>
#include <octomap/OcTree.h>

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cairn/map/terrain_map.hpp"
#include "cairn/od/expected.hpp"

namespace cairn::map {

/// How the cost grid's PGM encodes cells; its YAML names the mode, so map_server reads it
/// back as written (nav2_map_server's map_io: raw takes round(255 * shade) when it lies in
/// 0..100, else unknown, and ignores negate; trinary thresholds occ = 1 - shade).
enum class PgmMode {
  /// `mode: raw`: every pixel is the cell's cost as nav2 publishes a costmap as an
  /// OccupancyGrid (OccupancyFromCost: 0..100), 255 where unknown. map_server gives back
  /// exactly OccupancyFromCost(cost) per cell, inflation included.
  kRaw,
  /// `mode: trinary`, the classic static map: lethal cells 0 (black), unknown 205, every
  /// other cell 254, with occupied_thresh 0.65 and free_thresh 0.196: map_server reads 100,
  /// -1 and 0. Obstacles only, for a nav2 static layer that inflates by itself.
  kTrinary,
};

/// The grid extent the image files cover (see above). Fails on an unbounded map that has
/// observed nothing.
Expected<CellBox> ExportBounds(const TerrainMap& map);

/// The octree as a plain octomap::OcTree: the same structure, resolution, sensor model and
/// occupancy log-odds (the obstacle values are dropped).
std::unique_ptr<octomap::OcTree> ToOcTree(const TerrainOcTree& tree);
/// The octree as an octomap::ColorOcTree: occupancy log-odds, obstacle voxels red
/// (255, 0, 0), other voxels coloured by height from blue-green (low) to yellow (high).
std::unique_ptr<octomap::ColorOcTree> ToColorOcTree(const TerrainOcTree& tree);

/// The grid of the image files, in memory: ExportBounds, map_server's orientation (row 0
/// the top, highest y), row-major.
struct GridExport {
  CellBox box;
  int width = 0;   ///< columns, along world x
  int height = 0;  ///< rows, along world -y
  double resolution_m = 0.0;
  /// World xy of the lower-left cell's outer corner, as the YAMLs' origin [m].
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
  std::vector<Cost> cost;          ///< nav2 costmap values: 0 free .. 254 lethal, 255 unknown
  std::vector<float> elevation_m;  ///< ground elevation, what elevation.tiff holds, NaN unknown
};
/// Fails like ExportBounds.
Expected<GridExport> ExportGrid(const TerrainMap& map);

/// OctoMap binary (.bt): the maximum-likelihood occupancy of ToOcTree (OcTree::writeBinary).
Status WriteOctomapBinary(const TerrainMap& map, const std::filesystem::path& path);
/// OctoMap full file (.ot) of ToOcTree: occupancy probabilities (OcTree::write).
Status WriteOctomapFull(const TerrainMap& map, const std::filesystem::path& path);
/// OctoMap full file (.ot) of ToColorOcTree: obstacle voxels red, for octovis.
Status WriteObstacleOctomap(const TerrainMap& map, const std::filesystem::path& path);

/// The cost grid as map_server's pair: `yaml_path` (image, mode, resolution, origin, negate,
/// occupied_thresh, free_thresh) and the PGM beside it with the same stem.
Status WriteCostGrid(const TerrainMap& map, const std::filesystem::path& yaml_path,
                     PgmMode mode = PgmMode::kRaw);
/// The cost grid in colour (PNG, 8-bit BGR): unknown grey, free white through yellow to
/// orange at 252, inscribed purple, lethal red.
Status WriteCostColorPng(const TerrainMap& map, const std::filesystem::path& path);
/// The ground elevation (cell mean) as a 32-bit float single-channel TIFF [m, world z],
/// NaN where unknown, with `<stem>.yaml` beside it (image, resolution, origin, units, nodata).
Status WriteElevationTiff(const TerrainMap& map, const std::filesystem::path& path);
/// The live obstacles as JSON (features, footprint cells, frames), with the map's frame,
/// units and cell size.
Status WriteObstaclesJson(const TerrainMap& map, const std::filesystem::path& path);

/// Every file above into `dir` (which must exist): map.bt, map.ot, obstacles.ot,
/// cost.yaml + cost.pgm, cost.png, elevation.tiff + elevation.yaml, obstacles.json.
Status WriteMapFiles(const TerrainMap& map, const std::filesystem::path& dir,
                     PgmMode mode = PgmMode::kRaw);

/// An occupancy grid as map_server serves it (nav_msgs/OccupancyGrid): -1 unknown, 0..100.
struct OccupancyGrid {
  int width = 0;
  int height = 0;
  double resolution_m = 0.0;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< x, y [m], yaw [rad]
  /// data[row * width + col]; row 0 is the bottom row (lowest y), as in the message.
  std::vector<std::int8_t> data;

  std::int8_t at(int col, int row) const {
    return data[static_cast<std::size_t>(row) * width + col];
  }
};

/// Reads a map_server YAML and its image as nav2_map_server's loadMapYaml + loadMapFromFile
/// do: image relative to the YAML's directory, mode trinary when absent, negate as an int or
/// a bool, shade = mean of the colour channels (with alpha in trinary mode), 8- or 16-bit
/// images. Fails, naming the file and the field, where map_server would.
Expected<OccupancyGrid> ReadMapServerMap(const std::filesystem::path& yaml_path);

/// The grid map_server should give back for `map`'s cost grid written in `mode`: per cell of
/// ExportBounds, OccupancyFromCost(cost) (kRaw) or 100 / -1 / 0 for lethal / unknown / other
/// (kTrinary).
Expected<OccupancyGrid> ExpectedOccupancy(const TerrainMap& map, PgmMode mode);

}  // namespace cairn::map
