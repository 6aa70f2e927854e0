#include "pair_search.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <thread>

#include "cairn/od/parallel.hpp"

namespace cairn::od::internal {

Candidates FindCandidates(const LevelPoints& level, const PairTest& test) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int n = static_cast<int>(level.z.size());
  Candidates c{std::vector<std::uint8_t>(n, 0), std::vector<std::uint8_t>(n, 0)};
  float x_lo = kInf, x_hi = -kInf, y_lo = kInf, y_hi = -kInf;
  int valid = 0;
  for (int i = 0; i < n; ++i) {
    if (std::isnan(level.z[i])) continue;
    ++valid;
    x_lo = std::min(x_lo, level.x[i]);
    x_hi = std::max(x_hi, level.x[i]);
    y_lo = std::min(y_lo, level.y[i]);
    y_hi = std::max(y_hi, level.y[i]);
  }
  if (!(x_lo <= x_hi)) return c;
  // Cells of a quarter of the reach, at most 256 a side and at most about 2 sqrt(points) a
  // side (so that a small cloud spread wide does not pay for a grid far larger than itself);
  // rings of cells around a point's cell up to the reach. Any side keeps the filter exact:
  // coarser cells only keep more candidates.
  const double tan_theta = std::sqrt(static_cast<double>(test.tan2_theta));
  const double reach = test.max_height / tan_theta;
  const double extent = std::max<double>(x_hi - x_lo, y_hi - y_lo);
  const double per_side =
      std::min(255.0, std::max(1.0, 2.0 * std::sqrt(static_cast<double>(valid))));
  const double side = std::max(reach / 4.0, extent / per_side) * (1.0 + 1e-6);
  const int nx = static_cast<int>((x_hi - x_lo) / side) + 1;
  const int ny = static_cast<int>((y_hi - y_lo) / side) + 1;
  const int rings = std::max(1, static_cast<int>(std::ceil(reach / side)));
  std::vector<float> high(static_cast<std::size_t>(nx) * ny, -kInf);
  std::vector<float> low(high.size(), kInf);
  std::vector<std::int32_t> cell(n, -1);
  // Rounding may put a point lying on a cell boundary in the neighbouring cell (off by far
  // less than a micrometre): the margin below covers it.
  const double per_m = 1.0 / side;
  for (int i = 0; i < n; ++i) {
    if (std::isnan(level.z[i])) continue;
    const int cx = std::clamp(static_cast<int>((level.x[i] - x_lo) * per_m), 0, nx - 1);
    const int cy = std::clamp(static_cast<int>((level.y[i] - y_lo) * per_m), 0, ny - 1);
    cell[i] = cy * nx + cx;
    high[cell[i]] = std::max(high[cell[i]], level.z[i]);
    low[cell[i]] = std::min(low[cell[i]], level.z[i]);
  }
  // Ring k: the highest / lowest point within k cells (Chebyshev), by repeated 3x3
  // dilation; a point there lies at least (k - 1) cells away horizontally, so a partner
  // there must be max(HT, (k - 1) side tan(theta)) above or below. A margin of 1 mm covers
  // the rounding of cells and heights.
  constexpr float kMargin = 1e-3f;
  std::vector<std::uint8_t>& lower = c.lower;
  std::vector<std::uint8_t>& upper = c.upper;
  std::vector<float> tmp(high.size());
  const auto dilate = [&](std::vector<float>& v, bool take_max) {
    const auto pick = [take_max](float a, float b) { return take_max ? std::max(a, b) : std::min(a, b); };
    for (int y = 0; y < ny; ++y) {
      const float* row = &v[static_cast<std::size_t>(y) * nx];
      float* out = &tmp[static_cast<std::size_t>(y) * nx];
      for (int x = 0; x < nx; ++x) {
        float m = row[x];
        if (x > 0) m = pick(m, row[x - 1]);
        if (x + 1 < nx) m = pick(m, row[x + 1]);
        out[x] = m;
      }
    }
    for (int y = 0; y < ny; ++y) {
      for (int x = 0; x < nx; ++x) {
        const std::size_t k = static_cast<std::size_t>(y) * nx + x;
        float m = tmp[k];
        if (y > 0) m = pick(m, tmp[k - nx]);
        if (y + 1 < ny) m = pick(m, tmp[k + nx]);
        v[k] = m;
      }
    }
  };
  // Per cell, over the rings: a point there may be a lower point when it lies below
  // `below`, an upper point when above `above`.
  std::vector<float> below(high.size(), -kInf), above(high.size(), kInf);
  for (int k = 0; k <= rings; ++k) {
    if (k > 0) {
      dilate(high, true);
      dilate(low, false);
    }
    const float need = static_cast<float>(
        std::max<double>(test.min_height, std::max(0, k - 1) * side * tan_theta)) - kMargin;
    for (std::size_t j = 0; j < high.size(); ++j) {
      below[j] = std::max(below[j], high[j] - need);
      above[j] = std::min(above[j], low[j] + need);
    }
  }
  for (int i = 0; i < n; ++i) {
    if (cell[i] < 0) continue;
    lower[i] = level.z[i] < below[cell[i]];
    upper[i] = level.z[i] > above[cell[i]];
  }
  return c;
}

