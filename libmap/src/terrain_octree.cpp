#include "cairn/map/terrain_octree.hpp"

#include <algorithm>
#include <iterator>
#include <limits>

namespace cairn::map {

void TerrainOcTreeNode::updateOccupancyChildren() {
  if (children == nullptr) return;
  float occupancy = std::numeric_limits<float>::lowest();
  float obstacle = std::numeric_limits<float>::lowest();
  bool any = false;
  for (unsigned i = 0; i < 8; ++i) {
    if (children[i] == nullptr) continue;
    const auto* child = static_cast<const TerrainOcTreeNode*>(children[i]);
    occupancy = std::max(occupancy, child->getLogOdds());
    obstacle = std::max(obstacle, child->obstacle_);
    any = true;
  }
  if (!any) return;
  setLogOdds(occupancy);
  obstacle_ = obstacle;
}

std::istream& TerrainOcTreeNode::readData(std::istream& s) {
  s.read(reinterpret_cast<char*>(&value), sizeof(value));
  s.read(reinterpret_cast<char*>(&obstacle_), sizeof(obstacle_));
  return s;
}

std::ostream& TerrainOcTreeNode::writeData(std::ostream& s) const {
  s.write(reinterpret_cast<const char*>(&value), sizeof(value));
  s.write(reinterpret_cast<const char*>(&obstacle_), sizeof(obstacle_));
  return s;
}

TerrainOcTree::TerrainOcTree(double resolution_m)
    : octomap::OccupancyOcTreeBase<TerrainOcTreeNode>(resolution_m) {}

// The root, made when the tree is empty (then `created`).
TerrainOcTreeNode* TerrainOcTree::Root(bool& created) {
  created = root == nullptr;
  if (created) {
    root = new TerrainOcTreeNode();
    ++tree_size;
  }
  return root;
}

// One step of a walk down, from `node` to its child `pos`: the child made, or a pruned node
// expanded first (its eight children take its values). A free update stops instead (null)
// at a pruned node saturated free: it would change nothing below it. `created` says
// whether `node` was made by this walk (a new node has no children, which then is no sign
// of pruning); it is updated to the child.
TerrainOcTreeNode* TerrainOcTree::Step(TerrainOcTreeNode* node, unsigned pos, bool& created,
                                       bool free_update) {
  if (nodeChildExists(node, pos)) {
    created = false;
  } else if (!nodeHasChildren(node) && !created) {
    if (free_update && IsSaturatedFree(*node)) return nullptr;
    expandNode(node);
    created = false;
  } else {
    createNodeChild(node, pos);
    created = true;
  }
  return getNodeChild(node, pos);
}

TerrainOcTreeNode* TerrainOcTree::TouchLeaf(const octomap::OcTreeKey& key) {
  bool created = false;
  TerrainOcTreeNode* node = Root(created);
  for (unsigned depth = 0; depth < tree_depth; ++depth) {
    node = Step(node, octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - depth)),
                created, false);
  }
  return node;
}

namespace {
constexpr unsigned kBrickLevels = 3;  // a brick: the node this many levels above the leaves
}  // namespace

// The leaf's update once the walk has reached it.
TerrainOcTree::FreeUpdate TerrainOcTree::FreeLeaf(TerrainOcTreeNode* leaf) const {
  if (leaf == nullptr || IsSaturatedFree(*leaf)) return {};
  FreeUpdate result;
  result.changed = true;
  result.was_obstacle = IsObstacle(*leaf);
  Update(leaf, false, false);
  return result;
}

TerrainOcTree::FreeUpdate TerrainOcTree::UpdateFree(const octomap::OcTreeKey& key) {
  bool created = false;
  TerrainOcTreeNode* node = Root(created);
  for (unsigned depth = 0; depth < tree_depth && node != nullptr; ++depth) {
    node = Step(node, octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - depth)),
                created, true);
  }
  return FreeLeaf(node);
}

