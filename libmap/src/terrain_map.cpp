#include "cairn/map/terrain_map.hpp"

#include <octomap/OcTreeKey.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>

#include "cairn/od/parallel.hpp"
#include "cairn/util/format.hpp"
#include "key_bricks.hpp"
#include "place_returns.hpp"
#include "ray_keys.hpp"
#include "simd.hpp"  // libod/src: the processor's vector width

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace cairn::map {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr std::int64_t kOctreeFlushFrames = 8;

float LogOdds(double p) { return static_cast<float>(std::log(p / (1.0 - p))); }

/// How many cells along x or y a radius reaches: the most k with k cells' width within it, as
/// DiscOffsets counts it (a radius of a whole number of cells, 1.2 m at 0.2 m, reaches its
/// last cell although 1.2 / 0.2 evaluates to 5.999...).
int ReachCells(double radius_m, double cell_size_m) {
  int r = static_cast<int>(std::floor(radius_m / cell_size_m));
  while ((r + 1) * cell_size_m <= radius_m + 1e-9) ++r;
  return r;
}

/// Cell offsets whose centres lie within `radius_m` of the centre cell's (itself included).
std::vector<CellIndex> DiscOffsets(double radius_m, double cell_size_m) {
  const int r = ReachCells(radius_m, cell_size_m);
  std::vector<CellIndex> offsets;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (std::hypot(dx, dy) * cell_size_m <= radius_m + 1e-9) offsets.emplace_back(dx, dy);
    }
  }
  return offsets;
}

CellIndex Grow(const CellIndex& index, int cells) { return index + CellIndex::Constant(cells); }

#if defined(CAIRN_OD_WIDE_VECTORS)
// UpdateTerrain's sums for the four cells of a row from the one whose elevation and weight
// `z` and `w` point at, a cell to a lane, each lane with the one-cell loop's operations in its
// order: the right-hand side into rhs[k][lane], the normal matrix's upper triangle into
// n[e][lane] (AVX2).
__attribute__((target("avx2"))) void FitSumsAvx2(const double* z, const double* w,
                                                 const std::ptrdiff_t* offsets,
                                                 const std::array<double, 6>* upper,
                                                 std::size_t disc_size, double (&rhs)[3][4],
                                                 double (&n)[6][4]) {
  __m256d r[3], u[6];
  for (__m256d& v : r) v = _mm256_setzero_pd();
  for (__m256d& v : u) v = _mm256_setzero_pd();
  for (std::size_t o = 0; o < disc_size; ++o) {
    const __m256d zo = _mm256_loadu_pd(z + offsets[o]), wo = _mm256_loadu_pd(w + offsets[o]);
    for (int k = 0; k < 3; ++k)
      r[k] = _mm256_add_pd(r[k], _mm256_mul_pd(_mm256_set1_pd(upper[o][k]), zo));
    for (int e = 0; e < 6; ++e)
      u[e] = _mm256_add_pd(u[e], _mm256_mul_pd(wo, _mm256_set1_pd(upper[o][e])));
  }
  for (int k = 0; k < 3; ++k) _mm256_storeu_pd(rhs[k], r[k]);
  for (int e = 0; e < 6; ++e) _mm256_storeu_pd(n[e], u[e]);
}

// UpdateTerrain's sums of squared residuals for four cells of a row, planes (a, b, c) a lane each,
// as FitSumsAvx2.
__attribute__((target("avx2"))) void FitResidualsAvx2(const double* z, const double* w,
                                                      const std::ptrdiff_t* offsets,
                                                      const CellIndex* disc, std::size_t disc_size,
                                                      double s, const double (&plane)[3][4],
                                                      double (&residual2)[4]) {
  const __m256d a = _mm256_loadu_pd(plane[0]), b = _mm256_loadu_pd(plane[1]);
  const __m256d c = _mm256_loadu_pd(plane[2]), vs = _mm256_set1_pd(s);
  __m256d sum = _mm256_setzero_pd();
  for (std::size_t o = 0; o < disc_size; ++o) {
    const __m256d dx = _mm256_set1_pd(disc[o].x()), dy = _mm256_set1_pd(disc[o].y());
    const __m256d at = _mm256_add_pd(_mm256_add_pd(a, _mm256_mul_pd(_mm256_mul_pd(b, dx), vs)),
                                     _mm256_mul_pd(_mm256_mul_pd(c, dy), vs));
    const __m256d r = _mm256_sub_pd(_mm256_loadu_pd(z + offsets[o]), at);
    sum = _mm256_add_pd(sum, _mm256_mul_pd(_mm256_loadu_pd(w + offsets[o]), _mm256_mul_pd(r, r)));
  }
  _mm256_storeu_pd(residual2, sum);
}
#endif

// The plane (a, b, c) of a cell's fit from the upper triangle n of its normal matrix N (n[0] the
// neighbours with an elevation) and its right-hand side, by N's adjugate over its determinant
// (a few dozen operations, in place of an LDLT factorisation and solve per cell). False with
// fewer than 3 neighbours, or when they are collinear (|det N| < 1e-9 s^4 for cells s metres
// apart; det N is at least s^4 otherwise, the cells lying on a grid): the plane is then
// undetermined.
bool SolvePlane(const double (&n)[6], const Eigen::Vector3d& rhs, double s,
                Eigen::Vector3d& plane) {
  if (n[0] < 3.0) return false;
  const double a = n[0], b = n[1], c = n[2], d = n[3], e = n[4], f = n[5];
  const double a00 = d * f - e * e, a01 = c * e - b * f, a02 = b * e - c * d;
  const double det = a * a00 + b * a01 + c * a02;
  if (!(std::abs(det) >= 1e-9 * s * s * s * s)) return false;
  const double a11 = a * f - c * c, a12 = b * c - a * e, a22 = a * d - b * b;
  plane = Eigen::Vector3d(a00 * rhs.x() + a01 * rhs.y() + a02 * rhs.z(),
                          a01 * rhs.x() + a11 * rhs.y() + a12 * rhs.z(),
                          a02 * rhs.x() + a12 * rhs.y() + a22 * rhs.z()) /
          det;
  return true;
}

using internal::kFar;
using internal::kGround;
using internal::kNone;
using internal::kObstacle;

