// Internal: every compatible pair of one range image, found by bounding blocks of points
// rather than testing pairs one by one (a dual-tree search).
//
// 1. Candidates. A horizontal grid of cells holds the highest and lowest point of each; a
//    point can be the lower point of a pair only if some cell within reach (Hmax / tan
//    theta) holds a point high enough above it for the cell's distance, and the upper point
//    only if one holds a point low enough. The bounds are conservative (distances between
//    cells taken at their least, a margin against rounding): every point that has a partner
//    stays, most of the open ground goes.
// 2. Trees. The candidates of each kind are stored in a binary tree over the image grid: a
//    node is a rectangle of pixels, split along its longer side down to blocks of a few
//    hundred pixels, whose points are split in space down to leaves of at most 64 (sorted by
//    height); each node has the axis-aligned box of its points in the level frame.
// 3. Search. Ordered node pairs (lower, upper) are visited from (lower subtree, upper root)
//    down, the lower tree cut into tasks (4. below, on one thread too). A pair
//    is rejected when no point of the upper box can lie HT..Hmax above, and steeper than
//    theta from, any point of the lower box; accepted whole when every point of the upper
//    box does so for every point of the lower one (all its points join one segment, at
//    once); settled, and skipped, when it can change nothing (every lower point has a
//    partner, every upper point is raised, both nodes are one segment already); else split,
//    down to leaves. There the upper leaf's points that the lower leaf's box rejects are
//    dropped, the lower points are classified against the box of the others (the near
//    points), and each lower point left is tested against all the near points at once, four
//    at a time with SSE2, eight with AVX2 and sixteen with AVX-512F where the processor has
//    them (simd.hpp); a lower point that has a partner already takes as
//    partners only the near points not yet raised in its set (a pair of two such points
//    changes nothing), and one that pairs with near points which the leaf's earlier lower
//    points took (raised, in one set) joins that set once instead of taking each again.
// 4. Tasks. The lower tree is cut into 256 or more tasks (its largest nodes first), each searched
//    against the whole upper tree; the workers share one set of marks, flags and sets
//    (relaxed atomics, a lock-free union-find that links the larger root under the smaller),
//    so that what one settles the others skip. Every fact only grows, so a worker that reads
//    one late does more work, not wrong work, and the result does not depend on the
//    interleaving.
// The box bounds use the pair test's own float operations, which are monotonic in each
// coordinate, so a rejected pair holds no compatible pair and an accepted one holds only
// compatible pairs: the obstacle points, the raised points and the sets equal the O(N^2)
// definition's. Pairs are not counted: settled pairs, most of them on dense obstacles, are
// never looked at.
#pragma once

#include <cstdint>
#include <variant>
#include <vector>

#include "cairn/od/detector.hpp"
#include "detection_internal.hpp"

namespace cairn::od::internal {

/// Which points can be the lower / upper point of a compatible pair (1 = may, 0 = cannot),
/// per pixel, by the grid bound above. Invalid points are 0 in both. On up to `threads`
/// threads (0: all), with the same result on any.
struct Candidates {
  std::vector<std::uint8_t> lower, upper;
};
Candidates FindCandidates(const LevelPoints& level, const PairTest& test, int threads = 1);

/// Points of an image (those with mask[pixel] != 0) in a binary tree of pixel rectangles
/// (blocks), each block's points split in space (below).
struct PointTree {
  struct Node {
    float lo[3], hi[3];     // level-frame box of its points [m]
    std::int32_t begin;     // its points are stored at [begin, end)
    std::int32_t end;
    std::int32_t child[2];  // -1, -1 for a leaf
    std::int32_t parent;    // -1 for a root
  };
  std::vector<Node> nodes;
  /// Per tree: one for the whole image, or one per column (column mode; -1 when the column
  /// holds no point).
  std::vector<std::int32_t> roots;
  /// Stored points in tree order (each leaf's points together, by ascending height), then
  /// kPadding more (z infinite), so that the search reads four at a time from any point.
  std::vector<float> x, y, z;
  static constexpr int kPadding = 3;
  std::vector<std::int32_t> pixel;  ///< image index of each stored point

  /// The most points a leaf holds (the search keeps a leaf's points as bits of one word).
  static constexpr int kMaxLeafPoints = 64;
  /// The most pixels of a block (below).
  static constexpr int kMaxBlockPixels = 256;
  /// The image is cut into blocks of at most block_rows x block_cols pixels (block_cols cut
  /// down so that the product is at most kMaxBlockPixels), split in halves of whole blocks
  /// along the side longer in blocks. A block's points are then split in space, each part at the
  /// middle of its box's longest side, until each part fits in a leaf: fewer leaves hold both
  /// the near and the far side of an edge in the image (BENCHMARKS.md, 2026-12-07).
  /// With `per_column`, one tree per image column (blocks of block_rows pixels): pairs are
  /// then only searched within a column.
  PointTree(const LevelPoints& level, const std::vector<std::uint8_t>& mask, int width, int height,
            int block_rows, int block_cols, bool per_column = false);

