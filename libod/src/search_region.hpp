// Internal: the image region onto which a point's upper cone can project.
//
// The search region is computed apart from the pair test so that it can later be bounded
// hierarchically or cached without touching the test. Regions are conservative: every pixel
// whose point can lie in the cone is inside (with a one-pixel margin against rounding), so
// scanning the region and testing each pair exactly gives the O(N^2) definition's result.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od::internal {

/// Columns [col_begin[r], col_end[r]) of each row r in [row_begin, row_end). Buffers are
/// sized once to the image height and reused, so nothing is allocated per pixel.
struct RowSpans {
  int row_begin = 0;
  int row_end = 0;
  std::vector<int> col_begin;
  std::vector<int> col_end;

  explicit RowSpans(int rows) : col_begin(rows), col_end(rows) {}
  bool empty() const { return row_begin >= row_end; }
};

/// Exact search region for a pinhole camera. The truncated cone (heights HT..Hmax above the
/// point, half-angle 90 deg - theta about up) is cut into height slabs; each slab lies in
/// the convex hull of its two rim disks, so the bounding box of its projection is the box
/// of the projected rims (ellipses, in closed form) clipped at the nearest depth any valid
/// point has, plus the slab's cross-section at that depth when it reaches nearer. The union
/// of the slab boxes, row by row, is the region: a staircase around the projected cone.
class PinholeConeRegion {
 public:
  PinholeConeRegion(const PinholeModel& model, const Eigen::Vector3d& up,
                    const DetectorConfig& config, double z_near);

  /// Region for the point `p` (optical frame, z > 0).
  void Compute(const Eigen::Vector3d& p, RowSpans& spans) const;

 private:
  struct Box {
    double u_min, u_max, v_min, v_max;
    bool empty() const { return !(u_min <= u_max && v_min <= v_max); }
  };
  void AddDisk(const Eigen::Vector3d& center, double radius, Box& box) const;

  PinholeModel model_;
  Eigen::Vector3d up_, a_, b_;  // up and an orthonormal basis of the horizontal plane
  Eigen::Vector3d half_extent_per_radius_;  // per axis: sqrt(1 - (e . up)^2)
  std::vector<double> slab_heights_;        // HT = h_0 < ... < h_K = Hmax
  double tan_theta_;
  double z_near_;
};

/// The paper's square window above a pixel: side = scale * (image height of an HT-tall
/// object at the point's depth), from the pixel's row upwards, centred on its column.
void PaperWindow(const PinholeModel& model, const DetectorConfig& config, int row, int col,
                 double depth, RowSpans& spans);

/// Smallest z-depth of a valid point (the near clipping depth that loses nothing).
double NearestDepth(const RangeImage& image);

}  // namespace cairn::od::internal