PointTree::PointTree(const LevelPoints& level, const std::vector<std::uint8_t>& mask, int width,
                     int height, int leaf_rows, int leaf_cols, bool per_column) {
  const std::size_t n = static_cast<std::size_t>(width) * height;
  x.reserve(n);
  y.reserve(n);
  z.reserve(n);
  pixel.reserve(n);
  if (per_column) {
    for (int c = 0; c < width; ++c) {
      roots.push_back(Build(level, mask, width, 0, height, c, c + 1, leaf_rows, 1));
    }
  } else {
    roots.push_back(Build(level, mask, width, 0, height, 0, width, leaf_rows, leaf_cols));
  }
}

// Builds the subtree of pixels [r0, r1) x [c0, c1); returns its node, or -1 when it holds no
// point. A node with one non-empty half is that half.
std::int32_t PointTree::Build(const LevelPoints& level, const std::vector<std::uint8_t>& mask,
                              int width, int r0, int r1, int c0, int c1, int leaf_rows,
                              int leaf_cols) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const int rows = r1 - r0, cols = c1 - c0;
  if (rows <= leaf_rows && cols <= leaf_cols) {
    const std::int32_t begin = size();
    Node leaf{{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}, begin, begin, {-1, -1}, -1};
    for (int r = r0; r < r1; ++r) {
      for (int c = c0; c < c1; ++c) {
        const int i = r * width + c;
        if (!mask[i]) continue;
        const float px = level.x[i], py = level.y[i], pz = level.z[i];
        // By ascending height (insertion: leaves are small).
        int at = size();
        x.push_back(px);
        y.push_back(py);
        z.push_back(pz);
        pixel.push_back(i);
        for (; at > begin && z[at - 1] > pz; --at) {
          x[at] = x[at - 1];
          y[at] = y[at - 1];
          z[at] = z[at - 1];
          pixel[at] = pixel[at - 1];
        }
        x[at] = px;
        y[at] = py;
        z[at] = pz;
        pixel[at] = i;
        leaf.lo[0] = std::min(leaf.lo[0], px);
        leaf.lo[1] = std::min(leaf.lo[1], py);
        leaf.lo[2] = std::min(leaf.lo[2], pz);
        leaf.hi[0] = std::max(leaf.hi[0], px);
        leaf.hi[1] = std::max(leaf.hi[1], py);
        leaf.hi[2] = std::max(leaf.hi[2], pz);
      }
    }
    leaf.end = size();
    if (leaf.end == begin) return -1;
    nodes.push_back(leaf);
    return static_cast<std::int32_t>(nodes.size()) - 1;
  }
  // Split the longer side, in units of leaves, at a leaf boundary. Children first, so that
  // a node with one non-empty half can be that half.
  const bool split_rows = (rows + leaf_rows - 1) / leaf_rows > (cols + leaf_cols - 1) / leaf_cols;
  std::int32_t a, b;
  if (split_rows) {
    const int half = ((rows + leaf_rows - 1) / leaf_rows + 1) / 2 * leaf_rows;
    a = Build(level, mask, width, r0, r0 + half, c0, c1, leaf_rows, leaf_cols);
    b = Build(level, mask, width, r0 + half, r1, c0, c1, leaf_rows, leaf_cols);
  } else {
    const int half = ((cols + leaf_cols - 1) / leaf_cols + 1) / 2 * leaf_cols;
    a = Build(level, mask, width, r0, r1, c0, c0 + half, leaf_rows, leaf_cols);
    b = Build(level, mask, width, r0, r1, c0 + half, c1, leaf_rows, leaf_cols);
  }
  if (a < 0 || b < 0) return a >= 0 ? a : b;
  Node node;
  const Node& na = nodes[a];
  const Node& nb = nodes[b];
  for (int k = 0; k < 3; ++k) {
    node.lo[k] = std::min(na.lo[k], nb.lo[k]);
    node.hi[k] = std::max(na.hi[k], nb.hi[k]);
  }
  node.begin = na.begin;
  node.end = nb.end;
  node.child[0] = a;
  node.child[1] = b;
  node.parent = -1;
  const auto self = static_cast<std::int32_t>(nodes.size());
  nodes.push_back(node);
  nodes[a].parent = nodes[b].parent = self;
  return self;
}

