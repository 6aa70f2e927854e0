// Internal: the image region onto which a point's upper cone can project.
//
// The search region is computed apart from the pair test so that it can later be bounded
// hierarchically or cached without touching the test. Regions are conservative: every pixel
// whose point can lie in the cone is inside (with a one-pixel margin against rounding), so
// scanning the region and testing each pair exactly gives the O(N^2) definition's result.
#pragma once

#include <Eigen/Core>
#include <variant>
#include <vector>

#include "cairn/od/detector.hpp"
#include "cairn/od/range_image.hpp"

namespace cairn::od::internal {

/// Columns [col_begin[r], col_end[r]) of each row r in [row_begin, row_end). On a
/// spherical image a span may wrap: col_begin is in [0, width) and col_end may exceed
/// width, continuing at column 0. Buffers are sized once to the image height and reused,
/// so nothing is allocated per pixel.
struct RowSpans {
  int row_begin = 0;
  int row_end = 0;
  std::vector<int> col_begin;
  std::vector<int> col_end;

  explicit RowSpans(int rows) : col_begin(rows), col_end(rows) {}
  bool empty() const { return row_begin >= row_end; }
  bool Contains(int row, int col, int width) const {
    if (row < row_begin || row >= row_end) return false;
    return (col >= col_begin[row] && col < col_end[row]) ||
           (col + width >= col_begin[row] && col + width < col_end[row]);
  }
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

/// Exact search region for a spinning LiDAR. Each height slab of the cone lies in a ball;
/// seen from the sensor, a ball spans an elevation interval and an azimuth interval in
/// closed form. Rows are kept whose points' elevations (measured on the data, so beam
/// offsets and motion are covered) meet the interval; columns whose centre azimuth, widened
/// by the largest offset of any point from its column centre, meets the azimuth interval.
class SphericalConeRegion {
 public:
  SphericalConeRegion(const RangeImage& image, const SphericalModel& model,
                      const DetectorConfig& config);

  /// Region for the point `p` (sensor frame) stored at column `col`.
  void Compute(const Eigen::Vector3d& p, int col, RowSpans& spans) const;

 private:
  SphericalModel model_;
  Eigen::Vector3d up_;
  std::vector<double> slab_heights_;
  double tan_theta_;
  std::vector<double> row_elevation_min_, row_elevation_max_;  // +inf / -inf: empty row
  double offset_min_ = 0.0, offset_max_ = 0.0;  // point azimuth - column azimuth [rad]
};

/// The search region of every pixel of one image, by the config's mode and the image's
/// sensor model: the exact cone projection, or the paper's square window above the pixel
/// (side = scale * image size of an HT-tall object at the point's range, centred on its
/// column).
class ConeRegion {
 public:
  ConeRegion(const RangeImage& image, const DetectorConfig& config);
  void Compute(int pixel, RowSpans& spans) const;

 private:
  void PaperWindow(int pixel, RowSpans& spans) const;

  const RangeImage& image_;
  DetectorConfig config_;
  std::variant<std::monostate, PinholeConeRegion, SphericalConeRegion> exact_;
};

}  // namespace cairn::od::internal