int TerrainOcTree::UpdateFreeBrick(const octomap::OcTreeKey& base, const std::uint64_t (&voxels)[8],
                                   std::uint64_t (&was_obstacle)[8]) {
  std::fill(std::begin(was_obstacle), std::end(was_obstacle), 0);
  if (std::all_of(std::begin(voxels), std::end(voxels), [](std::uint64_t w) { return w == 0; })) {
    return 0;  // no walk: it would make nodes
  }
  bool created = false;
  TerrainOcTreeNode* brick = Root(created);
  for (unsigned depth = 0; depth + kBrickLevels < tree_depth; ++depth) {
    brick = Step(brick, octomap::computeChildIdx(base, static_cast<int>(tree_depth - 1 - depth)),
                 created, true);
    if (brick == nullptr) return 0;  // inside a pruned node saturated free
  }
  int changed = 0;
  for (unsigned w = 0; w < 8; ++w) {
    for (std::uint64_t word = voxels[w]; word != 0; word &= word - 1) {
      const unsigned b = w * 64 + static_cast<unsigned>(__builtin_ctzll(word));
      // Three levels down, each picked by three bits of the local Morton code; only the
      // first voxel's walk can meet the brick node as made by this update.
      TerrainOcTreeNode* node = brick;
      for (int level = 2; level >= 0 && node != nullptr; --level) {
        node = Step(node, b >> (3 * level) & 7u, created, true);
      }
      created = false;
      const FreeUpdate update = FreeLeaf(node);
      changed += update.changed;
      if (update.was_obstacle) was_obstacle[w] |= std::uint64_t{1} << (b & 63);
    }
  }
  return changed;
}

void TerrainOcTree::Update(TerrainOcTreeNode* leaf, bool occupied, bool obstacle) const {
  const float occupancy = leaf->getLogOdds() + (occupied ? prob_hit_log : prob_miss_log);
  leaf->setLogOdds(std::clamp(occupancy, clamping_thres_min, clamping_thres_max));
  const float evidence = leaf->obstacle_log_odds() + (obstacle ? prob_hit_log : prob_miss_log);
  leaf->set_obstacle_log_odds(std::clamp(evidence, clamping_thres_min, clamping_thres_max));
}

bool TerrainOcTree::IsSaturatedFree(const TerrainOcTreeNode& node) const {
  return node.getLogOdds() <= clamping_thres_min && node.obstacle_log_odds() <= clamping_thres_min;
}

void TerrainOcTree::DeleteDescendants(TerrainOcTreeNode* node, std::size_t& count) {
  for (unsigned i = 0; i < 8; ++i) {
    if (!nodeChildExists(node, i)) continue;
    TerrainOcTreeNode* child = getNodeChild(node, i);
    DeleteDescendants(child, count);
    child->ReleaseChildArray();
    deleteNodeChild(node, i);
    ++count;
  }
}

bool TerrainOcTree::DeleteOutsideRecurs(TerrainOcTreeNode* node, const octomap::OcTreeKey& key,
                                        unsigned depth, const Eigen::Vector2d& min,
                                        const Eigen::Vector2d& max, std::size_t& count) {
  if (!nodeHasChildren(node)) return false;  // a leaf straddling the border stays
  const octomap::key_type offset = tree_max_val >> (depth + 1);
  bool any_left = false;
  for (unsigned i = 0; i < 8; ++i) {
    if (!nodeChildExists(node, i)) continue;
    octomap::OcTreeKey child_key;
    octomap::computeChildKey(i, offset, key, child_key);
    const octomap::point3d c = keyToCoord(child_key, depth + 1);
    const double half = getNodeSize(depth + 1) / 2.0;
    TerrainOcTreeNode* child = getNodeChild(node, i);
    const bool outside = c.x() + half <= min.x() || c.x() - half >= max.x() ||
                         c.y() + half <= min.y() || c.y() - half >= max.y();
    if (outside || DeleteOutsideRecurs(child, child_key, depth + 1, min, max, count)) {
      DeleteDescendants(child, count);
      child->ReleaseChildArray();
      deleteNodeChild(node, i);
      ++count;
    } else {
      any_left = true;
    }
  }
  if (!any_left) return true;
  node->updateOccupancyChildren();
  return false;
}

std::size_t TerrainOcTree::DeleteOutsideXY(const Eigen::Vector2d& min, const Eigen::Vector2d& max) {
  if (root == nullptr) return 0;
  std::size_t count = 0;
  const octomap::OcTreeKey root_key(tree_max_val, tree_max_val, tree_max_val);
  if (DeleteOutsideRecurs(root, root_key, 0, min, max, count)) {
    root->ReleaseChildArray();
    delete root;
    root = nullptr;
    tree_size = 0;
    ++count;
  }
  return count;
}

}  // namespace cairn::map
