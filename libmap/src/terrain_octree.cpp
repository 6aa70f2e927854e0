#include "cairn/map/terrain_octree.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <mutex>
#include <new>
#include <vector>

#include "cairn/od/parallel.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define CAIRN_NODE_CHUNKS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CAIRN_NODE_CHUNKS 0
#endif
#endif
#ifndef CAIRN_NODE_CHUNKS
#define CAIRN_NODE_CHUNKS 1
#endif

namespace cairn::map {

#if CAIRN_NODE_CHUNKS
namespace {

// Nodes in chunks of 64 KiB aligned to their size, each with a bit per block that is free.
// A thread takes the free bits of a chunk a word at a time, lowest address first, from the
// lowest chunk (in the order they were made) with enough free blocks: a map built after
// another gets its nodes in the order of their addresses, as a fresh one does. (Free lists
// hand back the last freed first: in one process each map built after another then got
// slower, its nodes scattered over memory.) A node is freed by setting its bit, from any
// thread. Chunks live as long as the process (nodes may outlive any static).
constexpr std::size_t kBlockBytes = 16;
static_assert(sizeof(TerrainOcTreeNode) <= kBlockBytes &&
              alignof(TerrainOcTreeNode) <= kBlockBytes);
constexpr std::size_t kChunkBytes = std::size_t{1} << 16;
constexpr std::size_t kChunkBlocks = kChunkBytes / kBlockBytes;  // 4,096
constexpr std::size_t kWords = kChunkBlocks / 64;
constexpr std::int64_t kMinFree = 256;  // fewer free blocks: a chunk is passed over

struct Chunk {
  std::atomic<std::uint64_t> free[kWords];  // bit b of word w: block 64 w + b is free
  // On a cache line of its own: blocks next to it would share it with every take and free.
  alignas(64) std::atomic<std::int64_t> free_count;
  unsigned char padding[64 - sizeof(std::atomic<std::int64_t>)];
};
constexpr std::size_t kHeaderBlocks = (sizeof(Chunk) + kBlockBytes - 1) / kBlockBytes;

struct Chunks {
  std::mutex mutex;
  std::vector<Chunk*> made;
};
Chunks& AllChunks() {
  static Chunks* chunks = new Chunks;  // never destroyed (see above)
  return *chunks;
}

// The lowest chunk with kMinFree free blocks other than `passed` (a chunk whose words just
// gave too few: others may hold the rest for a moment), or a new one.
Chunk* NextChunk(const Chunk* passed) {
  Chunks& chunks = AllChunks();
  const std::lock_guard<std::mutex> lock(chunks.mutex);
  for (Chunk* c : chunks.made) {
    if (c != passed && c->free_count.load(std::memory_order_relaxed) >= kMinFree) return c;
  }
  chunks.made.reserve(chunks.made.size() + 1);  // before the chunk: a throw loses nothing
  void* memory = std::aligned_alloc(kChunkBytes, kChunkBytes);
  if (memory == nullptr) throw std::bad_alloc();
  Chunk* c = new (memory) Chunk;
  for (std::size_t w = 0; w < kWords; ++w) {
    std::uint64_t bits = ~std::uint64_t{0};
    for (std::size_t b = 0; b < 64; ++b) {
      if (64 * w + b < kHeaderBlocks) bits &= ~(std::uint64_t{1} << b);
    }
    c->free[w].store(bits, std::memory_order_relaxed);
  }
  c->free_count.store(static_cast<std::int64_t>(kChunkBlocks - kHeaderBlocks),
                      std::memory_order_relaxed);
  chunks.made.push_back(c);
  return c;
}

// A thread's place: its chunk, the next word to take, and the free blocks taken from the
// word before. Trivially destructible: still there while statics are destroyed. Blocks taken
// and not handed out when the thread ends stay unused.
struct Cursor {
  Chunk* chunk = nullptr;
  std::size_t next_word = kWords;
  std::size_t word = 0;
  std::uint64_t taken = 0;
};
thread_local Cursor t_cursor;

void* TakeBlock() {
  Cursor& c = t_cursor;
  for (;;) {
    if (c.taken != 0) {
      const unsigned bit = static_cast<unsigned>(__builtin_ctzll(c.taken));
      c.taken &= c.taken - 1;
      return reinterpret_cast<unsigned char*>(c.chunk) + (64 * c.word + bit) * kBlockBytes;
    }
    if (c.chunk != nullptr && c.next_word < kWords) {
      c.word = c.next_word++;
      c.taken = c.chunk->free[c.word].exchange(0, std::memory_order_acquire);
      if (c.taken != 0) {
        c.chunk->free_count.fetch_sub(__builtin_popcountll(c.taken), std::memory_order_relaxed);
      }
      continue;
    }
    c.chunk = NextChunk(c.chunk);
    c.next_word = 0;
  }
}

void GiveBlock(void* p) noexcept {
  const auto address = reinterpret_cast<std::uintptr_t>(p);
  Chunk* chunk = reinterpret_cast<Chunk*>(address & ~(kChunkBytes - 1));
  const std::size_t block = (address & (kChunkBytes - 1)) / kBlockBytes;
  chunk->free[block / 64].fetch_or(std::uint64_t{1} << (block % 64), std::memory_order_release);
  chunk->free_count.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

void* TerrainOcTreeNode::operator new(std::size_t size) {
  if (size != sizeof(TerrainOcTreeNode)) return ::operator new(size);
  return TakeBlock();
}

void TerrainOcTreeNode::operator delete(void* node, std::size_t size) noexcept {
  if (node == nullptr) return;
  if (size != sizeof(TerrainOcTreeNode)) {
    ::operator delete(node);
    return;
  }
  GiveBlock(node);
}
#else
void* TerrainOcTreeNode::operator new(std::size_t size) { return ::operator new(size); }
void TerrainOcTreeNode::operator delete(void* node, std::size_t) noexcept {
  ::operator delete(node);
}
#endif

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
inline TerrainOcTreeNode* TerrainOcTree::Step(TerrainOcTreeNode* node, unsigned pos, bool& created,
                                              bool free_update, std::size_t& made) {
  if (nodeChildExists(node, pos)) {
    created = false;
  } else if (!nodeHasChildren(node) && !created) {
    if (free_update && IsSaturatedFree(*node)) return nullptr;
    node->Expand();
    made += 8;
    created = false;
  } else {
    node->MakeChild(pos);
    ++made;
    created = true;
  }
  return getNodeChild(node, pos);
}

TerrainOcTreeNode* TerrainOcTree::TouchLeaf(const octomap::OcTreeKey& key) {
  bool created = false;
  return WalkDown(key, tree_depth, false, created);
}

namespace {
constexpr unsigned kBrickLevels = 3;  // a brick: the node this many levels above the leaves
// UpdateBricks' subtrees: this many levels above a brick (8 x 8 x 8 bricks, 6.4 m at
// 0.1 m voxels; a LiDAR frame's bricks fall into a few hundred).
constexpr unsigned kSubtreeLevels = 3;
}  // namespace

// The leaf's update once the walk has reached it.
inline TerrainOcTree::FreeUpdate TerrainOcTree::FreeLeaf(TerrainOcTreeNode* leaf) const {
  if (leaf == nullptr || IsSaturatedFree(*leaf)) return {};
  FreeUpdate result;
  result.changed = true;
  result.was_obstacle = IsObstacle(*leaf);
  Update(leaf, false, false);
  return result;
}

TerrainOcTree::FreeUpdate TerrainOcTree::UpdateFree(const octomap::OcTreeKey& key) {
  bool created = false;
  return FreeLeaf(WalkDown(key, tree_depth, true, created));
}

TerrainOcTreeNode* TerrainOcTree::WalkDown(const octomap::OcTreeKey& key, unsigned depth,
                                           bool free_update, bool& created) {
  std::size_t made = 0;
  TerrainOcTreeNode* node = Root(created);
  for (unsigned d = 0; d < depth && node != nullptr; ++d) {
    node = Step(node, octomap::computeChildIdx(key, static_cast<int>(tree_depth - 1 - d)), created,
                free_update, made);
  }
  CountMade(made);
  return node;
}

namespace {
bool AnyVoxel(const std::uint64_t (&voxels)[8]) {
  return std::any_of(std::begin(voxels), std::end(voxels), [](std::uint64_t w) { return w != 0; });
}
}  // namespace

int TerrainOcTree::UpdateBrickBelow(TerrainOcTreeNode* node, unsigned depth, bool created,
                                    BrickUpdate& brick, std::size_t& made) {
  // A hit's walk expands the pruned nodes on its way, which a free update's stops at.
  const bool hits = AnyVoxel(brick.hit);
  for (unsigned d = depth; d + kBrickLevels < tree_depth && node != nullptr; ++d) {
    node = Step(node, octomap::computeChildIdx(brick.base, static_cast<int>(tree_depth - 1 - d)),
                created, !hits, made);
  }
  if (node == nullptr) return 0;  // inside a pruned node saturated free
  int changed = 0;
  // Three levels down, each picked by three bits of the local Morton code; only the first
  // voxel's walk can meet the brick node as made by this update. Voxels in Morton order
  // share their first two steps with the voxel before in runs of 64 and 8: those steps
  // are kept (a step taken again returns what it returned, null included, and changes
  // nothing), so most voxels take one step. A hit where a free update's step stopped (null,
  // at a pruned node saturated free) takes the step again, expanding that node.
  unsigned last_64 = ~0u, last_8 = ~0u;
  TerrainOcTreeNode* upper = nullptr;  // the node of voxels b >> 6 == last_64
  TerrainOcTreeNode* lower = nullptr;  // the node of voxels b >> 3 == last_8
  for (unsigned w = 0; w < 8; ++w) {
    for (std::uint64_t word = brick.free[w] | brick.hit[w]; word != 0; word &= word - 1) {
      const unsigned at = static_cast<unsigned>(__builtin_ctzll(word));
      const unsigned b = w * 64 + at;
      const bool hit = (brick.hit[w] >> at & 1) != 0;
      if (b >> 6 != last_64 || (hit && upper == nullptr)) {
        upper = Step(node, b >> 6, created, !hit, made);
        last_64 = b >> 6;
        last_8 = ~0u;
      }
      if (b >> 3 != last_8 || (hit && lower == nullptr)) {
        lower = upper == nullptr ? nullptr : Step(upper, b >> 3 & 7u, created, !hit, made);
        last_8 = b >> 3;
      }
      TerrainOcTreeNode* leaf =
          lower == nullptr ? nullptr : Step(lower, b & 7u, created, !hit, made);
      created = false;
      if (hit) {
        Update(leaf, true, (brick.obstacle[w] >> at & 1) != 0);
        continue;
      }
      const FreeUpdate update = FreeLeaf(leaf);
      changed += update.changed;
      if (update.was_obstacle) brick.was_obstacle[w] |= std::uint64_t{1} << at;
    }
  }
  return changed;
}

int TerrainOcTree::UpdateFreeBrick(const octomap::OcTreeKey& base, const std::uint64_t (&voxels)[8],
                                   std::uint64_t (&was_obstacle)[8]) {
  std::fill(std::begin(was_obstacle), std::end(was_obstacle), 0);
  if (!AnyVoxel(voxels)) return 0;  // no walk: it would make nodes
  BrickUpdate brick;
  brick.base = base;
  std::copy(std::begin(voxels), std::end(voxels), std::begin(brick.free));
  bool created = false;
  std::size_t made = 0;
  TerrainOcTreeNode* top = Root(created);
  const int changed = UpdateBrickBelow(top, 0, created, brick, made);
  CountMade(made);
  std::copy(std::begin(brick.was_obstacle), std::end(brick.was_obstacle), std::begin(was_obstacle));
  return changed;
}

void TerrainOcTree::UpdateBricks(std::vector<BrickUpdate>& bricks, int threads) {
  const unsigned depth = tree_depth - kBrickLevels - kSubtreeLevels;  // the subtrees' depth
  const unsigned shift = tree_depth - depth;
  auto subtree_of = [&](const octomap::OcTreeKey& k) {
    return std::array<unsigned, 3>{static_cast<unsigned>(k[0]) >> shift,
                                   static_cast<unsigned>(k[1]) >> shift,
                                   static_cast<unsigned>(k[2]) >> shift};
  };
  // The subtrees, as runs of bricks, and the node each starts from: walked in order, as the
  // first brick with a voxel in each would walk it.
  struct Subtree {
    std::size_t first = 0, last = 0;  // the bricks [first, last)
    TerrainOcTreeNode* node = nullptr;
    bool created = false;  // the node was made by this walk
  };
  std::vector<Subtree> subtrees;
  for (std::size_t i = 0; i < bricks.size();) {
    Subtree t;
    t.first = i;
    const auto id = subtree_of(bricks[i].base);
    while (i < bricks.size() && subtree_of(bricks[i].base) == id) ++i;
    t.last = i;
    for (std::size_t j = t.first; j < t.last; ++j) {
      std::fill(std::begin(bricks[j].was_obstacle), std::end(bricks[j].was_obstacle), 0);
      bricks[j].changed = 0;
    }
    const auto first = bricks.begin() + static_cast<std::ptrdiff_t>(t.first);
    const auto last = bricks.begin() + static_cast<std::ptrdiff_t>(t.last);
    const auto with_voxels = std::find_if(
        first, last, [](const BrickUpdate& b) { return AnyVoxel(b.free) || AnyVoxel(b.hit); });
    if (with_voxels == last) continue;
    // With a hit below it, the subtree's node is reached as TouchLeaf reaches it.
    const bool hits =
        std::any_of(with_voxels, last, [](const BrickUpdate& b) { return AnyVoxel(b.hit); });
    t.node = WalkDown(with_voxels->base, depth, !hits, t.created);
    if (t.node != nullptr) subtrees.push_back(t);
  }
  std::vector<std::size_t> made(static_cast<std::size_t>(std::max(1, od::ThreadCount(threads))), 0);
  od::ParallelFor(
      static_cast<int>(subtrees.size()), threads,
      [&](int worker, int s) {
        const Subtree& t = subtrees[static_cast<std::size_t>(s)];
        bool created = t.created;
        for (std::size_t j = t.first; j < t.last; ++j) {
          BrickUpdate& brick = bricks[j];
          if (!AnyVoxel(brick.free) && !AnyVoxel(brick.hit)) continue;
          brick.changed = UpdateBrickBelow(t.node, depth, created, brick,
                                           made[static_cast<std::size_t>(worker)]);
          created = false;  // the path to the subtree's node has children now
        }
      },
      1);
  for (std::size_t m : made) CountMade(m);
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

bool TerrainOcTree::PruneSaturatedFreeRecurs(TerrainOcTreeNode* node, std::size_t& count) {
  if (!nodeHasChildren(node)) return IsSaturatedFree(*node);
  bool all = true;
  for (unsigned i = 0; i < 8; ++i) {
    // Every child is visited (not stopping at the first that is not saturated): its own
    // subtrees collapse too.
    all = nodeChildExists(node, i) && PruneSaturatedFreeRecurs(getNodeChild(node, i), count) && all;
  }
  // Saturated at the clamping thresholds, the eight are equal; a tree read with other
  // thresholds may hold leaves below them that differ, which stay apart.
  for (unsigned i = 1; all && i < 8; ++i) all = *getNodeChild(node, i) == *getNodeChild(node, 0);
  if (!all) return false;
  node->copyData(*getNodeChild(node, 0));
  for (unsigned i = 0; i < 8; ++i) deleteNodeChild(node, i);
  node->ReleaseChildArray();
  count += 8;
  return true;
}

std::size_t TerrainOcTree::PruneSaturatedFree() {
  if (root == nullptr) return 0;
  std::size_t count = 0;
  PruneSaturatedFreeRecurs(root, count);
  return count;
}

bool TerrainOcTree::DeleteOutsideRecurs(TerrainOcTreeNode* node, const octomap::OcTreeKey& key,
                                        unsigned depth, const Eigen::Vector2d& min,
                                        const Eigen::Vector2d& max, std::size_t& count) {
  if (!nodeHasChildren(node)) {
    // A voxel straddling the border stays; a pruned node straddling it is expanded, so that
    // what stays does not depend on when the tree was pruned.
    const octomap::point3d c = keyToCoord(key, depth);
    const double half = getNodeSize(depth) / 2.0;
    const bool inside = c.x() - half >= min.x() && c.x() + half <= max.x() &&
                        c.y() - half >= min.y() && c.y() + half <= max.y();
    if (inside || depth >= tree_depth) return false;
    node->Expand();
    CountMade(8);
  }
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
