#include "cairn/map/terrain_octree.hpp"

#include <algorithm>
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

TerrainOcTreeNode* TerrainOcTree::TouchLeaf(const octomap::OcTreeKey& key) {
  bool created = false;
  if (root == nullptr) {
    root = new TerrainOcTreeNode();
    ++tree_size;
    created = true;
  }
  TerrainOcTreeNode* node = root;
  for (unsigned depth = 0; depth < tree_depth; ++depth) {
    const unsigned pos = octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - depth));
    if (nodeChildExists(node, pos)) {
      created = false;
    } else if (!nodeHasChildren(node) && !created) {
      // A pruned node: its eight children take its values, then the walk goes on.
      expandNode(node);
      created = false;
    } else {
      createNodeChild(node, pos);
      created = true;
    }
    node = getNodeChild(node, pos);
  }
  return node;
}

TerrainOcTree::FreeUpdate TerrainOcTree::UpdateFree(const octomap::OcTreeKey& key) {
  FreeCursor cursor;
  return UpdateFree(key, cursor);
}

TerrainOcTree::FreeUpdate TerrainOcTree::UpdateFree(const octomap::OcTreeKey& key,
                                                    FreeCursor& cursor) {
  constexpr unsigned kBrickLevels = 3;
  const std::uint64_t brick = static_cast<std::uint64_t>(key[0] >> kBrickLevels) |
                              static_cast<std::uint64_t>(key[1] >> kBrickLevels) << 16 |
                              static_cast<std::uint64_t>(key[2] >> kBrickLevels) << 32;
  const unsigned brick_depth = tree_depth - kBrickLevels;
  TerrainOcTreeNode* node = nullptr;
  unsigned depth = 0;
  // Whether `node` was created by this update (its missing children are then not a sign of
  // pruning). A brick node reached again has children (the first update made one) unless
  // it is a pruned leaf, so false is right for it.
  bool created = false;
  if (brick == cursor.brick) {
    if (cursor.node == nullptr) return {};  // inside a saturated free pruned node
    node = cursor.node;
    depth = brick_depth;
  } else {
    cursor.brick = brick;
    cursor.node = nullptr;
    if (root == nullptr) {
      root = new TerrainOcTreeNode();
      ++tree_size;
      created = true;
    }
    node = root;
  }
  for (; depth < tree_depth; ++depth) {
    if (depth == brick_depth && cursor.node == nullptr) cursor.node = node;
    const unsigned pos = octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - depth));
    if (nodeChildExists(node, pos)) {
      created = false;
    } else if (!nodeHasChildren(node) && !created) {
      if (IsSaturatedFree(*node)) return {};  // pruned, and already as free as can be
      expandNode(node);
      created = false;
    } else {
      createNodeChild(node, pos);
      created = true;
    }
    node = getNodeChild(node, pos);
  }
  if (IsSaturatedFree(*node)) return {};
  FreeUpdate result;
  result.changed = true;
  result.was_obstacle = IsObstacle(*node);
  Update(node, false, false);
  return result;
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
