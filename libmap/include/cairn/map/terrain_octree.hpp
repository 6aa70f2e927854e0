// TerrainOcTree: an OctoMap occupancy octree whose voxels also know whether obstacle points
// put them there.
//
// Each node carries two log-odds, updated together by the same sensor model:
//  - occupancy (OctoMap's own): + hit for any return ending in the voxel, + miss for a ray
//    passing through it;
//  - obstacle: + hit for a return of an obstacle point (a kept segment, above its foot),
//    + miss for a ray passing through it and for a return of a ground point.
// A voxel is an obstacle voxel while it is occupied and its obstacle log-odds is above 0.
// Both are clamped with the tree's clamping thresholds, so that an object that moves away,
// or a false obstacle seen once, is cleared by the rays of later frames. Inner nodes hold
// the maximum of their children for both; nodes collapse only when both values agree.
//
// World frame (z up), metres. Files are written as plain octomap::OcTree / ColorOcTree
// (see map_files.hpp), which OctoMap's tools read; this type is not registered with
// OctoMap's .ot factory.
#pragma once

#include <octomap/OcTreeNode.h>
#include <octomap/OccupancyOcTreeBase.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <vector>

namespace cairn::map {

class TerrainOcTreeNode : public octomap::OcTreeNode {
 public:
  TerrainOcTreeNode() = default;
  // OctoMap's node copy constructor copies children with global new, as its own base type:
  // no copies (a node's delete hands it back to the chunks of terrain_octree.cpp).
  TerrainOcTreeNode(const TerrainOcTreeNode& rhs) = delete;
  TerrainOcTreeNode& operator=(const TerrainOcTreeNode& rhs) = delete;

  /// Nodes come from chunks of their own (terrain_octree.cpp), handed out in the order of
  /// their addresses, freed ones too: a frame makes and prunes hundreds of thousands, which
  /// malloc serves at about the cost of the ray walk. Plain new and delete under
  /// AddressSanitizer, which then watches every node.
  static void* operator new(std::size_t size);
  static void operator delete(void* node, std::size_t size) noexcept;

  float obstacle_log_odds() const { return obstacle_; }
  void set_obstacle_log_odds(float l) { obstacle_ = l; }

  // OctoMap's node interface (names as OctoMap calls them).
  bool operator==(const TerrainOcTreeNode& rhs) const {
    return rhs.value == value && rhs.obstacle_ == obstacle_;
  }
  void copyData(const TerrainOcTreeNode& from) {
    OcTreeNode::copyData(from);
    obstacle_ = from.obstacle_;
  }
  /// Inner nodes: the maximum of the children, for both values.
  void updateOccupancyChildren();
  std::istream& readData(std::istream& s);
  std::ostream& writeData(std::ostream& s) const;

 private:
  friend class TerrainOcTree;
  // Frees the child pointer array once every child is gone (OctoMap's deleteNodeChild
  // leaves it, and a node with an array must not be deleted).
  void ReleaseChildArray() {
    delete[] children;
    children = nullptr;
  }
  // OctoMap's createNodeChild and expandNode without the tree's node count, which walks on
  // several threads would share: the caller counts the nodes made.
  TerrainOcTreeNode* MakeChild(unsigned pos) {
    if (children == nullptr) {
      children = new octomap::AbstractOcTreeNode*[8];
      for (unsigned i = 0; i < 8; ++i) children[i] = nullptr;
    }
    auto* child = new TerrainOcTreeNode();
    children[pos] = child;
    return child;
  }
  void Expand() {
    for (unsigned i = 0; i < 8; ++i) MakeChild(i)->copyData(*this);
  }

  float obstacle_ = 0.0f;
};

class TerrainOcTree : public octomap::OccupancyOcTreeBase<TerrainOcTreeNode> {
 public:
  explicit TerrainOcTree(double resolution_m);
  // OctoMap's node copy constructor copies children as its own base type, which would slice
  // ours: no copies (TerrainMap owns its tree; map_files.hpp converts it).
  TerrainOcTree(const TerrainOcTree&) = delete;
  TerrainOcTree& operator=(const TerrainOcTree&) = delete;

  TerrainOcTree* create() const override { return new TerrainOcTree(resolution); }
  std::string getTreeType() const override { return "TerrainOcTree"; }

  /// The leaf at full depth for `key`, created, or expanded from a pruned ancestor. Inner
  /// nodes are not updated (call updateInnerOccupancy() after a batch, as with lazy_eval).
  TerrainOcTreeNode* TouchLeaf(const octomap::OcTreeKey& key);

  /// One update of both log-odds of a leaf, clamped with the tree's thresholds:
  /// `occupied` adds the hit (else the miss) log-odds to occupancy; `obstacle` adds the hit
  /// (else the miss) log-odds to the obstacle value.
  void Update(TerrainOcTreeNode* leaf, bool occupied, bool obstacle) const {
    const float occupancy = leaf->getLogOdds() + (occupied ? prob_hit_log : prob_miss_log);
    leaf->setLogOdds(std::clamp(occupancy, clamping_thres_min, clamping_thres_max));
    const float evidence = leaf->obstacle_log_odds() + (obstacle ? prob_hit_log : prob_miss_log);
    leaf->set_obstacle_log_odds(std::clamp(evidence, clamping_thres_min, clamping_thres_max));
  }

  /// One free update (a ray passed through) of the voxel `key`, walking the tree once: a
  /// voxel inside a pruned node saturated free in both values is left alone (the update
  /// would change nothing), without expanding it. Returns whether the voxel was an obstacle
  /// voxel before the update, and whether it changed.
  struct FreeUpdate {
    bool changed = false;
    bool was_obstacle = false;
  };
  FreeUpdate UpdateFree(const octomap::OcTreeKey& key);