namespace {

enum Verdict { kReject, kMixed, kAccept };

// |gap| between two intervals, computed as the pair test computes |dx| (0 when they meet).
inline float Gap(float a_lo, float a_hi, float b_lo, float b_hi) {
  if (b_lo > a_hi) return b_lo - a_hi;
  if (a_lo > b_hi) return a_lo - b_hi;
  return 0.0f;
}

// Largest |b - a| over the two intervals, as the pair test rounds it.
inline float Reach(float a_lo, float a_hi, float b_lo, float b_hi) {
  return std::max(std::abs(b_hi - a_lo), std::abs(b_lo - a_hi));
}

// The pair test over all (a in box A, b in box B) with b the upper point. Each bound is the
// pair test's float expression at the extreme coordinates; rounding is monotonic, so the
// verdict holds for every pair the boxes contain.
inline Verdict Classify(const float* a_lo, const float* a_hi, const float* b_lo, const float* b_hi,
                        const PairTest& t) {
  const float dz_hi = b_hi[2] - a_lo[2];
  const float dz_lo = b_lo[2] - a_hi[2];
  if (!(dz_hi > t.min_height) || !(dz_lo < t.max_height)) return kReject;
  const float dz_best = std::min(dz_hi, t.max_height);
  const float gx = Gap(a_lo[0], a_hi[0], b_lo[0], b_hi[0]);
  const float gy = Gap(a_lo[1], a_hi[1], b_lo[1], b_hi[1]);
  if (!(dz_best * dz_best > t.tan2_theta * (gx * gx + gy * gy))) return kReject;
  if (!(dz_lo > t.min_height) || !(dz_hi < t.max_height)) return kMixed;
  const float rx = Reach(a_lo[0], a_hi[0], b_lo[0], b_hi[0]);
  const float ry = Reach(a_lo[1], a_hi[1], b_lo[1], b_hi[1]);
  return dz_lo * dz_lo > t.tan2_theta * (rx * rx + ry * ry) ? kAccept : kMixed;
}

enum NodeFlag : std::uint8_t { kFull = 1, kUnified = 2 };

using Node = PointTree::Node;

// One worker's state over the image's pixels (flags, counts, sets) and the two trees' nodes.
// kFull on a lower-tree node: every point has a partner; on an upper-tree node: every point
// is raised. kUnified: every point of the node is in one set.
class Search {
 public:
  Search(const PointTree& lower, const PointTree& upper, int pixels, const PairTest& test,
         const PairSearchOptions& options)
      : lo_(lower), up_(upper), test_(test), unions_(options.unions),
        parent_(options.unions ? pixels : 0), lower_(pixels, 0), raised_(pixels, 0),
        flags_lo_(lower.nodes.size(), 0), flags_up_(upper.nodes.size(), 0) {
    for (int i = 0; i < static_cast<int>(parent_.size()); ++i) parent_[i] = i;
  }