#if defined(CAIRN_OD_WIDE_VECTORS)
// PlacePixels four pixels at a time (AVX2), from pixel 0 on; returns the first pixel left (fewer
// than four before n). m holds T_world_sensor's rotation row by row, then its translation.
__attribute__((target("avx2,popcnt"))) int PlacePixelsAvx2(
    const float* x, const float* y, const float* z, const std::uint8_t* valid_mask, int n,
    const double (&m)[12], double max_range_m, double cell_size_m, std::uint8_t* point_class,
    Eigen::Vector3d* world, CellIndex* cell, int& valid, CellIndex& lo, CellIndex& hi) {
  const __m256d zero = _mm256_setzero_pd(), max_range = _mm256_set1_pd(max_range_m);
  const __m256d size = _mm256_set1_pd(cell_size_m);
  __m256d r[12];
  for (int k = 0; k < 12; ++k) r[k] = _mm256_set1_pd(m[k]);
  __m128i lo_x = _mm_set1_epi32(lo.x()), lo_y = _mm_set1_epi32(lo.y());
  __m128i hi_x = _mm_set1_epi32(hi.x()), hi_y = _mm_set1_epi32(hi.y());
  alignas(32) double wx[4], wy[4], wz[4];
  int placed_count = 0, i = 0;
  for (; i + 4 <= n; i += 4) {
    std::int32_t bytes;
    std::memcpy(&bytes, valid_mask + i, sizeof bytes);
    const __m256d has_return = _mm256_castsi256_pd(_mm256_xor_si256(
        _mm256_cmpeq_epi64(_mm256_cvtepu8_epi64(_mm_cvtsi32_si128(bytes)), _mm256_setzero_si256()),
        _mm256_set1_epi64x(-1)));
    const __m256d px = _mm256_cvtps_pd(_mm_loadu_ps(x + i));
    const __m256d py = _mm256_cvtps_pd(_mm_loadu_ps(y + i));
    const __m256d pz = _mm256_cvtps_pd(_mm_loadu_ps(z + i));
    // p.norm(), then the cut, as the one-pixel path has them.
    const __m256d range = _mm256_sqrt_pd(_mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(px, px), _mm256_mul_pd(py, py)), _mm256_mul_pd(pz, pz)));
    const __m256d placed = _mm256_and_pd(has_return, _mm256_cmp_pd(range, zero, _CMP_GT_OQ));
    const __m256d far = _mm256_and_pd(placed, _mm256_cmp_pd(range, max_range, _CMP_GT_OQ));
    const __m256d scale = _mm256_div_pd(max_range, range);
    const __m256d qx = _mm256_blendv_pd(px, _mm256_mul_pd(px, scale), far);
    const __m256d qy = _mm256_blendv_pd(py, _mm256_mul_pd(py, scale), far);
    const __m256d qz = _mm256_blendv_pd(pz, _mm256_mul_pd(pz, scale), far);
    // Row k of R times q, plus the translation's k.
    __m256d v[3];
    for (int k = 0; k < 3; ++k) {
      v[k] = _mm256_add_pd(
          _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r[3 * k], qx), _mm256_mul_pd(r[3 * k + 1], qy)),
                        _mm256_mul_pd(r[3 * k + 2], qz)),
          r[9 + k]);
    }
    _mm256_store_pd(wx, v[0]);
    _mm256_store_pd(wy, v[1]);
    _mm256_store_pd(wz, v[2]);
    // IndexOf: floor(coordinate / size), exact in doubles, as ints.
    const __m128i cx = _mm256_cvtpd_epi32(
        _mm256_round_pd(_mm256_div_pd(v[0], size), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
    const __m128i cy = _mm256_cvtpd_epi32(
        _mm256_round_pd(_mm256_div_pd(v[1], size), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
    auto* const to = reinterpret_cast<__m128i*>(cell + i);
    _mm_storeu_si128(to, _mm_unpacklo_epi32(cx, cy));
    _mm_storeu_si128(to + 1, _mm_unpackhi_epi32(cx, cy));
    // The cells' bounds over the placed pixels only (the others' lanes keep the bounds).
    const __m128i in = _mm256_cvtpd_epi32(_mm256_and_pd(placed, _mm256_set1_pd(-1.0)));
    lo_x = _mm_min_epi32(lo_x, _mm_blendv_epi8(lo_x, cx, in));
    lo_y = _mm_min_epi32(lo_y, _mm_blendv_epi8(lo_y, cy, in));
    hi_x = _mm_max_epi32(hi_x, _mm_blendv_epi8(hi_x, cx, in));
    hi_y = _mm_max_epi32(hi_y, _mm_blendv_epi8(hi_y, cy, in));
    const int is_placed = _mm256_movemask_pd(placed), is_far = _mm256_movemask_pd(far);
    placed_count += __builtin_popcount(static_cast<unsigned>(is_placed));
    for (int l = 0; l < 4; ++l) {
      point_class[i + l] = ((is_placed >> l) & 1) == 0 ? kNone
                           : ((is_far >> l) & 1)       ? kFar
                                                       : kGround;
      world[i + l] = Eigen::Vector3d(wx[l], wy[l], wz[l]);
    }
  }
  alignas(16) std::int32_t b[4][4];
  _mm_store_si128(reinterpret_cast<__m128i*>(b[0]), lo_x);
  _mm_store_si128(reinterpret_cast<__m128i*>(b[1]), lo_y);
  _mm_store_si128(reinterpret_cast<__m128i*>(b[2]), hi_x);
  _mm_store_si128(reinterpret_cast<__m128i*>(b[3]), hi_y);
  for (int l = 0; l < 4; ++l) {
    lo = lo.cwiseMin(CellIndex(b[0][l], b[1][l]));
    hi = hi.cwiseMax(CellIndex(b[2][l], b[3][l]));
  }
  valid += placed_count;
  return i;
}
#endif

}  // namespace

namespace internal {

void PlacePixels(const float* x, const float* y, const float* z, const std::uint8_t* valid_mask,
                 int n, const Eigen::Isometry3d& T_world_sensor, double max_range_m,
                 const TerrainGrid& grid, int lanes, std::uint8_t* point_class,
                 Eigen::Vector3d* world, CellIndex* cell, int& valid, CellIndex& lo,
                 CellIndex& hi) {
  int i = 0;
#if defined(CAIRN_OD_WIDE_VECTORS)
  if (lanes >= 8) {
    const Eigen::Matrix3d& R = T_world_sensor.linear();
    const Eigen::Vector3d& t = T_world_sensor.translation();
    const double m[12] = {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2),
                          R(2, 0), R(2, 1), R(2, 2), t.x(),   t.y(),   t.z()};
    i = PlacePixelsAvx2(x, y, z, valid_mask, n, m, max_range_m, grid.cell_size(), point_class,
                        world, cell, valid, lo, hi);
  }
#else
  (void)lanes;
#endif
  for (; i < n; ++i) {
    point_class[i] = kNone;
    if (valid_mask[i] == 0) continue;
    const Eigen::Vector3d p(x[i], y[i], z[i]);  // as RangeImage::point
    const double range = p.norm();
    if (!(range > 0.0)) continue;
    ++valid;
    if (range > max_range_m) {
      point_class[i] = kFar;
      world[i] = T_world_sensor * (p * (max_range_m / range));
    } else {
      point_class[i] = kGround;
      world[i] = T_world_sensor * p;
    }
    cell[i] = grid.IndexOf(world[i].head<2>());
    lo = lo.cwiseMin(cell[i]);
    hi = hi.cwiseMax(cell[i]);
  }
}

}  // namespace internal

// Per-slot values that live for one frame (stamped with the frame, reset lazily).
struct TerrainMap::Scratch {
  struct Slot {
    std::int64_t stamp = -1;
    int ground = 0;
    int obstacle = 0;
    bool seen_through = false;
  };
  std::vector<Slot> slots;
  std::vector<CellIndex> touched;  // cells stamped this frame
  // The frame's box of cells: those of its in-range returns in the grid and those within the
  // ground disc of them, row by row from frame_lo, frame_width wide. Per cell its lowest
  // in-range return this frame (low_z infinite where none; low_x and low_y are then stale),
  // and, once a point in it asked (HeightAboveGround), the lowest returns of the cells within
  // reach at around[around_begin, around_end) (around_begin -1 before) and the lowest of
  // their heights. Dense: a frame's look-ups of its neighbourhoods read rows of it instead of
  // each neighbour's slot.
  CellIndex frame_lo = CellIndex::Zero();
  int frame_width = 0;
  std::vector<float> low_x, low_y, low_z;
  std::vector<std::int32_t> around_begin, around_end;
  std::vector<float> lowest_around;
  std::vector<std::ptrdiff_t> ground_disc_at;  // ground_disc's offsets in the frame's box
  // Per cell that asked: the lowest returns within reach, coordinate by coordinate.
  std::vector<float> around_x, around_y, around_z;
  std::vector<std::uint8_t> point_class;
  std::vector<Eigen::Vector3d> world;  // per pixel with a return: it (or its clipped ray end)
  std::vector<CellIndex> point_cell;   // per pixel with a return: its cell
  std::vector<std::ptrdiff_t> point_slot;  // and that cell's slot, -1 outside the grid
  TerrainGrid::SlotTable frame_slots;      // the frame's cells and those within the ground disc
  internal::KeyBricks endpoints;           // voxels where in-range returns end
  internal::KeyBricks obstacle_endpoints;  // those where obstacle returns end
  internal::KeyBricks far_ends;            // ends of the rays of returns beyond max_range
  internal::KeyBricks free_keys;
  std::vector<octomap::OcTreeKey> ray_ends;        // the endpoints and the far ends
  std::vector<internal::KeyBricks> worker_keys;    // free keys of the other ray workers
  std::vector<internal::KeyBitBox> ray_boxes;      // free keys of each ray worker, as bits
  std::vector<std::pair<std::uint64_t, std::uint32_t>> brick_order;
  std::vector<TerrainOcTree::BrickUpdate> bricks;  // a frame's free voxels and ends, brick by brick
  TerrainGrid::SlotTable slot_table;   // UpdateTerrain's and UpdateCosts', kept from frame to frame
  std::vector<CellIndex> ground_disc;  // cells that may hold a return within ground_radius
  std::vector<CellIndex> fit_disc;     // offsets within plane_fit_radius
  // Per offset (dx, dy): the upper triangle of the outer product of its row (1, dx, dy) [m]
  // with itself, whose first three are the row.
  std::vector<std::array<double, 6>> fit_upper;
  std::vector<double> fit_elevations;            // UpdateTerrain's box, row by row (0 where none)
  std::vector<double> fit_weights;          // and 1 where the cell has an elevation, 0 where not
  std::vector<std::ptrdiff_t> fit_offsets;  // fit_disc's offsets in that box
  std::vector<CellIndex> merge_disc;   // offsets within merge_distance
  int inflation_cells = 0;             // r: the inflation reaches r cells along x or y
  // The inflation cost at offset (dx, dy) within r of a lethal cell, at (dy + r) (2 r + 1) +
  // dx + r; 0 at the cell itself and beyond inflation_radius.
  std::vector<Cost> inflation_table;
  std::vector<Cost> inflation_box;    // per cell of UpdateCosts' box, the most inflation at it