  int size() const { return static_cast<int>(pixel.size()); }

  struct SplitParts;

 private:
  std::int32_t Build(const LevelPoints& level, const std::vector<std::uint8_t>& mask, int width,
                     int r0, int r1, int c0, int c1, int block_rows, int block_cols);
  std::int32_t Block(const LevelPoints& level, const std::vector<std::uint8_t>& mask, int width,
                     int r0, int r1, int c0, int c1);
  std::int32_t Split(float* xs, float* ys, float* zs, std::int32_t* at, int m, const float* lo,
                     const float* hi, SplitParts& parts);
  std::int32_t Leaf(const float* xs, const float* ys, const float* zs, const std::int32_t* at,
                    int m, const float* lo, const float* hi);
  std::int32_t Join(std::int32_t a, std::int32_t b);
  std::int32_t stored_ = 0;  // points stored so far (Leaf)
};

/// Detect's blocks (PointTree): 4 x 64 pixels on a LiDAR scan, 16 x 16 on camera images, the
/// fastest of the shapes tried on the benchmark frames (BENCHMARKS.md, 2026-12-07; before the
/// blocks were split in space, leaves were blocks of 2 x 32 and 8 x 8 pixels).
struct BlockShape {
  int rows, cols;
};
constexpr BlockShape kLidarBlock{4, 64}, kCameraBlock{16, 16};
/// The image's kind of block: kLidarBlock on a spherical (LiDAR) image, else kCameraBlock.
inline BlockShape BlockShapeFor(const RangeImage& image) {
  return std::holds_alternative<SphericalModel>(image.model()) ? kLidarBlock : kCameraBlock;
}

struct PairSearchOptions {
  /// Build the sets (the cone detector). Off (the mask alone) and the per-column trees were
  /// the column baseline's, which now has its own pass; no caller uses them. Taking them out
  /// made the search 30% slower on the KITTI scan (50 -> 65 ms, code layout), so they stay
  /// until the search is reworked.
  bool unions = true;
  int threads = 1;     ///< >= 1
};

/// Per pixel of the image.
struct PairSearchResult {
  std::vector<std::uint8_t> lower;   ///< 1: the lower point of some compatible pair
  std::vector<std::uint8_t> raised;  ///< 1: the upper point of some compatible pair
  /// With unions: the sets as a forest, a parent pixel per pixel (a pixel in no pair is its
  /// own). Each set's root is its smallest pixel, and a parent's index is below its child's.
  /// Every pixel of a set of two or more is marked lower or raised, so a marked pixel's
  /// parent is marked too.
  std::vector<std::int32_t> parent;
  /// pairs_tested: tested point by point with the upper point HT..Hmax above the lower;
  /// pairs_compatible: found (one by one or in accepted blocks; settled pairs are not looked
  /// at, so this is not the number of pairs).
  DetectionStats stats;
};

/// The leaves' box tests (3. above): sixteen points at a time with `lanes` 16 (AVX-512F), eight
/// with 8 (AVX2), four with 4 (SSE2), else one at a time, every width with Classify's float
/// operations in its order. `lanes` is at most VectorLanes() (a wider one may be an instruction the
/// processor does not have). At most 64 points, read up to three past `count` (a tree's padding).
///
/// The lower points [0, count) of x, y, z against the box of upper points b_lo..b_hi: bit k of
/// `keep` is set unless the box rejects point k (none of its points can be a partner), of
/// `accept` when it accepts it (every one is); bits are added to both (zero them first).
void ClassifyByBox(int lanes, const float* x, const float* y, const float* z, int count,
                   const float* b_lo, const float* b_hi, const PairTest& test, std::uint64_t& keep,
                   std::uint64_t& accept);
/// The upper points [0, count) of x, y, z against the box of lower points a_lo..a_hi: bit k
/// unless the box rejects point k; `lo` and `hi` get the box of the points kept (empty: +inf
/// and -inf, when there are none).
std::uint64_t NearBox(int lanes, const float* x, const float* y, const float* z, int count,
                      const float* a_lo, const float* a_hi, const PairTest& test, float* lo,
                      float* hi);

/// Searches the pairs (lower point in `lower`, upper point in `upper`), two trees over the
/// same image of `pixels` pixels with the same number of roots (matched by position).
PairSearchResult SearchPairs(const PointTree& lower, const PointTree& upper, int pixels,
                             const PairTest& test, const PairSearchOptions& options);

}  // namespace cairn::od::internal