  void Visit(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    const Verdict v = Classify(A.lo, A.hi, B.lo, B.hi, test_);
    if (v == kReject) return;
    ++stats_.node_pairs;
    if (v == kAccept) {
      Accept(a, b);
      return;
    }
    if (Settled(a, b)) return;
    const bool a_leaf = Leaf(A), b_leaf = Leaf(B);
    if (a_leaf && b_leaf) {
      Leaves(a, b);
      return;
    }
    if (SplitLower(A, B, a_leaf, b_leaf)) {
      Visit(A.child[0], b);
      Visit(A.child[1], b);
    } else {
      Visit(a, B.child[0]);
      Visit(a, B.child[1]);
    }
  }

  // Adds `other`'s findings (another worker over the same trees) to this one.
  void Merge(Search& other) {
    const int n = static_cast<int>(lower_.size());
    for (int i = 0; i < n; ++i) {
      lower_[i] |= other.lower_[i];
      raised_[i] |= other.raised_[i];
    }
    if (unions_) {
      for (int i = 0; i < n; ++i) {
        const int root = other.Find(i);
        if (root != i) Union(i, root);
      }
    }
    stats_.pairs_tested += other.stats_.pairs_tested;
    stats_.pairs_compatible += other.stats_.pairs_compatible;
    stats_.node_pairs += other.stats_.node_pairs;
    stats_.blocks_accepted += other.stats_.blocks_accepted;
  }

  PairSearchResult Result() {
    PairSearchResult r;
    if (unions_) {
      r.set.resize(parent_.size());
      for (int i = 0; i < static_cast<int>(parent_.size()); ++i) r.set[i] = Find(i);
    }
    r.lower = std::move(lower_);
    r.raised = std::move(raised_);
    r.stats = stats_;
    return r;
  }

 private:
  static int Size(const Node& n) { return n.end - n.begin; }
  static bool Leaf(const Node& n) { return n.child[0] < 0; }

  static bool SplitLower(const Node& A, const Node& B, bool a_leaf, bool b_leaf) {
    if (a_leaf) return false;
    if (b_leaf) return true;
    return Size(A) >= Size(B);
  }

  int Find(int i) {
    while (parent_[i] != i) {
      parent_[i] = parent_[parent_[i]];
      i = parent_[i];
    }
    return i;
  }
  // Joins the sets of i and j; returns the root of the joined set.
  int Union(int i, int j) {
    i = Find(i);
    j = Find(j);
    if (i == j) return i;
    if (i < j) std::swap(i, j);
    parent_[i] = j;
    return j;
  }

  bool Settled(int a, int b) {
    if (!(flags_lo_[a] & kFull) || !(flags_up_[b] & kFull)) return false;
    if (!unions_) return true;
    if (!(flags_lo_[a] & kUnified) || !(flags_up_[b] & kUnified)) return false;
    return Find(lo_.pixel[lo_.nodes[a].begin]) == Find(up_.pixel[up_.nodes[b].begin]);
  }

  void Accept(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    ++stats_.blocks_accepted;
    stats_.pairs_compatible += static_cast<std::int64_t>(Size(A)) * Size(B);
    Mark(lo_, flags_lo_, a, lower_);
    Mark(up_, flags_up_, b, raised_);
    if (unions_) {
      Unify(lo_, flags_lo_, a);
      Unify(up_, flags_up_, b);
      Union(lo_.pixel[A.begin], up_.pixel[B.begin]);
    }
  }

  // The first point of upper leaf B (sorted by height) more than HT above pz, as the pair
  // test rounds it: the points from there while less than Hmax above are the candidates,
  // on which the pair test reduces to its slope condition.
  int FirstAbove(const Node& B, float pz) const {
    int j = B.begin;
    while (j < B.end && !(up_.z[j] - pz > test_.min_height)) ++j;
    return j;
  }