  // Cell c's place in the frame's box.
  std::size_t FrameCell(const CellIndex& c) const {
    return static_cast<std::size_t>(c.y() - frame_lo.y()) * static_cast<std::size_t>(frame_width) +
           static_cast<std::size_t>(c.x() - frame_lo.x());
  }

  // Cell c's slot for frame `stamp`: reset and listed in `touched` when first met.
  Slot& Stamp(const TerrainGrid& grid, const CellIndex& c, std::int64_t stamp) {
    return Stamp(grid.Slot(c), c, stamp);
  }
  Slot& Stamp(std::size_t grid_slot, const CellIndex& c, std::int64_t stamp) {
    Slot& slot = slots[grid_slot];
    if (slot.stamp != stamp) {
      slot = Slot{};
      slot.stamp = stamp;
      touched.push_back(c);
    }
    return slot;
  }
};

// A kept segment as this frame saw it.
struct TerrainMap::FrameSegment {
  int label = 0;
  std::vector<CellIndex> cells;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Constant(std::numeric_limits<double>::lowest());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::int64_t count = 0;
  double height_m = 0.0;

  // Adds obstacle return p, in cell c, standing plain_height_m above the lowest return near it.
  void Add(int segment_label, const CellIndex& c, const Eigen::Vector3d& p, double plain_height_m) {
    label = segment_label;
    // Returns come in the image's order, a segment's runs of them in one cell: each run's
    // cell once (the cells are sorted and made unique later).
    if (cells.empty() || cells.back() != c) cells.push_back(c);
    bbox_min = bbox_min.cwiseMin(p);
    bbox_max = bbox_max.cwiseMax(p);
    sum += p;
    ++count;
    height_m = std::max(height_m, plain_height_m);
  }
};

TerrainMap::TerrainMap(const MapConfig& config)
    : config_(config),
      grid_(config.cell_size_m,
            config.window_size_m > 0.0
                ? static_cast<int>(std::ceil(config.window_size_m / config.cell_size_m - 1e-9))
                : 0),
      octree_(std::make_unique<TerrainOcTree>(config.voxel_size_m)),
      scratch_(std::make_unique<Scratch>()) {
  octree_->setProbHit(config.voxel_hit_probability);
  octree_->setProbMiss(config.voxel_miss_probability);
  octree_->setClampingThresMin(config.voxel_min_probability);
  octree_->setClampingThresMax(config.voxel_max_probability);
  cell_hit_ = LogOdds(config.cell_hit_probability);
  cell_miss_ = LogOdds(config.cell_miss_probability);
  cell_min_ = LogOdds(config.cell_min_probability);
  cell_max_ = LogOdds(config.cell_max_probability);
  lethal_log_odds_ = LogOdds(config.obstacle_probability);
  const double s = config.cell_size_m;
  // Any point of a cell within ground_radius of any point of the centre cell.
  scratch_->ground_disc = DiscOffsets(config.ground_radius_m + std::sqrt(2.0) * s, s);
  scratch_->fit_disc = DiscOffsets(config.plane_fit_radius_m, s);
  for (const CellIndex& d : scratch_->fit_disc) {
    const Eigen::Vector3d row(1.0, d.x() * s, d.y() * s);
    const Eigen::Matrix3d n = row * row.transpose();
    scratch_->fit_upper.push_back({n(0, 0), n(0, 1), n(0, 2), n(1, 1), n(1, 2), n(2, 2)});
  }
  scratch_->merge_disc = DiscOffsets(config.merge_distance_m, s);
  const int r = ReachCells(config.inflation_radius_m, s);
  scratch_->inflation_cells = r;
  scratch_->inflation_table.assign(static_cast<std::size_t>(2 * r + 1) * (2 * r + 1), 0);
  for (const CellIndex& d : DiscOffsets(config.inflation_radius_m, s)) {
    if (d.isZero()) continue;
    const double distance = std::hypot(d.x(), d.y()) * s;
    scratch_->inflation_table[static_cast<std::size_t>(d.y() + r) * (2 * r + 1) + (d.x() + r)] =
        InflationCost(distance, config.robot_radius_m, config.cost_scaling_factor);
  }
  pruned_at_ = grid_.min_index();
  PrepareScratch();
}

TerrainMap::TerrainMap(TerrainMap&&) noexcept = default;
TerrainMap& TerrainMap::operator=(TerrainMap&&) noexcept = default;
TerrainMap::~TerrainMap() = default;

Expected<TerrainMap> TerrainMap::Create(const MapConfig& config) {
  if (Status s = config.Validate(); !s) return s.error();
  return TerrainMap(config);
}

void TerrainMap::PrepareScratch() { scratch_->slots.assign(grid_.slot_count(), Scratch::Slot{}); }

namespace {

// Why a frame cannot be fused (parts disagree, bad pose or stamp), without the frame's name.
Status CheckFrameInputs(const od::RangeImage& image, const od::Detection& detection,
                        const od::Classification& classification,
                        const Eigen::Isometry3d& T_world_sensor, double stamp_s) {
  if (detection.width != image.width() || detection.height != image.height() ||
      detection.labels.size() != static_cast<std::size_t>(image.size())) {
    return Error{"the detection is " + std::to_string(detection.width) + "x" +
                 std::to_string(detection.height) + " but the range image is " +
                 std::to_string(image.width()) + "x" + std::to_string(image.height())};
  }
  if (classification.verdicts.size() != detection.segments.size()) {
    return Error{"the classification has " + std::to_string(classification.verdicts.size()) +
                 " verdicts for " + std::to_string(detection.segments.size()) + " segments"};
  }
  const int segment_count = static_cast<int>(detection.segments.size());
  for (const std::int32_t label : detection.labels) {
    if (label < 0 || label > segment_count) {
      return Error{"segment label " + std::to_string(label) + " out of range 0.." +
                   std::to_string(segment_count)};
    }
  }
  if (!T_world_sensor.matrix().allFinite()) return Error{"the pose is not finite"};
  if (T_world_sensor.translation().cwiseAbs().maxCoeff() > kMaxWorldCoordinateM) {
    return Error{"the pose lies more than 1000 km from the map's origin (" +
                 std::to_string(T_world_sensor.translation().norm()) + " m)"};
  }
  if (!std::isfinite(stamp_s)) return Error{"the time stamp is not finite"};
  return Status::Ok();
}

// Adds a ground return at height z to the cell's elevation (count, mean, extremes).
void AddGroundElevation(Cell& cell, float z) {
  ++cell.ground_points;
  if (cell.ground_points == 1) {
    cell.elevation_mean_m = cell.elevation_min_m = cell.elevation_max_m = z;
  } else {
    cell.elevation_mean_m += (z - cell.elevation_mean_m) / cell.ground_points;
    cell.elevation_min_m = std::min(cell.elevation_min_m, z);
    cell.elevation_max_m = std::max(cell.elevation_max_m, z);
  }
}

// The free voxels of the rays from `sensor` to `ends`, into `free_keys` (0 threads: every core).
void CastFreeRays(const TerrainOcTree& tree, const octomap::point3d& sensor,
                  const std::vector<octomap::OcTreeKey>& ends, int wanted_threads,
                  internal::KeyBricks& free_keys, std::vector<internal::KeyBricks>& worker_keys,
                  std::vector<internal::KeyBitBox>& worker_boxes) {
  // Every ray lies in the box of its two ends: the sets index their bricks in the box of
  // them all.
  octomap::OcTreeKey lo, hi;
  if (!tree.coordToKeyChecked(sensor, lo)) {
    free_keys.Clear();  // outside the tree: OctoMap casts no ray either
    return;
  }
  hi = lo;
  for (const octomap::OcTreeKey& end : ends) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], end[i]);
      hi[i] = std::max(hi[i], end[i]);
    }
  }
  // One ray per end voxel, in blocks of 1,024 rays to each worker, each worker into its own
  // box of bits (four or eight rays walked in turn, each key one or) or, where the box would be too
  // large, its own set; the boxes then go into free_keys. The union does not depend on the
  // split.
  constexpr std::size_t kBlock = 1024;
  const int most = od::ThreadCount(wanted_threads);
  free_keys.Clear(lo, hi);
  if (static_cast<int>(worker_boxes.size()) < most) worker_boxes.resize(most);
  if (worker_boxes[0].Reset(lo, hi)) {
    // The caller is worker 0; a helper resets its box when it joins (the same box).
    internal::KeyLayout layout;
    worker_boxes[0].Layout(layout.lo, layout.stride);
    std::vector<char> worked(static_cast<std::size_t>(most), 0);
    worked[0] = 1;
    od::ParallelFor(
        static_cast<int>((ends.size() + kBlock - 1) / kBlock), most,
        [&](int worker, int block) {
          internal::KeyBitBox& box = worker_boxes[worker];
          if (!worked[worker]) {
            box.Reset(lo, hi);
            worked[worker] = 1;
          }
          const std::size_t begin = static_cast<std::size_t>(block) * kBlock;
          internal::ForEachRayKeyInTurn(tree, sensor, ends.data() + begin,
                                        ends.data() + std::min(ends.size(), begin + kBlock), layout,
                                        [&box](std::size_t, std::int64_t key) { box.Set(key); });
        },
        1);
    for (int t = 0; t < most; ++t) {
      if (worked[t]) worker_boxes[t].MoveInto(free_keys);
    }
    return;
  }
  if (static_cast<int>(worker_keys.size()) < most - 1) worker_keys.resize(most - 1);
  for (int t = 0; t < most - 1; ++t) worker_keys[t].Clear(lo, hi);
  const int used = od::ParallelFor(
      static_cast<int>(ends.size()), most,
      [&](int worker, int e) {
        internal::KeyBricks::Inserter insert(worker == 0 ? free_keys : worker_keys[worker - 1]);
        internal::ForEachRayKey(tree, sensor, tree.keyToCoord(ends[e]), insert);
      },
      static_cast<int>(kBlock));
  for (int t = 1; t < used; ++t) free_keys.Merge(worker_keys[t - 1]);
}

}  // namespace

