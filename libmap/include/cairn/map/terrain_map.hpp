// TerrainMap: obstacles of successive range frames fused into an OctoMap and a 2.5-D cost
// grid, for planners. One object owns the fused state; Integrate() adds a frame.
//
// Frames: each range image holds points in its sensor frame; T_world_sensor maps them into
// the world (z up, fixed at the start of a sequence; from odometry or ground truth). Metres,
// radians, seconds.
//
// Per frame, Integrate():
//  1. classifies every return within max_range_m: an obstacle point belongs to a segment the
//     rules kept and stands above the ground around it (MapConfig::obstacle_min_height_m,
//     ground_radius_m, ground_max_slope_rad); every other return is ground (this drops the
//     foot band of terrain that the cone detector pairs with an obstacle's base);
//  2. updates the octree (TerrainOcTree): endpoints occupied (and obstacle or not), free
//     space along each ray, OctoMap's discretised update (one ray per endpoint voxel);
//  3. updates the grid: elevation from ground points, obstacle evidence per cell (hit:
//     obstacle points in it; miss: ground points in it, or a ray through an obstacle voxel
//     above it), then slope, roughness and cost around what changed;
//  4. associates kept segments with persistent obstacles and retires those with no lethal
//     cell left.
// A rolling window (MapConfig::window_size_m > 0) is centred on the sensor before the frame
// is fused; what lies outside it is dropped from the grid, the octree and the obstacles.
//
// Not thread-safe; queries are const and cheap.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "cairn/map/cost.hpp"
#include "cairn/map/map_config.hpp"
#include "cairn/map/obstacle.hpp"
#include "cairn/map/terrain_grid.hpp"
#include "cairn/map/terrain_octree.hpp"
#include "cairn/od/detector.hpp"
#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/rules.hpp"

namespace cairn::map {

/// What one Integrate() call did.
struct FrameSummary {
  std::int64_t frame_id = 0;
  double stamp_s = 0.0;
  int valid_points = 0;     ///< valid returns in the image
  int points_in_range = 0;  ///< of which within max_range_m (and the window)
  int obstacle_points = 0;  ///< classified obstacle (kept segment, above its foot)
  int ground_points = 0;
  int kept_segments = 0;            ///< kept segments with obstacle points
  int obstacles_created = 0;        ///< new persistent obstacles
  int obstacles_updated = 0;        ///< existing ones a segment joined
  int obstacles_merged = 0;         ///< existing ones merged into another by a segment
  int obstacles_retired = 0;        ///< no lethal cell left
  std::size_t voxels_occupied = 0;  ///< endpoint voxels updated
  std::size_t voxels_free = 0;      ///< free voxels updated (not saturated)
  int cells_hit = 0;
  int cells_missed = 0;
  int lethal_cells = 0;  ///< in the whole grid after the frame
  bool window_moved = false;
  /// Time spent per stage [s]: point classification, octree, grid and cost, obstacles.
  double classify_s = 0.0;
  double octree_s = 0.0;
  double grid_s = 0.0;
  double obstacles_s = 0.0;
};

/// Costs met along a straight line, for planners.
struct LineCost {
  Cost max_cost = kUnknownCost;  ///< the largest cost on the line (255 if it leaves the grid)
  std::vector<CellIndex> cells;  ///< every cell the line passes through, in order
  std::vector<Cost> costs;       ///< their costs (255 outside the grid)
};

/// A square of cells around a point. cost(i, j) and elevation_m(i, j) describe cell
/// min_index + (i, j): i along world x, j along world y. Outside the grid: 255 and NaN.
struct GridPatch {
  CellIndex min_index = CellIndex::Zero();
  double cell_size_m = 0.0;
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();  ///< world xy of cell (0, 0)'s corner
  Eigen::Matrix<Cost, Eigen::Dynamic, Eigen::Dynamic> cost;
  Eigen::MatrixXf elevation_m;  ///< ground elevation (mean), NaN where unknown
};

/// A box of cells, both corners included.
struct CellBox {
  CellIndex min = CellIndex::Zero();
  CellIndex max = CellIndex::Zero();
  Eigen::Vector2i size() const { return max - min + Eigen::Vector2i::Ones(); }
};

/// Memory held by the map.
struct MapMemory {
  std::size_t grid_bytes = 0;
  std::size_t octree_bytes = 0;  ///< OctoMap's memoryUsage()
  std::size_t octree_leaves = 0;
  std::size_t obstacles = 0;
};

class TerrainMap {
 public:
  /// Fails when the config does not validate.
  static Expected<TerrainMap> Create(const MapConfig& config);

  TerrainMap(TerrainMap&&) noexcept;
  TerrainMap& operator=(TerrainMap&&) noexcept;
  ~TerrainMap();