  // Two leaves, point by point; a lower point whose partners are all or none of the upper
  // leaf is settled by the leaf's box, and once a point has a partner, the rest of a leaf
  // that is raised and in its set already can change nothing.
  void Leaves(int a, int b) {
    const Node& A = lo_.nodes[a];
    const Node& B = up_.nodes[b];
    // Raw pointers: the flag stores below may alias anything, which would reload the
    // vectors' data on every step.
    const float* ux = up_.x.data();
    const float* uy = up_.y.data();
    const float* uz = up_.z.data();
    const std::int32_t* upix = up_.pixel.data();
    std::uint8_t* raised = raised_.data();
    const float hmax = test_.max_height, tan2 = test_.tan2_theta;
    const bool b_done = (flags_up_[b] & kFull) && (!unions_ || (flags_up_[b] & kUnified));
    const int b_first = upix[B.begin];
    for (int i = A.begin; i < A.end; ++i) {
      const float p[3] = {lo_.x[i], lo_.y[i], lo_.z[i]};
      const int pi = lo_.pixel[i];
      if (b_done && lower_[pi] && (!unions_ || Find(pi) == Find(b_first))) continue;
      const Verdict v = Classify(p, p, B.lo, B.hi, test_);
      if (v == kReject) continue;
      if (v == kAccept) {
        lower_[pi] = 1;
        stats_.pairs_compatible += Size(B);
        Mark(up_, flags_up_, b, raised_);
        if (unions_) {
          Unify(up_, flags_up_, b);
          Union(pi, b_first);
        }
        continue;
      }
      int root = unions_ ? Find(pi) : 0;
      const int first = FirstAbove(B, p[2]);
      int j = first;
      bool any = false;
      for (; j < B.end && uz[j] - p[2] < hmax; ++j) {
        const float dx = ux[j] - p[0], dy = uy[j] - p[1], dz = uz[j] - p[2];
        if (!(dz * dz > tan2 * (dx * dx + dy * dy))) continue;
        ++stats_.pairs_compatible;
        any = true;
        const int pj = upix[j];
        raised[pj] = 1;
        if (unions_) {
          const int rj = Find(pj);
          if (rj != root) root = Union(root, rj);
        }
        if (b_done && (!unions_ || root == Find(b_first))) {
          ++j;
          break;
        }
      }
      stats_.pairs_tested += j - first;
      if (any) lower_[pi] = 1;
    }
    UpdateLeaf(lo_, flags_lo_, a, lower_);
    UpdateLeaf(up_, flags_up_, b, raised_);
  }

  // Sets kFull on a leaf when every point has `point_flag`, and then tries to see the leaf
  // as one set.
  void UpdateLeaf(const PointTree& t, std::vector<std::uint8_t>& flags, int n,
                  const std::vector<std::uint8_t>& point_flag) {
    const Node& node = t.nodes[n];
    if (!(flags[n] & kFull)) {
      for (int i = node.begin; i < node.end; ++i) {
        if (!point_flag[t.pixel[i]]) return;
      }
      flags[n] |= kFull;
      PropagateUp(t, flags, node.parent, kFull);
    }
    if (unions_ && !(flags[n] & kUnified)) {
      const int root = Find(t.pixel[node.begin]);
      for (int i = node.begin + 1; i < node.end; ++i) {
        if (Find(t.pixel[i]) != root) return;
      }
      flags[n] |= kUnified;
      PropagateUp(t, flags, node.parent, kUnified);
    }
  }

  // A node gets `flag` when both children have it (kUnified: and are in one set).
  void PropagateUp(const PointTree& t, std::vector<std::uint8_t>& flags, int n, NodeFlag flag) {
    for (; n >= 0 && !(flags[n] & flag); n = t.nodes[n].parent) {
      const Node& node = t.nodes[n];
      if (!(flags[node.child[0]] & flag) || !(flags[node.child[1]] & flag)) return;
      if (flag == kUnified && Find(t.pixel[t.nodes[node.child[0]].begin]) !=
                                  Find(t.pixel[t.nodes[node.child[1]].begin])) {
        return;
      }
      flags[n] |= flag;
    }
  }