Expected<FrameSummary> TerrainMap::Integrate(const od::RangeImage& image,
                                             const od::Detection& detection,
                                             const od::Classification& classification,
                                             const Eigen::Isometry3d& T_world_sensor,
                                             double stamp_s, std::int64_t frame_id) {
  const std::string where = "frame " + std::to_string(frame_id) + ": ";
  if (Status s = CheckFrameInputs(image, detection, classification, T_world_sensor, stamp_s); !s) {
    return Error{where + s.message()};
  }

  FrameSummary summary;
  summary.frame_id = frame_id;
  summary.stamp_s = stamp_s;
  const std::int64_t stamp = frames_ + 1;  // counted once the frame is accepted
  const Eigen::Vector3d origin = T_world_sensor.translation();
  auto start = std::chrono::steady_clock::now();

  summary.window_moved = MoveWindow(origin);
  if (Status s = PlaceReturns(image, T_world_sensor, summary); !s) {
    return Error{where + s.message()};
  }
  frames_ = stamp;
  std::vector<FrameSegment> segments = ClassifyReturns(detection, classification, stamp, summary);
  summary.classify_s = util::SecondsSince(start);
  start = std::chrono::steady_clock::now();

  UpdateOctree(origin, stamp, summary);
  summary.octree_s = util::SecondsSince(start);
  start = std::chrono::steady_clock::now();

  UpdateGridEvidence(summary);
  summary.grid_s = util::SecondsSince(start);
  start = std::chrono::steady_clock::now();

  UpdatePersistentObstacles(segments, stamp_s, frame_id, summary);
  summary.obstacles_s = util::SecondsSince(start);
  return summary;
}

// The window follows the sensor (rolling grids only), the octree pruned to it; true if it moved.
bool TerrainMap::MoveWindow(const Eigen::Vector3d& origin) {
  if (!grid_.rolling()) return false;
  const bool window_moved = grid_.MoveTo(origin.head<2>());
  const CellIndex moved = (grid_.min_index() - pruned_at_).cwiseAbs();
  if (moved.maxCoeff() >= std::max(1, grid_.extent().x() / 16)) PruneOctreeToWindow();
  return window_moved;
}

// Returns into the world, far ones cut at max_range; an unbounded grid grows to every ray's cells.
Status TerrainMap::PlaceReturns(const od::RangeImage& image,
                                const Eigen::Isometry3d& T_world_sensor, FrameSummary& summary) {
  Scratch& sc = *scratch_;
  const int n = image.size();
  sc.point_class.resize(n);
  sc.world.resize(n);
  sc.point_cell.resize(n);
  CellIndex lo = grid_.IndexOf(T_world_sensor.translation().head<2>());
  CellIndex hi = lo;
  int valid = 0;
  internal::PlacePixels(image.x().data(), image.y().data(), image.z().data(),
                        image.valid_mask().data(), n, T_world_sensor, config_.max_range_m, grid_,
                        od::internal::VectorLanes(), sc.point_class.data(), sc.world.data(),
                        sc.point_cell.data(), valid, lo, hi);
  summary.valid_points += valid;
  if (!grid_.rolling() && summary.valid_points > 0) {
    CellIndex new_lo = lo, new_hi = hi;
    if (grid_.extent().x() > 0) {
      new_lo = new_lo.cwiseMin(grid_.min_index());
      new_hi = new_hi.cwiseMax(grid_.min_index() + grid_.extent() - CellIndex::Ones());
    }
    const double cells = (new_hi.x() - new_lo.x() + 1.0) * (new_hi.y() - new_lo.y() + 1.0);
    if (cells > static_cast<double>(kMaxGridCells)) {
      return Error{"the unbounded grid would grow to " + std::to_string(cells) +
                   " cells, more than kMaxGridCells (" + std::to_string(kMaxGridCells) +
                   "): use a rolling window (map.window_size) or larger cells"};
    }
    if (grid_.Reserve(lo, hi)) PrepareScratch();
  }
  // Each return's slot, from a table of the frame's cells (Slot divides twice per call),
  // which also covers the cells within the ground disc of any of them.
  int reach = 0;
  for (const CellIndex& d : sc.ground_disc) reach = std::max(reach, d.cwiseAbs().maxCoeff());
  sc.frame_slots.Reset(grid_, Grow(lo, -reach), Grow(hi, reach));
  sc.point_slot.assign(n, -1);
  CellIndex in_lo = CellIndex::Constant(std::numeric_limits<int>::max());
  CellIndex in_hi = CellIndex::Constant(std::numeric_limits<int>::min());
  for (int i = 0; i < n; ++i) {
    if (sc.point_class[i] == kNone) continue;
    sc.point_slot[i] = sc.frame_slots(sc.point_cell[i]);
    if (sc.point_class[i] == kGround && sc.point_slot[i] >= 0) {
      in_lo = in_lo.cwiseMin(sc.point_cell[i]);
      in_hi = in_hi.cwiseMax(sc.point_cell[i]);
    }
  }
  // The dense box, afresh.
  if (in_lo.x() > in_hi.x()) in_lo = in_hi = lo;  // no return in range: any box
  sc.frame_lo = Grow(in_lo, -reach);
  sc.frame_width = in_hi.x() - in_lo.x() + 1 + 2 * reach;
  const std::size_t frame_cells = static_cast<std::size_t>(sc.frame_width) *
                                  static_cast<std::size_t>(in_hi.y() - in_lo.y() + 1 + 2 * reach);
  sc.low_x.resize(frame_cells);
  sc.low_y.resize(frame_cells);
  sc.low_z.assign(frame_cells, kInfinity);
  sc.around_begin.assign(frame_cells, -1);
  sc.around_end.resize(frame_cells);
  sc.lowest_around.resize(frame_cells);
  sc.ground_disc_at.clear();
  for (const CellIndex& d : sc.ground_disc) {
    sc.ground_disc_at.push_back(static_cast<std::ptrdiff_t>(d.y()) * sc.frame_width + d.x());
  }
  return Status::Ok();
}

// The lowest in-range return of each grid cell, in the frame's box (the cell's slot stamped,
// listed in `touched`).
void TerrainMap::FindLowestReturns(std::int64_t stamp, FrameSummary& summary) {
  Scratch& sc = *scratch_;
  sc.touched.clear();
  const int n = static_cast<int>(sc.point_class.size());
  for (int i = 0; i < n; ++i) {
    if (sc.point_class[i] != kGround || sc.point_slot[i] < 0) continue;
    ++summary.points_in_range;
    sc.Stamp(static_cast<std::size_t>(sc.point_slot[i]), sc.point_cell[i], stamp);
    const std::size_t at = sc.FrameCell(sc.point_cell[i]);
    if (sc.world[i].z() < sc.low_z[at]) {
      sc.low_x[at] = static_cast<float>(sc.world[i].x());
      sc.low_y[at] = static_cast<float>(sc.world[i].y());
      sc.low_z[at] = static_cast<float>(sc.world[i].z());
    }
  }
}

