#include "cairn/od/io/point_cloud.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <complex>
#include <cstring>
#include <fstream>
#include <opencv2/core.hpp>
#include <sstream>
#include <string_view>

#include "cairn/od/io/atomic_file.hpp"
#include "png.hpp"

namespace cairn::od::io {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kBinPointBytes = 16;  // 4 x float32
constexpr double kOrganisedAgreement = 0.9;  // share of neighbour pairs that must agree

// The formats are little-endian; these builds target little-endian hosts only.
static_assert(sizeof(float) == 4, "float32 expected");

Expected<std::string> ReadBytes(const std::filesystem::path& path, const char* what) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{name + ": no such file (" + what + ")"};
  if (std::filesystem::is_directory(path, ec)) {
    return Error{name + ": is a directory, expected a " + what + " file"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{name + ": cannot open for reading (" + what + ")"};
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return Error{name + ": read failed (" + what + ")"};
  return buffer.str();
}

bool IsReturn(const Eigen::Vector3f& p) { return p.x() != 0.f || p.y() != 0.f || p.z() != 0.f; }

double WrapPi(double a) { return std::remainder(a, 2.0 * kPi); }

}  // namespace

Expected<PointCloud> ReadKittiBin(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> bytes = ReadBytes(path, "KITTI .bin point cloud");
  if (!bytes) return bytes.error();
  if (bytes->size() % kBinPointBytes != 0) {
    return Error{name + ": size " + std::to_string(bytes->size()) +
                 " bytes is not a multiple of 16 (x, y, z, intensity float32 per point): the "
                 "file is truncated or not a KITTI .bin"};
  }
  const std::size_t n = bytes->size() / kBinPointBytes;
  PointCloud cloud;
  cloud.points.resize(n);
  cloud.intensity.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    float v[4];
    std::memcpy(v, bytes->data() + i * kBinPointBytes, kBinPointBytes);
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]) ||
        !std::isfinite(v[3])) {
      return Error{name + ": point " + std::to_string(i) +
                   " has a non-finite value (expected finite x, y, z, intensity)"};
    }
    cloud.points[i] = Eigen::Vector3f(v[0], v[1], v[2]);
    cloud.intensity[i] = v[3];
  }
  return cloud;
}

Status WriteKittiBin(const std::filesystem::path& path, const PointCloud& cloud) {
  assert(cloud.intensity.empty() || cloud.intensity.size() == cloud.points.size());
  std::string bytes(cloud.points.size() * kBinPointBytes, '\0');
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const float v[4] = {cloud.points[i].x(), cloud.points[i].y(), cloud.points[i].z(),
                        cloud.intensity.empty() ? 0.f : cloud.intensity[i]};
    std::memcpy(bytes.data() + i * kBinPointBytes, v, kBinPointBytes);
  }
  return WriteFileAtomic(path, bytes);
}

Expected<PointLayout> ResolveLayout(const PointCloud& cloud, const SphericalModel& preset,
                                    OrganisedMode mode, const std::string& source) {
  if (Status s = preset.Validate(); !s) return Error{source + ": " + s.message()};
  const std::size_t n = cloud.points.size();
  const std::size_t rings = static_cast<std::size_t>(preset.height());
  PointLayout layout;
  layout.model = preset;
  const bool divisible = n > 0 && n % rings == 0;
  if (mode == OrganisedMode::kYes && !divisible) {
    return Error{source + ": " + std::to_string(n) + " points cannot be an organised scan of " +
                 std::to_string(rings) + " rings (not a multiple)"};
  }
  if (mode == OrganisedMode::kNo || !divisible) return layout;

  const std::size_t columns = n / rings;
  const double step = 2.0 * kPi / static_cast<double>(columns);
  auto azimuth = [](const Eigen::Vector3f& p) { return std::atan2(double(p.y()), double(p.x())); };
  auto elevation = [](const Eigen::Vector3f& p) {
    return std::atan2(double(p.z()), std::hypot(double(p.x()), double(p.y())));
  };
  // Evidence: within a column, elevation falls with the ring; along a ring, the azimuth
  // falls by one step per column (within a few steps: Ouster beams have azimuth offsets).
  std::size_t ring_pairs = 0, ring_agree = 0, col_pairs = 0, col_agree = 0;
  // Column 0's azimuth from the data: circular mean of azimuth + col * step over returns.
  std::complex<double> start_sum(0.0, 0.0);
  for (std::size_t c = 0; c < columns; ++c) {
    for (std::size_t r = 0; r < rings; ++r) {
      const Eigen::Vector3f& p = cloud.points[c * rings + r];
      if (!IsReturn(p)) continue;
      start_sum += std::polar(1.0, azimuth(p) + static_cast<double>(c) * step);
      if (r + 1 < rings) {
        const Eigen::Vector3f& below = cloud.points[c * rings + r + 1];
        if (IsReturn(below)) {
          ++ring_pairs;
          if (elevation(below) < elevation(p)) ++ring_agree;
        }
      }
      if (c + 1 < columns) {
        const Eigen::Vector3f& next = cloud.points[(c + 1) * rings + r];
        if (IsReturn(next)) {
          ++col_pairs;
          const double d = WrapPi(azimuth(p) - azimuth(next));  // one step when organised
          if (d > -2.0 * step && d < 4.0 * step) ++col_agree;
        }
      }
    }
  }
  const bool evidence = ring_pairs > 0 && col_pairs > 0 &&
                        ring_agree >= kOrganisedAgreement * ring_pairs &&
                        col_agree >= kOrganisedAgreement * col_pairs;
  if (mode == OrganisedMode::kAuto && !evidence) return layout;

  layout.organised = true;
  layout.model.width = static_cast<int>(columns);
  layout.model.azimuth_start_rad = std::abs(start_sum) > 0.0 ? std::arg(start_sum) : 0.0;
  layout.rows.resize(n);
  layout.cols.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    layout.rows[i] = static_cast<std::int32_t>(i % rings);
    layout.cols[i] = static_cast<std::int32_t>(i / rings);
  }
  return layout;
}