  // Every point of node n gets `point_flag` (lower or raised).
  void Mark(const PointTree& t, std::vector<std::uint8_t>& flags, int n,
            std::vector<std::uint8_t>& point_flag) {
    if (flags[n] & kFull) return;
    MarkDown(t, flags, n, point_flag);
    PropagateUp(t, flags, t.nodes[n].parent, kFull);
  }
  void MarkDown(const PointTree& t, std::vector<std::uint8_t>& flags, int n,
                std::vector<std::uint8_t>& point_flag) {
    if (flags[n] & kFull) return;
    flags[n] |= kFull;
    const Node& node = t.nodes[n];
    if (Leaf(node)) {
      for (int i = node.begin; i < node.end; ++i) point_flag[t.pixel[i]] = 1;
      return;
    }
    MarkDown(t, flags, node.child[0], point_flag);
    MarkDown(t, flags, node.child[1], point_flag);
  }

  // Every point of node n in one set.
  void Unify(const PointTree& t, std::vector<std::uint8_t>& flags, int n) {
    if (flags[n] & kUnified) return;
    UnifyDown(t, flags, n);
    PropagateUp(t, flags, t.nodes[n].parent, kUnified);
  }
  void UnifyDown(const PointTree& t, std::vector<std::uint8_t>& flags, int n) {
    if (flags[n] & kUnified) return;
    flags[n] |= kUnified;
    const Node& node = t.nodes[n];
    if (Leaf(node)) {
      int root = Find(t.pixel[node.begin]);
      for (int i = node.begin + 1; i < node.end; ++i) root = Union(root, t.pixel[i]);
      return;
    }
    UnifyDown(t, flags, node.child[0]);
    UnifyDown(t, flags, node.child[1]);
    Union(t.pixel[t.nodes[node.child[0]].begin], t.pixel[t.nodes[node.child[1]].begin]);
  }

  const PointTree& lo_;
  const PointTree& up_;
  const PairTest& test_;
  const bool unions_;
  std::vector<std::int32_t> parent_;
  std::vector<std::uint8_t> lower_, raised_;
  std::vector<std::uint8_t> flags_lo_, flags_up_;
  DetectionStats stats_;
};

struct Task {
  std::int32_t lower, upper;
};

// Lower nodes that split the work, each with its tree's upper root: every lower point lies
// in exactly one, so each ordered pair is searched by exactly one task.
std::vector<Task> Tasks(const PointTree& lower, const PointTree& upper, std::size_t wanted) {
  std::vector<Task> tasks;
  for (std::size_t t = 0; t < lower.roots.size(); ++t) {
    if (lower.roots[t] >= 0 && upper.roots[t] >= 0) tasks.push_back({lower.roots[t], upper.roots[t]});
  }
  while (tasks.size() < wanted) {
    std::vector<Task> next;
    bool split = false;
    for (const Task& t : tasks) {
      const Node& n = lower.nodes[t.lower];
      if (n.child[0] < 0) {
        next.push_back(t);
      } else {
        next.push_back({n.child[0], t.upper});
        next.push_back({n.child[1], t.upper});
        split = true;
      }
    }
    tasks.swap(next);
    if (!split) break;
  }
  return tasks;
}

}  // namespace

PairSearchResult SearchPairs(const PointTree& lower, const PointTree& upper, int pixels,
                             const PairTest& test, const PairSearchOptions& options) {
  const int threads = std::max(1, options.threads);
  const std::vector<Task> tasks =
      Tasks(lower, upper, threads == 1 ? 0 : 32 * static_cast<std::size_t>(threads));
  std::vector<Search> workers;
  workers.reserve(threads);
  for (int t = 0; t < threads; ++t) workers.emplace_back(lower, upper, pixels, test, options);
  ParallelFor(
      static_cast<int>(tasks.size()), threads,
      [&](int worker, int k) { workers[worker].Visit(tasks[k].lower, tasks[k].upper); }, 1);
  for (int t = 1; t < threads; ++t) workers[0].Merge(workers[t]);
  return workers[0].Result();
}

}  // namespace cairn::od::internal