// How far a point stands above the ground around it: the most, over the lowest returns q
// of the cells within reach, of p.z - q.z - tan(ground_max_slope) |p - q|_xy (rise is that
// tan, reach2 the squared ground_radius). Returns that and the plain height above the lowest
// return within reach.
std::pair<float, float> TerrainMap::HeightAboveGround(const Eigen::Vector3d& p, const CellIndex& c,
                                                      float rise, float reach2) {
  Scratch& sc = *scratch_;
  const Eigen::Vector3f pf = p.cast<float>();
  float height = -kInfinity;
  float plain = -kInfinity;
  // The lowest returns of the cells within reach, gathered once per cell and frame (the
  // points of a segment crowd into few cells); their lowest settles most points, the foot.
  // Each neighbour's is written, and kept (counted) only when there is one: no branch.
  const std::size_t at = sc.FrameCell(c);
  if (sc.around_begin[at] < 0) {
    const std::size_t begin = sc.around_x.size();
    std::size_t end = begin;
    const std::size_t most = begin + sc.ground_disc_at.size();
    sc.around_x.resize(most);
    sc.around_y.resize(most);
    sc.around_z.resize(most);
    float lowest = kInfinity;
    for (const std::ptrdiff_t d : sc.ground_disc_at) {
      const std::size_t o = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(at) + d);
      const float z = sc.low_z[o];
      sc.around_x[end] = sc.low_x[o];
      sc.around_y[end] = sc.low_y[o];
      sc.around_z[end] = z;
      end += z < kInfinity;
      lowest = std::min(lowest, z);
    }
    sc.around_x.resize(end);
    sc.around_y.resize(end);
    sc.around_z.resize(end);
    sc.around_begin[at] = static_cast<std::int32_t>(begin);
    sc.around_end[at] = static_cast<std::int32_t>(end);
    sc.lowest_around[at] = lowest;
  }
  const float lowest_around = sc.lowest_around[at];
  if (pf.z() - lowest_around < config_.obstacle_min_height_m) {
    return std::make_pair(pf.z() - lowest_around, pf.z() - lowest_around);
  }
  const float* const qx = sc.around_x.data();
  const float* const qy = sc.around_y.data();
  const float* const qz = sc.around_z.data();
  int k = sc.around_begin[at];
  const int around_end = sc.around_end[at];
#if defined(__SSE2__)
  // Four at a time, in the scalar loop's float operations. The four lanes' maxima are taken in
  // another order than one by one, which could differ only in the sign of a zero maximum (the
  // two compare equal).
  {
    const __m128 px = _mm_set1_ps(pf.x()), py = _mm_set1_ps(pf.y()), pz = _mm_set1_ps(pf.z());
    const __m128 vrise = _mm_set1_ps(rise), vreach2 = _mm_set1_ps(reach2);
    const __m128 none = _mm_set1_ps(-kInfinity);
    __m128 heights = none, plains = none;
    for (; k + 4 <= around_end; k += 4) {
      const __m128 dx = _mm_sub_ps(px, _mm_loadu_ps(qx + k));
      const __m128 dy = _mm_sub_ps(py, _mm_loadu_ps(qy + k));
      const __m128 dxy2 = _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy));
      const __m128 within = _mm_cmpngt_ps(dxy2, vreach2);  // as !(dxy2 > reach2)
      const __m128 dz = _mm_sub_ps(pz, _mm_loadu_ps(qz + k));
      const __m128 h = _mm_sub_ps(dz, _mm_mul_ps(vrise, _mm_sqrt_ps(dxy2)));
      // max(candidate, so far): the earlier value where they are equal, as std::max keeps it.
      heights = _mm_max_ps(_mm_or_ps(_mm_and_ps(within, h), _mm_andnot_ps(within, none)), heights);
      plains = _mm_max_ps(_mm_or_ps(_mm_and_ps(within, dz), _mm_andnot_ps(within, none)), plains);
    }
    const auto most = [](__m128 v) {
      v = _mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2)));
      return _mm_cvtss_f32(_mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1))));
    };
    height = most(heights);
    plain = most(plains);
  }
#endif
  for (; k < around_end; ++k) {
    const float dx = pf.x() - qx[k], dy = pf.y() - qy[k];
    const float dxy2 = dx * dx + dy * dy;
    if (dxy2 > reach2) continue;
    height = std::max(height, pf.z() - qz[k] - rise * std::sqrt(dxy2));
    plain = std::max(plain, pf.z() - qz[k]);
  }
  return std::make_pair(height, plain);
}

// The lowest return per cell, then each return's class into its cell; returns segments by label.
std::vector<TerrainMap::FrameSegment> TerrainMap::ClassifyReturns(
    const od::Detection& detection, const od::Classification& classification, std::int64_t stamp,
    FrameSummary& summary) {
  FindLowestReturns(stamp, summary);
  Scratch& sc = *scratch_;
  sc.around_x.clear();
  sc.around_y.clear();
  sc.around_z.clear();
  const float rise = static_cast<float>(std::tan(config_.ground_max_slope_rad));
  const float reach2 = static_cast<float>(config_.ground_radius_m * config_.ground_radius_m);
  std::vector<FrameSegment> segments(detection.segments.size() + 1);
  const int n = static_cast<int>(sc.point_class.size());
  for (int i = 0; i < n; ++i) {
    if (sc.point_class[i] != kGround || sc.point_slot[i] < 0) continue;
    const Eigen::Vector3d& p = sc.world[i];
    const CellIndex& c = sc.point_cell[i];
    const std::size_t grid_slot = static_cast<std::size_t>(sc.point_slot[i]);
    const int label = detection.labels[i];
    Cell& cell = grid_.AtSlot(grid_slot);
    Scratch::Slot& slot = sc.slots[grid_slot];
    const float z = static_cast<float>(p.z());
    const bool kept =
        label > 0 && classification.verdicts[label - 1].cls == od::SegmentClass::kKept;
    const auto [height, plain_height] =
        kept ? HeightAboveGround(p, c, rise, reach2) : std::make_pair(0.0f, 0.0f);
    if (kept && height >= config_.obstacle_min_height_m) {
      sc.point_class[i] = kObstacle;
      ++summary.obstacle_points;
      ++slot.obstacle;
      ++cell.obstacle_points;
      cell.obstacle_top_m = std::isnan(cell.obstacle_top_m) ? z : std::max(cell.obstacle_top_m, z);
      segments[label].Add(label, c, p, static_cast<double>(plain_height));
    } else {
      ++summary.ground_points;
      ++slot.ground;
      AddGroundElevation(cell, z);
    }
    cell.observed = true;
  }
  return segments;
}

// The voxels where this frame's rays end, afresh (in range, of obstacles, far; all: ray_ends).
void TerrainMap::CollectRayEnds() {
  Scratch& sc = *scratch_;
  const TerrainOcTree& tree = *octree_;
  sc.endpoints.Clear();
  sc.obstacle_endpoints.Clear();
  sc.far_ends.Clear();
  const int n = static_cast<int>(sc.point_class.size());
  for (int i = 0; i < n; ++i) {
    const std::uint8_t cls = sc.point_class[i];
    if (cls == kNone) continue;
    octomap::OcTreeKey key;
    const Eigen::Vector3d& p = sc.world[i];
    if (!tree.coordToKeyChecked(p.x(), p.y(), p.z(), key)) continue;  // beyond the tree
    if (cls == kFar) {
      sc.far_ends.Insert(key);
    } else {
      sc.endpoints.Insert(key);
      if (cls == kObstacle) sc.obstacle_endpoints.Insert(key);
    }
  }
  sc.ray_ends.clear();
  const auto collect = [&](const octomap::OcTreeKey& end, bool) { sc.ray_ends.push_back(end); };
  sc.endpoints.ForEach(collect);
  sc.far_ends.ForEach(collect);
}