  /// Fuses one frame (see above). `detection` and `classification` must come from `image`:
  /// the same size, one verdict per segment, labels in range; fails (naming the mismatch)
  /// otherwise, or on a non-finite pose or stamp, and then changes nothing.
  Expected<FrameSummary> Integrate(const od::RangeImage& image, const od::Detection& detection,
                                   const od::Classification& classification,
                                   const Eigen::Isometry3d& T_world_sensor, double stamp_s,
                                   std::int64_t frame_id);

  // --- queries (world xy [m]) ---
  /// Cost of the cell holding `xy`; 255 outside the grid.
  Cost CostAt(const Eigen::Vector2d& xy) const;
  /// Every cell the segment a-b passes through (grid traversal), with its cost.
  LineCost CostAlongLine(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  /// The cells within `half_size_m` of `centre` in x and y (a square of 2 n + 1 cells a side
  /// centred on centre's cell, n = round(half_size_m / cell_size)).
  GridPatch PatchAround(const Eigen::Vector2d& centre, double half_size_m) const;
  /// The cell holding `xy`, or nullptr outside the grid.
  const Cell* CellAt(const Eigen::Vector2d& xy) const;
  /// Live persistent obstacles, by increasing id.
  const std::vector<Obstacle>& obstacles() const { return obstacles_; }
  /// The bounding box of the cells observed so far, within the grid's extent; nothing
  /// before the first observation.
  std::optional<CellBox> ObservedBounds() const;

  const TerrainGrid& grid() const { return grid_; }
  /// The octree, its inner nodes up to date and pruned (Integrate() refreshes them only
  /// every few frames; this does it when needed, so the first call after a frame may walk
  /// the whole tree).
  const TerrainOcTree& octree() const;
  const MapConfig& config() const { return config_; }
  std::int64_t frames_integrated() const { return frames_; }
  std::int64_t obstacles_retired() const { return retired_total_; }
  MapMemory Memory() const;

 private:
  // Checkpoints (checkpoint.hpp) save every member below except the per-frame scratch and
  // rebuild a map from them, so that a resumed map continues exactly like an uninterrupted
  // one.
  friend struct detail::CheckpointAccess;

  explicit TerrainMap(const MapConfig& config);
  struct Scratch;
  struct FramePoint;
  struct FrameSegment;

  void PrepareScratch();
  // Integrate()'s stages, in order (those given the summary add their counts to it).
  bool MoveWindow(const Eigen::Vector3d& origin);
  Status PlaceReturns(const od::RangeImage& image, const Eigen::Isometry3d& T_world_sensor,
                      FrameSummary& summary);
  std::vector<FrameSegment> ClassifyReturns(const od::Detection& detection,
                                            const od::Classification& classification,
                                            std::int64_t stamp, FrameSummary& summary);
  void UpdateOctree(const Eigen::Vector3d& origin, std::int64_t stamp, FrameSummary& summary);
  void UpdateGridEvidence(FrameSummary& summary);
  void UpdatePersistentObstacles(std::vector<FrameSegment>& segments, double stamp_s,
                                 std::int64_t frame_id, FrameSummary& summary);
  // Parts of those stages.
  void FindLowestReturns(std::int64_t stamp, FrameSummary& summary);
  std::pair<float, float> HeightAboveGround(const Eigen::Vector3d& p, const CellIndex& c,
                                            float rise, float reach2);
  void CollectRayEnds();
  void UpdateCosts(const CellIndex& lo, const CellIndex& hi);
  void UpdateTerrain(const CellIndex& lo, const CellIndex& hi);
  void FuseObstacles(std::vector<FrameSegment>& segments, double stamp_s, std::int64_t frame_id,
                     FrameSummary& summary);
  void RetireObstacles(FrameSummary& summary);
  void PruneOctreeToWindow();
  void FlushOctree() const;

  MapConfig config_;
  TerrainGrid grid_;
  std::unique_ptr<TerrainOcTree> octree_;
  mutable bool octree_stale_ = false;  // inner nodes not updated since the last leaf change
  std::unique_ptr<Scratch> scratch_;
  std::vector<Obstacle> obstacles_;
  int next_obstacle_id_ = 1;
  std::int64_t frames_ = 0;
  std::int64_t retired_total_ = 0;
  CellIndex observed_min_ = CellIndex::Zero();
  CellIndex observed_max_ = CellIndex::Zero();
  bool has_observed_ = false;
  CellIndex pruned_at_ = CellIndex::Zero();  // window position of the last octree pruning
  // Log-odds of the cell model.
  float cell_hit_ = 0.0f, cell_miss_ = 0.0f, cell_min_ = 0.0f, cell_max_ = 0.0f;
  float lethal_log_odds_ = 0.0f;
};

}  // namespace cairn::map