Expected<std::vector<std::uint32_t>> PointLabels(const RangeImage& image,
                                                 const Detection& detection,
                                                 const Classification& classification) {
  assert(detection.width == image.width() && detection.height == image.height());
  if (detection.segments.size() > 0xFFFF) {
    return Error{std::to_string(detection.segments.size()) +
                 " segments: ids above 65535 do not fit the upper 16 bits of a .label entry"};
  }
  const std::vector<std::uint8_t> cls = ClassImage(detection, classification);
  const std::vector<std::int32_t>& cell = image.cell_of_point();
  std::vector<std::uint32_t> labels(cell.size(), 0u);
  for (std::size_t i = 0; i < cell.size(); ++i) {
    if (cell[i] < 0) continue;
    const auto id = static_cast<std::uint32_t>(detection.labels[cell[i]]);
    labels[i] = (id << 16) | static_cast<std::uint32_t>(cls[cell[i]]);
  }
  return labels;
}

Status WriteLabelFile(const std::filesystem::path& path,
                      const std::vector<std::uint32_t>& labels) {
  return WriteFileAtomic(
      path, std::string_view(reinterpret_cast<const char*>(labels.data()), labels.size() * 4));
}

Expected<std::vector<std::uint32_t>> ReadLabelFile(const std::filesystem::path& path) {
  Expected<std::string> bytes = ReadBytes(path, "SemanticKITTI .label file");
  if (!bytes) return bytes.error();
  if (bytes->size() % 4 != 0) {
    return Error{path.string() + ": size " + std::to_string(bytes->size()) +
                 " bytes is not a multiple of 4 (one uint32 per point): the file is truncated"};
  }
  std::vector<std::uint32_t> labels(bytes->size() / 4);
  std::memcpy(labels.data(), bytes->data(), bytes->size());
  return labels;
}

Grid<float> RangeGrid(const RangeImage& image) {
  Grid<float> grid{image.width(), image.height(),
                   std::vector<float>(static_cast<std::size_t>(image.size()), 0.f)};
  for (int i = 0; i < image.size(); ++i) {
    if (image.valid(i)) grid.data[i] = static_cast<float>(image.range(i));
  }
  return grid;
}

Expected<RgbImage> RenderBirdsEye(const RangeImage& image,
                                  const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::uint8_t>& point_class,
                                  const BirdsEyeOptions& options) {
  if (point_class.size() != points.size()) {
    return Error{"bird's-eye view: " + std::to_string(point_class.size()) + " classes for " +
                 std::to_string(points.size()) + " points"};
  }
  if (!(options.metres_per_pixel > 0.0) || !(options.half_extent_m > 0.0) ||
      options.half_extent_m / options.metres_per_pixel > 10000.0) {
    return Error{"bird's-eye view: metres_per_pixel and half_extent_m must be positive, "
                 "at most 20000 px across"};
  }
  const int side = static_cast<int>(std::ceil(2.0 * options.half_extent_m /
                                               options.metres_per_pixel));
  RgbImage out{side, side, std::vector<std::array<std::uint8_t, 3>>(
                               static_cast<std::size_t>(side) * side, {0, 0, 0})};
  const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();
  auto draw = [&](std::uint8_t wanted, std::array<std::uint8_t, 3> colour, int radius) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (point_class[i] != wanted || !IsReturn(points[i])) continue;
      const Eigen::Vector3f q = R * points[i];
      const double row_f = (options.half_extent_m - q.x()) / options.metres_per_pixel;
      const double col_f = (options.half_extent_m - q.y()) / options.metres_per_pixel;
      const int row = static_cast<int>(std::floor(row_f)), col = static_cast<int>(std::floor(col_f));
      for (int dr = -radius; dr <= radius; ++dr) {
        for (int dc = -radius; dc <= radius; ++dc) {
          const int rr = row + dr, cc = col + dc;
          if (rr >= 0 && rr < side && cc >= 0 && cc < side) out.at(rr, cc) = colour;
        }
      }
    }
  };
  draw(static_cast<std::uint8_t>(SegmentClass::kNone), {110, 110, 110}, 0);
  draw(static_cast<std::uint8_t>(SegmentClass::kRejected), {255, 0, 0}, 1);
  draw(static_cast<std::uint8_t>(SegmentClass::kKept), {0, 40, 255}, 1);
  return out;
}

Status WriteRgbPng(const std::filesystem::path& path, const RgbImage& image) {
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int r = 0; r < image.height; ++r) {
    for (int c = 0; c < image.width; ++c) {
      const auto& p = image.at(r, c);
      bgr.at<cv::Vec3b>(r, c) = cv::Vec3b(p[2], p[1], p[0]);
    }
  }
  return detail::WritePngAtomic(path, bgr);
}

}  // namespace cairn::od::io