// OctoMap's discretised update, one ray per endpoint voxel: free space, then the endpoints.
void TerrainMap::UpdateOctree(const Eigen::Vector3d& origin, std::int64_t stamp,
                              FrameSummary& summary) {
  Scratch& sc = *scratch_;
  TerrainOcTree& tree = *octree_;
  const double s = config_.cell_size_m;
  const Eigen::Vector2d window_min = grid_.min_index().cast<double>() * s;
  const Eigen::Vector2d window_max = (grid_.min_index() + grid_.extent()).cast<double>() * s;
  const auto in_window = [&](const octomap::OcTreeKey& key) {
    if (!grid_.rolling()) return true;
    const octomap::point3d c = tree.keyToCoord(key);
    return c.x() >= window_min.x() && c.x() < window_max.x() && c.y() >= window_min.y() &&
           c.y() < window_max.y();
  };
  CollectRayEnds();
  const octomap::point3d sensor(static_cast<float>(origin.x()), static_cast<float>(origin.y()),
                                static_cast<float>(origin.z()));
  CastFreeRays(tree, sensor, sc.ray_ends, config_.threads, sc.free_keys, sc.worker_keys,
               sc.ray_boxes);
  // Endpoints win: their voxels are not updated as free. A brick at a time, the free voxels
  // and the endpoints together: the tree is walked to each brick once, and the bricks'
  // subtrees are updated on map.threads threads.
  std::vector<TerrainOcTree::BrickUpdate>& bricks = sc.bricks;
  bricks.clear();
  sc.free_keys.ForEachBrickOfEitherInMortonOrder(
      sc.endpoints, sc.brick_order,
      [&](std::uint64_t code, const internal::KeyBricks::Brick* free,
          const internal::KeyBricks::Brick* ends) {
        TerrainOcTree::BrickUpdate& update = bricks.emplace_back();
        const octomap::OcTreeKey base = internal::KeyBricks::BaseKeyOf(code);
        update.base = base;
        const internal::KeyBricks::Brick* obstacles =
            ends != nullptr ? sc.obstacle_endpoints.BrickOf(code) : nullptr;
        for (int w = 0; w < 8; ++w) {
          const std::uint64_t hit = ends != nullptr ? ends->bits[w] : 0;
          update.free[w] = (free != nullptr ? free->bits[w] : 0) & ~hit;
          update.hit[w] = hit;
          update.obstacle[w] = obstacles != nullptr ? obstacles->bits[w] & hit : 0;
        }
        // The window is an interval in x and y: a brick whose corner voxels lie in it does.
        const octomap::OcTreeKey far(static_cast<octomap::key_type>(base[0] + 7),
                                     static_cast<octomap::key_type>(base[1] + 7), base[2]);
        if (!in_window(base) || !in_window(far)) {
          for (unsigned b = 0; b < 512; ++b) {
            if (!in_window(internal::KeyBricks::KeyOf(base, b))) {
              const std::uint64_t keep = ~(std::uint64_t{1} << (b & 63));
              update.free[b >> 6] &= keep;
              update.hit[b >> 6] &= keep;
            }
          }
        }
        for (const std::uint64_t w : update.hit) {
          summary.voxels_occupied += __builtin_popcountll(w);
        }
      });
  tree.UpdateBricks(bricks, config_.threads);
  for (const TerrainOcTree::BrickUpdate& brick : bricks) {
    summary.voxels_free += brick.changed;
    for (unsigned w = 0; w < 8; ++w) {
      for (std::uint64_t word = brick.was_obstacle[w]; word != 0; word &= word - 1) {
        // A ray went through where an obstacle was: evidence against the cell below it.
        const unsigned b = w * 64 + static_cast<unsigned>(__builtin_ctzll(word));
        const octomap::point3d c = tree.keyToCoord(internal::KeyBricks::KeyOf(brick.base, b));
        const CellIndex cell = grid_.IndexOf({c.x(), c.y()});
        if (grid_.Contains(cell)) sc.Stamp(grid_, cell, stamp).seen_through = true;
      }
    }
  }
  // Inner nodes and pruning cost a walk over the whole tree: done every few frames, and
  // whenever the tree is looked at (octree()); the leaves are always current.
  octree_stale_ = true;
  if (stamp % kOctreeFlushFrames == 0) tree.PruneSaturatedFree();
}

// Obstacle evidence, one update per touched cell, then terrain and cost around what changed.
void TerrainMap::UpdateGridEvidence(FrameSummary& summary) {
  Scratch& sc = *scratch_;
  const double s = config_.cell_size_m;
  CellIndex dirty_lo = CellIndex::Constant(std::numeric_limits<int>::max());
  CellIndex dirty_hi = CellIndex::Constant(std::numeric_limits<int>::min());
  for (const CellIndex& c : sc.touched) {
    const Scratch::Slot& slot = sc.slots[grid_.Slot(c)];
    Cell& cell = grid_.At(c);
    if (slot.obstacle > 0) {
      cell.obstacle_log_odds = std::min(cell.obstacle_log_odds + cell_hit_, cell_max_);
      ++cell.hits;
      ++summary.cells_hit;
    } else if (slot.ground > 0 || slot.seen_through) {
      cell.obstacle_log_odds = std::max(cell.obstacle_log_odds + cell_miss_, cell_min_);
      ++cell.misses;
      ++summary.cells_missed;
    }
    cell.lethal = cell.obstacle_log_odds > lethal_log_odds_;
    dirty_lo = dirty_lo.cwiseMin(c);
    dirty_hi = dirty_hi.cwiseMax(c);
    if (cell.observed) {
      if (!has_observed_) {
        observed_min_ = observed_max_ = c;
        has_observed_ = true;
      }
      observed_min_ = observed_min_.cwiseMin(c);
      observed_max_ = observed_max_.cwiseMax(c);
    }
  }
  if (!sc.touched.empty()) {
    const int fit = ReachCells(config_.plane_fit_radius_m, s);
    const CellIndex terrain_lo = Grow(dirty_lo, -fit);
    const CellIndex terrain_hi = Grow(dirty_hi, fit);
    UpdateTerrain(terrain_lo, terrain_hi);
    if (!summary.window_moved) {
      UpdateCosts(Grow(terrain_lo, -sc.inflation_cells), Grow(terrain_hi, sc.inflation_cells));
    }
  }
  if (summary.window_moved) {
    // Inflation from cells that left the window is gone everywhere near its edges.
    UpdateCosts(grid_.min_index(), grid_.min_index() + grid_.extent() - CellIndex::Ones());
  }
}

// The kept segments join or found persistent obstacles; those with no lethal cell left retire.
void TerrainMap::UpdatePersistentObstacles(std::vector<FrameSegment>& segments, double stamp_s,
                                           std::int64_t frame_id, FrameSummary& summary) {
  std::vector<FrameSegment> kept;
  for (FrameSegment& seg : segments) {
    if (seg.count == 0) continue;
    std::sort(seg.cells.begin(), seg.cells.end(), [](const CellIndex& a, const CellIndex& b) {
      return a.y() != b.y() ? a.y() < b.y() : a.x() < b.x();
    });
    seg.cells.erase(std::unique(seg.cells.begin(), seg.cells.end()), seg.cells.end());
    kept.push_back(std::move(seg));
  }
  summary.kept_segments = static_cast<int>(kept.size());
  FuseObstacles(kept, stamp_s, frame_id, summary);
  RetireObstacles(summary);
  for (const Obstacle& o : obstacles_) summary.lethal_cells += static_cast<int>(o.cells.size());
}