  /// Free updates of the voxels of one brick: the node three levels above the leaves (8 x 8
  /// x 8 voxels) whose first voxel is `base` (its keys' low three bits zero). Bit b of
  /// `voxels` (bit b % 64 of word b / 64) is the voxel whose local coordinates, interleaved
  /// x, y, z from the lowest bit, make b: the same Morton code that picks the child at each
  /// of the three levels. The tree walks to the brick once, then down to each voxel, the
  /// steps it shares with the voxel before taken once; the tree and the answers are those
  /// of UpdateFree on each voxel in ascending b. Sets bit b
  /// of `was_obstacle` for the voxels that were obstacle voxels before; returns how many
  /// voxels changed.
  int UpdateFreeBrick(const octomap::OcTreeKey& base, const std::uint64_t (&voxels)[8],
                      std::uint64_t (&was_obstacle)[8]);

  /// A frame's updates of one brick (whose first voxel is `base`), its voxels' bits as
  /// UpdateFreeBrick's: `free` a free update each (a ray passed through), `hit` an occupied
  /// one (a return ended there: TouchLeaf, then Update with occupied true), with an
  /// obstacle hit where `obstacle` has the voxel too. No voxel is in both `free` and `hit`.
  struct BrickUpdate {
    octomap::OcTreeKey base;
    std::uint64_t free[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    std::uint64_t hit[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    std::uint64_t obstacle[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    std::uint64_t was_obstacle[8] = {0, 0, 0, 0, 0, 0, 0, 0};  ///< out: of the free voxels
    int changed = 0;  ///< out: free voxels that changed (UpdateFreeBrick's count)
  };
  /// The updates of many bricks, each voxel's as UpdateFree or TouchLeaf and Update make it,
  /// walking the tree to each brick once and down to each voxel in the brick's Morton order.
  /// Each leaf takes one update, and a hit expands the pruned nodes above it that a free update
  /// stops at, whichever comes first: the tree and the answers are those of all the free
  /// updates first (UpdateFreeBrick on each brick in turn), then all the hits. On up to
  /// `threads` threads (0: every core), the bricks in the Morton order of their bases
  /// (KeyBricks::ForEachBrickOfEitherInMortonOrder's): they are split by their subtree a few levels
  /// above them (Morton order keeps each subtree's bricks together, which the threads rely
  /// on: a subtree met twice would be updated by two threads at once); the path to each
  /// subtree is walked first, in order, on one thread, then the subtrees, which share no
  /// node, each on one thread. UpdateFree, UpdateFreeBrick and TouchLeaf are the references
  /// the tests hold this to.
  void UpdateBricks(std::vector<BrickUpdate>& bricks, int threads);

  /// Whether a node is saturated free in both values (a free update changes nothing).
  bool IsSaturatedFree(const TerrainOcTreeNode& node) const {
    return node.getLogOdds() <= clamping_thres_min &&
           node.obstacle_log_odds() <= clamping_thres_min;
  }
  bool IsObstacle(const TerrainOcTreeNode& node) const {
    return isNodeOccupied(node) && node.obstacle_log_odds() > 0.0f;
  }

  /// Collapses every node whose eight children are leaves saturated free into one leaf
  /// saturated free, bottom up (OctoMap's prune() does that too, and also collapses equal
  /// leaves that are not saturated, which the next frame's rays then expand again). Leaves
  /// keep their values; inner nodes are not updated. Returns the nodes deleted.
  std::size_t PruneSaturatedFree();

  /// Deletes every node whose box lies entirely outside [min, max] in x and y (world) and
  /// returns how many nodes went; voxels that straddle the border stay, and inner nodes keep
  /// the maximum of the children left. A pruned node that straddles the border is expanded
  /// first: the voxels left do not depend on when the tree was pruned.
  std::size_t DeleteOutsideXY(const Eigen::Vector2d& min, const Eigen::Vector2d& max);

 private:
  TerrainOcTreeNode* Root(bool& created);
  // (Defined in terrain_octree.cpp, the only user, inline in its walks.)
  inline TerrainOcTreeNode* Step(TerrainOcTreeNode* node, unsigned pos, bool& created,
                                 bool free_update, std::size_t& made);
  // The walk from the root down to `depth` along `key`: a free update's (null inside a
  // pruned node saturated free), or TouchLeaf's (`free_update` false).
  TerrainOcTreeNode* WalkDown(const octomap::OcTreeKey& key, unsigned depth, bool free_update,
                              bool& created);
  // UpdateBricks' work on one brick below `node`, at `depth` on the path to it (reached with
  // `created`); the nodes made are counted into `made`. Returns the free voxels changed.
  int UpdateBrickBelow(TerrainOcTreeNode* node, unsigned depth, bool created, BrickUpdate& brick,
                       std::size_t& made);
  void CountMade(std::size_t made) {
    tree_size += made;
    if (made > 0) size_changed = true;
  }
  inline FreeUpdate FreeLeaf(TerrainOcTreeNode* leaf) const;
  // PruneSaturatedFree below `node`; true when `node` is (now) a leaf saturated free.
  bool PruneSaturatedFreeRecurs(TerrainOcTreeNode* node, std::size_t& count);
  // Deletes every descendant of `node` (not the node itself); counts them.
  void DeleteDescendants(TerrainOcTreeNode* node, std::size_t& count);
  // Returns true when `node` has no child left and must go too.
  bool DeleteOutsideRecurs(TerrainOcTreeNode* node, const octomap::OcTreeKey& key, unsigned depth,
                           const Eigen::Vector2d& min, const Eigen::Vector2d& max,
                           std::size_t& count);
};

}  // namespace cairn::map