void TerrainMap::UpdateTerrain(const CellIndex& lo, const CellIndex& hi) {
  const CellIndex from = lo.cwiseMax(grid_.min_index());
  const CellIndex to = hi.cwiseMin(grid_.min_index() + grid_.extent() - CellIndex::Ones());
  if (from.x() > to.x() || from.y() > to.y()) return;
  Scratch& sc = *scratch_;
  const double s = config_.cell_size_m;
  const int fit = ReachCells(config_.plane_fit_radius_m, s);
  // The elevations of the box and the cells within the fit's reach of it, row by row, with a
  // weight 1, or 0 (and an elevation 0) where a cell has none or lies outside the extent: each
  // fit reads its neighbours here, in a few cache lines, rather than cell by cell through the
  // slots.
  const CellIndex box_lo = Grow(from, -fit), box_hi = Grow(to, fit);
  const int box_width = box_hi.x() - box_lo.x() + 1, box_height = box_hi.y() - box_lo.y() + 1;
  TerrainGrid::SlotTable& slots = sc.slot_table;
  slots.Reset(grid_, box_lo, box_hi);
  sc.fit_elevations.resize(static_cast<std::size_t>(box_width) * box_height);
  sc.fit_weights.resize(sc.fit_elevations.size());
  for (int j = 0; j < box_height; ++j) {
    const std::size_t row = static_cast<std::size_t>(j) * box_width;
    for (int i = 0; i < box_width; ++i) {
      const std::ptrdiff_t slot = slots(box_lo + CellIndex(i, j));
      const Cell* const cell = slot < 0 ? nullptr : &grid_.AtSlot(static_cast<std::size_t>(slot));
      const bool there = cell != nullptr && cell->has_elevation();
      sc.fit_elevations[row + i] = there ? static_cast<double>(cell->elevation_mean_m) : 0.0;
      sc.fit_weights[row + i] = there ? 1.0 : 0.0;
    }
  }
  sc.fit_offsets.clear();
  for (const CellIndex& d : sc.fit_disc) {
    sc.fit_offsets.push_back(static_cast<std::ptrdiff_t>(d.y()) * box_width + d.x());
  }
  const std::size_t disc_size = sc.fit_disc.size();
  // A cell's slope, roughness and terrain cost from its plane, its sum of squared residuals and
  // its neighbours with an elevation.
  const auto finish = [&](Cell& cell, const Eigen::Vector3d& plane, double residual2,
                          double count) {
    // The gradient's norm without std::hypot's care for overflow (a gradient is far from
    // it), which took a third of the fits' time.
    const double gradient = std::sqrt(plane.y() * plane.y() + plane.z() * plane.z());
    cell.slope_rad = static_cast<float>(std::atan(gradient));
    cell.roughness_m = static_cast<float>(std::sqrt(residual2 / count));
    const double level = std::max(cell.slope_rad / config_.slope_cost_max_rad,
                                  cell.roughness_m / config_.roughness_cost_max_m);
    cell.terrain_cost =
        static_cast<Cost>(std::lround(kMaxTerrainCost * std::clamp(level, 0.0, 1.0)));
  };
  [[maybe_unused]] const int lanes = od::internal::VectorLanes();
  // Each cell's fit writes the cell alone and reads only the elevations above: rows go to
  // map.threads threads.
  const auto fit_row = [&](int k) {
    const int j = from.y() + k;
    const std::size_t first = static_cast<std::size_t>(k + fit) * box_width + fit;
    const double* const elevations = sc.fit_elevations.data() + first;
    const double* const weights = sc.fit_weights.data() + first;
    const auto cell_at = [&](int i) -> Cell& {
      Cell& cell = grid_.AtSlot(static_cast<std::size_t>(slots({i, j})));
      cell.slope_rad = cell.roughness_m = kNaN;
      cell.terrain_cost = kFreeCost;
      return cell;
    };
    int i = from.x();
#if defined(CAIRN_OD_WIDE_VECTORS)
    // Four cells at a time, each as one alone.
    for (; lanes >= 8 && i + 3 <= to.x(); i += 4) {
      const double* const z = elevations + (i - from.x());
      const double* const w = weights + (i - from.x());
      double rhs[3][4], n[6][4], plane[3][4] = {}, residual2[4];
      FitSumsAvx2(z, w, sc.fit_offsets.data(), sc.fit_upper.data(), disc_size, rhs, n);
      Cell* fitted[4] = {};  // the lanes' cells that have a plane
      for (int l = 0; l < 4; ++l) {
        Cell& cell = cell_at(i + l);
        const double sums[6] = {n[0][l], n[1][l], n[2][l], n[3][l], n[4][l], n[5][l]};
        Eigen::Vector3d p;
        if (!cell.has_elevation() ||
            !SolvePlane(sums, Eigen::Vector3d(rhs[0][l], rhs[1][l], rhs[2][l]), s, p)) {
          continue;
        }
        fitted[l] = &cell;
        for (int e = 0; e < 3; ++e) plane[e][l] = p(e);
      }
      if (!(fitted[0] || fitted[1] || fitted[2] || fitted[3])) continue;
      FitResidualsAvx2(z, w, sc.fit_offsets.data(), sc.fit_disc.data(), disc_size, s, plane,
                       residual2);
      for (int l = 0; l < 4; ++l) {
        if (fitted[l] == nullptr) continue;
        finish(*fitted[l], Eigen::Vector3d(plane[0][l], plane[1][l], plane[2][l]), residual2[l],
               n[0][l]);
      }
    }
#endif
    for (; i <= to.x(); ++i) {
      Cell& cell = cell_at(i);
      if (!cell.has_elevation()) continue;
      // Least squares z = a + b dx + c dy over the neighbours with an elevation, in metres
      // from this cell's centre (well conditioned whatever the world coordinates). Every
      // neighbour is added, weighted 1 or 0, without a branch to mispredict at the edges of
      // what was seen: a weight 0 and an elevation 0 add nothing.
      const double* const z = elevations + (i - from.x());
      const double* const w = weights + (i - from.x());
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      double n[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
      for (std::size_t o = 0; o < disc_size; ++o) {
        const std::ptrdiff_t at = sc.fit_offsets[o];
        for (int c = 0; c < 3; ++c) rhs(c) += sc.fit_upper[o][c] * z[at];
        for (int e = 0; e < 6; ++e) n[e] += w[at] * sc.fit_upper[o][e];
      }
      Eigen::Vector3d plane;
      if (!SolvePlane(n, rhs, s, plane)) continue;
      double residual2 = 0.0;
      for (std::size_t o = 0; o < disc_size; ++o) {
        const std::ptrdiff_t at = sc.fit_offsets[o];
        const CellIndex& d = sc.fit_disc[o];
        const double r = z[at] - (plane.x() + plane.y() * d.x() * s + plane.z() * d.y() * s);
        residual2 += w[at] * (r * r);
      }
      finish(cell, plane, residual2, n[0]);
    }
  };
  od::ParallelFor(to.y() - from.y() + 1, config_.threads, fit_row, 8);
}

void TerrainMap::UpdateCosts(const CellIndex& lo, const CellIndex& hi) {
  const CellIndex grid_lo = grid_.min_index();
  const CellIndex grid_hi = grid_.min_index() + grid_.extent() - CellIndex::Ones();
  const CellIndex from = lo.cwiseMax(grid_lo);
  const CellIndex to = hi.cwiseMin(grid_hi);
  if (from.x() > to.x() || from.y() > to.y()) return;
  Scratch& sc = *scratch_;
  const int r = sc.inflation_cells, side = 2 * r + 1;
  const CellIndex src_from = Grow(from, -r).cwiseMax(grid_lo);
  const CellIndex src_to = Grow(to, r).cwiseMin(grid_hi);
  TerrainGrid::SlotTable& slots = sc.slot_table;
  slots.Reset(grid_, src_from, src_to);  // every cell in the extent
  // Per cell of the box, the most inflation of a lethal cell near enough to reach it (every
  // one in the box grown by r): each raises the cells around it, row by row. nav2's rule
  // (CombineInflation) keeps the larger cost, or leaves an unknown cell unknown below the
  // inscribed cost, so combining the most at once is combining each in turn.
  const int width = to.x() - from.x() + 1;
  sc.inflation_box.assign(static_cast<std::size_t>(width) * (to.y() - from.y() + 1), 0);
  for (int j = src_from.y(); j <= src_to.y(); ++j) {
    for (int i = src_from.x(); i <= src_to.x(); ++i) {
      if (!grid_.AtSlot(static_cast<std::size_t>(slots({i, j}))).lethal) continue;
      const int x0 = std::max(i - r, from.x()), x1 = std::min(i + r, to.x());
      const int y0 = std::max(j - r, from.y()), y1 = std::min(j + r, to.y());
      for (int y = y0; y <= y1; ++y) {
        Cost* const target = sc.inflation_box.data() +
                             static_cast<std::size_t>(y - from.y()) * width + (x0 - from.x());
        const Cost* const cost =
            sc.inflation_table.data() + static_cast<std::size_t>(y - j + r) * side + (x0 - i + r);
        for (int x = 0; x <= x1 - x0; ++x) target[x] = std::max(target[x], cost[x]);
      }
    }
  }
  for (int j = from.y(); j <= to.y(); ++j) {
    const Cost* const inflation =
        sc.inflation_box.data() + static_cast<std::size_t>(j - from.y()) * width;
    for (int i = from.x(); i <= to.x(); ++i) {
      Cell& cell = grid_.AtSlot(static_cast<std::size_t>(slots({i, j})));
      const Cost own = cell.lethal      ? kLethalCost
                       : !cell.observed ? kUnknownCost
                                        : cell.terrain_cost;
      cell.cost = CombineInflation(own, inflation[i - from.x()]);
    }
  }
}

void TerrainMap::FuseObstacles(std::vector<FrameSegment>& segments, double stamp_s,
                               std::int64_t frame_id, FrameSummary& summary) {
  const auto find = [&](int id) {
    return std::lower_bound(obstacles_.begin(), obstacles_.end(), id,
                            [](const Obstacle& o, int value) { return o.id < value; });
  };
  for (FrameSegment& seg : segments) {
    std::vector<int> ids;
    for (const CellIndex& c : seg.cells) {
      for (const CellIndex& d : scratch_->merge_disc) {
        const Cell* cell = grid_.Find(c + d);
        if (cell != nullptr && cell->obstacle_id != 0) ids.push_back(cell->obstacle_id);
      }
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());

    int target_id = 0;
    if (ids.empty()) {
      Obstacle fresh;
      fresh.id = next_obstacle_id_++;
      fresh.bbox_min = seg.bbox_min;
      fresh.bbox_max = seg.bbox_max;
      fresh.first_seen_s = stamp_s;
      obstacles_.push_back(std::move(fresh));  // ids only grow: the vector stays sorted
      target_id = obstacles_.back().id;
      ++summary.obstacles_created;
    } else {
      target_id = ids.front();  // the oldest
      ++summary.obstacles_updated;
      for (std::size_t k = 1; k < ids.size(); ++k) {
        auto other = find(ids[k]);
        auto target = find(target_id);
        Obstacle& t = *target;
        const Obstacle& o = *other;
        const double total = static_cast<double>(t.point_count + o.point_count);
        if (total > 0) {
          t.centroid = (t.centroid * static_cast<double>(t.point_count) +
                        o.centroid * static_cast<double>(o.point_count)) /
                       total;
        }
        t.point_count += o.point_count;
        t.bbox_min = t.bbox_min.cwiseMin(o.bbox_min);
        t.bbox_max = t.bbox_max.cwiseMax(o.bbox_max);
        t.height_m = std::max(t.height_m, o.height_m);
        t.first_seen_s = std::min(t.first_seen_s, o.first_seen_s);
        t.last_seen_s = std::max(t.last_seen_s, o.last_seen_s);
        std::vector<std::int64_t> frames;
        std::merge(t.frames.begin(), t.frames.end(), o.frames.begin(), o.frames.end(),
                   std::back_inserter(frames));
        frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
        t.frames = std::move(frames);
        t.merged_ids.push_back(o.id);
        t.merged_ids.insert(t.merged_ids.end(), o.merged_ids.begin(), o.merged_ids.end());
        for (const CellIndex& c : o.cells) {
          if (Cell* cell = grid_.Find(c); cell != nullptr && cell->obstacle_id == o.id) {
            cell->obstacle_id = target_id;
            t.cells.push_back(c);
          }
        }
        obstacles_.erase(other);
        ++summary.obstacles_merged;
      }
    }
    Obstacle& t = *find(target_id);
    const double total = static_cast<double>(t.point_count + seg.count);
    t.centroid = (t.centroid * static_cast<double>(t.point_count) + seg.sum) / total;
    t.point_count += seg.count;
    t.bbox_min = t.bbox_min.cwiseMin(seg.bbox_min);
    t.bbox_max = t.bbox_max.cwiseMax(seg.bbox_max);
    t.height_m = std::max(t.height_m, seg.height_m);
    t.last_seen_s = std::max(t.last_seen_s, stamp_s);
    if (t.frames.empty() || t.frames.back() != frame_id) t.frames.push_back(frame_id);
    for (const CellIndex& c : seg.cells) {
      Cell& cell = grid_.At(c);
      if (cell.obstacle_id != target_id) {
        cell.obstacle_id = target_id;
        t.cells.push_back(c);
      }
    }
  }
}

void TerrainMap::RetireObstacles(FrameSummary& summary) {
  const double s = config_.cell_size_m;
  std::vector<Obstacle> live;
  live.reserve(obstacles_.size());
  for (Obstacle& o : obstacles_) {
    std::vector<CellIndex> cells;
    for (const CellIndex& c : o.cells) {
      Cell* cell = grid_.Find(c);
      if (cell == nullptr || cell->obstacle_id != o.id) continue;
      if (cell->lethal) {
        cells.push_back(c);
      } else {
        cell->obstacle_id = 0;  // cleared: no longer part of it
      }
    }
    std::sort(cells.begin(), cells.end(), [](const CellIndex& a, const CellIndex& b) {
      return a.y() != b.y() ? a.y() < b.y() : a.x() < b.x();
    });
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    if (cells.empty()) {
      ++summary.obstacles_retired;
      ++retired_total_;
      continue;
    }
    o.cells = std::move(cells);
    CellIndex lo = o.cells.front(), hi = o.cells.front();
    for (const CellIndex& c : o.cells) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
    o.footprint_min = lo.cast<double>() * s;
    o.footprint_max = (hi + CellIndex::Ones()).cast<double>() * s;
    o.footprint_area_m2 = static_cast<double>(o.cells.size()) * s * s;
    live.push_back(std::move(o));
  }
  obstacles_ = std::move(live);
}

void TerrainMap::FlushOctree() const {
  if (!octree_stale_) return;
  octree_->updateInnerOccupancy();
  octree_->prune();
  octree_stale_ = false;
}

const TerrainOcTree& TerrainMap::octree() const {
  FlushOctree();
  return *octree_;
}

void TerrainMap::PruneOctreeToWindow() {
  const double s = config_.cell_size_m;
  octree_->DeleteOutsideXY(grid_.min_index().cast<double>() * s,
                           (grid_.min_index() + grid_.extent()).cast<double>() * s);
  pruned_at_ = grid_.min_index();
}

Cost TerrainMap::CostAt(const Eigen::Vector2d& xy) const {
  const Cell* cell = grid_.Find(grid_.IndexOf(xy));
  return cell != nullptr ? cell->cost : kUnknownCost;
}

const Cell* TerrainMap::CellAt(const Eigen::Vector2d& xy) const {
  return grid_.Find(grid_.IndexOf(xy));
}

LineCost TerrainMap::CostAlongLine(const Eigen::Vector2d& a, const Eigen::Vector2d& b) const {
  LineCost out;
  out.max_cost = kFreeCost;
  const auto visit = [&](const CellIndex& c) {
    const Cell* cell = grid_.Find(c);
    const Cost cost = cell != nullptr ? cell->cost : kUnknownCost;
    out.cells.push_back(c);
    out.costs.push_back(cost);
    out.max_cost = std::max(out.max_cost, cost);
  };
  // Amanatides & Woo's traversal; where the line passes exactly through a corner, both cells
  // beside it are taken (a planner must not slip between two obstacles).
  const double s = config_.cell_size_m;
  CellIndex c = grid_.IndexOf(a);
  const CellIndex end = grid_.IndexOf(b);
  const Eigen::Vector2d d = b - a;
  const int step_x = d.x() > 0 ? 1 : (d.x() < 0 ? -1 : 0);
  const int step_y = d.y() > 0 ? 1 : (d.y() < 0 ? -1 : 0);
  const double inf = std::numeric_limits<double>::infinity();
  const auto first_crossing = [&](double p, double dp, int index, int step) {
    if (step == 0) return inf;
    const double boundary = (index + (step > 0 ? 1 : 0)) * s;
    return (boundary - p) / dp;
  };
  double t_x = first_crossing(a.x(), d.x(), c.x(), step_x);
  double t_y = first_crossing(a.y(), d.y(), c.y(), step_y);
  const double dt_x = step_x != 0 ? s / std::abs(d.x()) : inf;
  const double dt_y = step_y != 0 ? s / std::abs(d.y()) : inf;
  const int max_steps = (end - c).cwiseAbs().sum() + 1;
  visit(c);
  for (int k = 0; k < max_steps && c != end; ++k) {
    if (t_x < t_y) {
      c.x() += step_x;
      t_x += dt_x;
    } else if (t_y < t_x) {
      c.y() += step_y;
      t_y += dt_y;
    } else {
      visit({c.x() + step_x, c.y()});
      visit({c.x(), c.y() + step_y});
      c += CellIndex(step_x, step_y);
      t_x += dt_x;
      t_y += dt_y;
    }
    visit(c);
  }
  return out;
}

GridPatch TerrainMap::PatchAround(const Eigen::Vector2d& centre, double half_size_m) const {
  const double s = config_.cell_size_m;
  const int half = static_cast<int>(std::lround(std::max(0.0, half_size_m) / s));
  GridPatch patch;
  patch.min_index = grid_.IndexOf(centre) - CellIndex::Constant(half);
  patch.cell_size_m = s;
  patch.origin = patch.min_index.cast<double>() * s;
  const int side = 2 * half + 1;
  patch.cost.resize(side, side);
  patch.elevation_m.resize(side, side);
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      const Cell* cell = grid_.Find(patch.min_index + CellIndex(i, j));
      patch.cost(i, j) = cell != nullptr ? cell->cost : kUnknownCost;
      patch.elevation_m(i, j) =
          cell != nullptr && cell->has_elevation() ? cell->elevation_mean_m : kNaN;
    }
  }
  return patch;
}

std::optional<CellBox> TerrainMap::ObservedBounds() const {
  if (!has_observed_) return std::nullopt;
  CellBox box{observed_min_.cwiseMax(grid_.min_index()),
              observed_max_.cwiseMin(grid_.min_index() + grid_.extent() - CellIndex::Ones())};
  if (box.min.x() > box.max.x() || box.min.y() > box.max.y()) return std::nullopt;
  return box;
}

MapMemory TerrainMap::Memory() const {
  MapMemory m;
  m.grid_bytes = grid_.memory_bytes() + scratch_->slots.capacity() * sizeof(Scratch::Slot);
  FlushOctree();
  m.octree_bytes = octree_->memoryUsage();
  m.octree_leaves = octree_->getNumLeafNodes();
  m.obstacles = obstacles_.size();
  return m;
}

}  // namespace cairn::map
