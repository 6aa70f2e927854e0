#include "cairn/sources/decode.hpp"

#include <mrpt/img/CImage.h>
#include <mrpt/maps/CPointsMap.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/vision/CStereoRectifyMap.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "cairn/od/units.hpp"
#include "cairn/sources/mrpt_convert.hpp"
#include "mrpt_errors.hpp"

namespace cairn::sources {
namespace {

using ::mrpt::obs::CObservation;
using ::mrpt::obs::CObservation3DRangeScan;
using ::mrpt::obs::CObservationPointCloud;
using ::mrpt::obs::CObservationRotatingScan;
using ::mrpt::obs::CObservationStereoImages;
using ::mrpt::obs::CObservationVelodyneScan;
using ::mrpt::obs::VelodyneCalibration;
using detail::Describe;

std::string Who(const CObservation& o) {
  return ShortClassName(o.GetRuntimeClass()->className) + " '" + o.sensorLabel + "'";
}

Frame NewFrame(const CObservation& o) {
  Frame frame;
  frame.label = o.sensorLabel;
  frame.mrpt_class = ShortClassName(o.GetRuntimeClass()->className);
  frame.stamp_s = FromMrptTime(o.timestamp);
  return frame;
}

double Median(std::vector<double> values) {
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// Columns on a grid of `width` azimuth steps aligned with a firing azimuth: the firing at
// `first_azimuth_rad` (atan2(y, x) convention) falls on a column centre, and column 0 looks
// as nearly backwards as the grid allows, so that forward is in the middle of the image.
struct AzimuthGrid {
  double start_rad = kPi;
  double step_rad = 2.0 * kPi;
  int width = 1;

  AzimuthGrid(double first_azimuth_rad, int columns) : width(columns) {
    step_rad = 2.0 * kPi / width;
    start_rad = first_azimuth_rad + std::round((kPi - first_azimuth_rad) / step_rad) * step_rad;
  }
  int Column(double azimuth_rad) const {
    long col = std::lround((start_rad - azimuth_rad) / step_rad) % width;
    if (col < 0) col += width;
    return static_cast<int>(col);
  }
};

// The lasers of a calibration ordered top beam first: row_of_laser[id] and the elevations.
struct RingOrder {
  std::vector<std::int32_t> row_of_laser;
  std::vector<double> elevation_rad;  // by row
};

RingOrder OrderRings(const std::vector<double>& elevation_of_laser) {
  std::vector<int> lasers(elevation_of_laser.size());
  std::iota(lasers.begin(), lasers.end(), 0);
  std::stable_sort(lasers.begin(), lasers.end(), [&](int a, int b) {
    return elevation_of_laser[a] > elevation_of_laser[b];
  });
  RingOrder order;
  order.row_of_laser.assign(lasers.size(), -1);
  for (std::size_t row = 0; row < lasers.size(); ++row) {
    order.row_of_laser[lasers[row]] = static_cast<std::int32_t>(row);
    order.elevation_rad.push_back(elevation_of_laser[lasers[row]]);
  }
  return order;
}

// MRPT's name of the default calibration for a Velodyne, from the packets' model byte or a
// rotating scan's lidarModel; empty when MRPT has none.
std::string DefaultCalibrationName(int model_byte) {
  if (model_byte == 0x22) return "VLP16";
  if (model_byte == 0x21) return "HDL32";
  return "";
}
// The names MRPT's CObservationRotatingScan::fromVelodyne() writes.
std::string DefaultCalibrationName(const std::string& lidar_model) {
  if (lidar_model == "VLP-16") return "VLP16";
  if (lidar_model == "HDL-32E") return "HDL32";
  return "";
}

std::string Hex(int value) {
  char text[8];
  std::snprintf(text, sizeof(text), "0x%02x", value & 0xFF);
  return text;
}

// Velodyne points with their laser ids and firing azimuths, from generatePointCloud. MRPT's
// base class has no virtual destructor; the collector lives on the stack, never deleted
// through the base.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnon-virtual-dtor"
class VelodyneCollector : public CObservationVelodyneScan::PointCloudStorageWrapper {
 public:
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;
  std::vector<std::int32_t> laser_id;
  std::vector<double> azimuth_deg;  // Velodyne's: clockwise seen from above

  void reserve(std::size_t n) override {
    points.reserve(n);
    intensity.reserve(n);
    laser_id.reserve(n);
    azimuth_deg.reserve(n);
  }
  void add_point(float x, float y, float z, uint8_t pt_intensity,
                 const ::mrpt::system::TTimeStamp&, const float azimuth,
                 uint16_t laser) override {
    points.emplace_back(x, y, z);
    intensity.push_back(pt_intensity);
    laser_id.push_back(laser);
    azimuth_deg.push_back(azimuth);
  }
};
#pragma GCC diagnostic pop

// Grey 8-bit copy of an MRPT image.
Expected<od::Grid<std::uint8_t>> GreyGrid(const ::mrpt::img::CImage& image, const std::string& who,
                                          const char* which) {
  if (image.isEmpty()) return Error{who + ": empty " + which + " image"};
  const ::mrpt::img::CImage grey(image, ::mrpt::img::FAST_REF_OR_CONVERT_TO_GRAY);
  if (grey.getPixelDepth() != ::mrpt::img::PixelDepth::D8U) {
    return Error{who + ": " + which + " image is not 8-bit"};
  }
  od::Grid<std::uint8_t> grid;
  grid.width = static_cast<int>(grey.getWidth());
  grid.height = static_cast<int>(grey.getHeight());
  grid.data.resize(static_cast<std::size_t>(grid.width) * grid.height);
  for (int r = 0; r < grid.height; ++r) {
    const auto* line = grey.ptrLine<std::uint8_t>(static_cast<unsigned>(r));
    std::copy(line, line + grid.width, grid.data.begin() + static_cast<std::ptrdiff_t>(r) * grid.width);
  }
  return grid;
}

}  // namespace

std::vector<double> LaserElevations(const VelodyneCalibration& calibration) {
  std::vector<double> elevations;
  for (const auto& laser : calibration.laser_corrections) {
    elevations.push_back(laser.verticalCorrection * kDegToRad);
  }
  return elevations;
}

bool IsRangeObservation(const CObservation& o) {
  return dynamic_cast<const CObservation3DRangeScan*>(&o) != nullptr ||
         dynamic_cast<const CObservationVelodyneScan*>(&o) != nullptr ||
         dynamic_cast<const CObservationRotatingScan*>(&o) != nullptr ||
         dynamic_cast<const CObservationPointCloud*>(&o) != nullptr ||
         dynamic_cast<const CObservationStereoImages*>(&o) != nullptr;
}

std::optional<std::string> WhyNoRangeData(const CObservation& o) {
  if (const auto* scan = dynamic_cast<const CObservation3DRangeScan*>(&o)) {
    if (!scan->hasRangeImage) return std::string("no range image");
  } else if (const auto* velodyne = dynamic_cast<const CObservationVelodyneScan*>(&o)) {
    if (velodyne->scan_packets.empty()) return std::string("no packets");
  } else if (const auto* rotating = dynamic_cast<const CObservationRotatingScan*>(&o)) {
    if (rotating->rangeImage.rows() == 0 || rotating->rangeImage.cols() == 0) {
      return std::string("empty range image");
    }
  } else if (const auto* cloud = dynamic_cast<const CObservationPointCloud*>(&o)) {
    if (!cloud->pointcloud && !cloud->isExternallyStored()) return std::string("no point map");
  } else if (const auto* stereo = dynamic_cast<const CObservationStereoImages*>(&o)) {
    if (!stereo->hasImageRight) return std::string("no right image");
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------
// Range cameras

Expected<Frame> DecodeRangeScan(const CObservation3DRangeScan& scan) {
  const std::string who = Who(scan);
  try {
    scan.load();
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its externally stored data: " + Describe(e)};
  }
  if (!scan.hasRangeImage) return Error{who + ": no range image"};
  const int rows = static_cast<int>(scan.rangeImage.rows());
  const int cols = static_cast<int>(scan.rangeImage.cols());
  if (rows <= 0 || cols <= 0) return Error{who + ": empty range image"};
  const ::mrpt::img::TCamera& camera = scan.cameraParams;
  if (static_cast<int>(camera.ncols) != cols || static_cast<int>(camera.nrows) != rows) {
    return Error{who + ": cameraParams are " + std::to_string(camera.ncols) + "x" +
                 std::to_string(camera.nrows) + " for a " + std::to_string(cols) + "x" +
                 std::to_string(rows) + " range image"};
  }
  if (!(scan.rangeUnits > 0.0f) || !std::isfinite(scan.rangeUnits)) {
    return Error{who + ": rangeUnits must be positive, got " + std::to_string(scan.rangeUnits)};
  }
  Frame frame = NewFrame(scan);
  DepthImage image;
  image.model.width = cols;
  image.model.height = rows;
  image.model.fx = camera.fx();
  image.model.fy = camera.fy();
  image.model.cx = camera.cx();
  image.model.cy = camera.cy();
  if (Status s = image.model.Validate(); !s) return Error{who + ": cameraParams: " + s.message()};
  const bool distorted =
      std::any_of(camera.dist.begin(), camera.dist.end(), [](double k) { return k != 0.0; });
  for (double k : camera.dist) {
    if (!std::isfinite(k)) return Error{who + ": cameraParams: non-finite distortion"};
  }

  // The ray of every pixel in undistorted normalised coordinates (x/z, y/z).
  const std::size_t n = static_cast<std::size_t>(rows) * cols;
  std::vector<cv::Point2f> ray(n);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) ray[static_cast<std::size_t>(r) * cols + c] = cv::Point2f(c, r);
  }
  const cv::Matx33d K(camera.fx(), 0.0, camera.cx(), 0.0, camera.fy(), camera.cy(), 0.0, 0.0,
                      1.0);
  const cv::Mat dist(1, static_cast<int>(camera.dist.size()), CV_64F,
                     const_cast<double*>(camera.dist.data()));
  if (distorted) {
    cv::undistortPoints(std::vector<cv::Point2f>(ray), ray, K, dist);
  } else {
    for (cv::Point2f& p : ray) {
      p = cv::Point2f(static_cast<float>((p.x - camera.cx()) / camera.fx()),
                      static_cast<float>((p.y - camera.cy()) / camera.fy()));
    }
  }
  // z-depth per pixel of the recording's grid.
  std::vector<float> z(n, 0.0f);
  const double units = scan.rangeUnits;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * cols + c;
      const double d = scan.rangeImage(r, c) * units;
      if (d <= 0.0) continue;
      z[i] = static_cast<float>(
          scan.range_is_depth ? d : d / std::sqrt(1.0 + ray[i].x * ray[i].x + ray[i].y * ray[i].y));
    }
  }
  if (!distorted) {
    image.depth_m = std::move(z);
  } else {
    // Resample onto the undistorted pinhole with the same K: each output pixel takes the
    // depth of the recorded pixel nearest to where its ray was imaged. A z-depth does not
    // change when the pixel moves along its own ray, so no value is altered.
    cv::Mat map_x, map_y;
    cv::initUndistortRectifyMap(K, dist, cv::Matx33d::eye(), K, cv::Size(cols, rows), CV_32FC1,
                                map_x, map_y);
    image.depth_m.assign(n, 0.0f);
    image.decoded_of_source.assign(n, -1);
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const long sc = std::lround(map_x.at<float>(r, c));
        const long sr = std::lround(map_y.at<float>(r, c));
        if (sc < 0 || sr < 0 || sc >= cols || sr >= rows) continue;
        const std::size_t source = static_cast<std::size_t>(sr) * cols + sc;
        const std::size_t out = static_cast<std::size_t>(r) * cols + c;
        image.depth_m[out] = z[source];
        image.decoded_of_source[source] = static_cast<std::int32_t>(out);
      }
    }
    // Recorded pixels no output pixel took (where the lens compresses the image): to the
    // output pixel their ray falls on.
    for (std::size_t i = 0; i < n; ++i) {
      if (image.decoded_of_source[i] >= 0) continue;
      const long c = std::lround(camera.fx() * ray[i].x + camera.cx());
      const long r = std::lround(camera.fy() * ray[i].y + camera.cy());
      if (c >= 0 && r >= 0 && c < cols && r < rows) {
        image.decoded_of_source[i] = static_cast<std::int32_t>(r * cols + c);
      }
    }
  }
  frame.T_body_sensor = FromCPose3D(scan.sensorPose);
  frame.T_body_sensor.linear() = frame.T_body_sensor.linear() * RotationFluFromOptical();
  frame.data = std::move(image);
  return frame;
}

// ---------------------------------------------------------------------------------------
// Spinning LiDARs

Expected<Frame> DecodeVelodyneScan(const CObservationVelodyneScan& scan,
                                   const DecodeOptions& options) {
  const std::string who = Who(scan);
  if (scan.scan_packets.empty()) return Error{who + ": no packets"};
  CObservationVelodyneScan copy = scan;  // generatePointCloud is not const
  std::string calibration_name = "the calibration stored in the observation";
  if (copy.calibration.empty()) {
    const int model = copy.scan_packets.front().velodyne_model_ID;
    const std::string name = DefaultCalibrationName(model);
    if (name.empty()) {
      return Error{who + ": no calibration stored, and MRPT has no default calibration for "
                         "model byte " + Hex(model) + " (known: 0x22 VLP-16, 0x21 HDL-32E)"};
    }
    copy.calibration = VelodyneCalibration::LoadDefaultCalibration(name);
    if (copy.calibration.empty()) {
      return Error{who + ": MRPT's default calibration '" + name + "' is not installed"};
    }
    calibration_name = "MRPT's default " + name + " calibration";
  }
  const std::vector<double> elevation_of_laser = LaserElevations(copy.calibration);
  VelodyneCollector collected;
  try {
    CObservationVelodyneScan::TGeneratePointCloudParameters params;
    params.minDistance = static_cast<float>(options.velodyne_min_range_m);
    copy.generatePointCloud(collected, params);
  } catch (const std::exception& e) {
    return Error{who + ": cannot make points from the packets: " + Describe(e)};
  }
  if (collected.points.empty()) return Error{who + ": the packets hold no return"};
  // MRPT 2.5 hands add_point() the firing azimuth in hundredths of a degree (0..35999), the
  // packets' unit; its point_cloud.azimuth field holds degrees. Accept either.
  if (*std::max_element(collected.azimuth_deg.begin(), collected.azimuth_deg.end()) > 720.0) {
    for (double& a : collected.azimuth_deg) a *= 0.01;
  }
  for (std::int32_t id : collected.laser_id) {
    if (id < 0 || id >= static_cast<int>(elevation_of_laser.size())) {
      return Error{who + ": laser id " + std::to_string(id) + " beyond the " +
                   std::to_string(elevation_of_laser.size()) + " lasers of " + calibration_name};
    }
  }
  const RingOrder order = OrderRings(elevation_of_laser);

  // Firings, from the data: MRPT gives the returns firing by firing, each laser's azimuth
  // interpolated within the firing (0.12 deg across a VLP-16's), firings a step apart
  // (0.4 deg at 10 Hz). A return more than half the typical step past the first return of
  // the current firing starts the next one. Each firing gets its own column; the columns
  // per turn follow from the mean step over the sweep.
  std::vector<double> last(elevation_of_laser.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> steps;
  std::vector<double> unwrapped(collected.azimuth_deg.size());
  double turns = 0.0;
  for (std::size_t i = 0; i < collected.points.size(); ++i) {
    if (i > 0 && collected.azimuth_deg[i] + 180.0 < collected.azimuth_deg[i - 1]) turns += 360.0;
    unwrapped[i] = collected.azimuth_deg[i] + turns;
    double& previous = last[collected.laser_id[i]];
    if (std::isfinite(previous)) {
      const double d = std::fmod(collected.azimuth_deg[i] - previous + 360.0, 360.0);
      if (d > 1e-4 && d < 10.0) steps.push_back(d);
    }
    previous = collected.azimuth_deg[i];
  }
  if (steps.empty()) return Error{who + ": cannot measure the firing step (too few returns)"};
  const double typical_step_deg = Median(steps);
  std::vector<std::int32_t> firing(unwrapped.size(), 0);
  double firing_start = unwrapped.front();
  for (std::size_t i = 1; i < unwrapped.size(); ++i) {
    firing[i] = firing[i - 1];
    if (unwrapped[i] - firing_start > 0.5 * typical_step_deg) {
      ++firing[i];
      firing_start = unwrapped[i];
    }
  }
  const double step_deg = firing.back() > 0
                              ? (firing_start - unwrapped.front()) / firing.back()
                              : typical_step_deg;
  const int width = std::clamp(static_cast<int>(std::lround(360.0 / step_deg)), 16, 8192);
  // Velodyne azimuths grow clockwise seen from above; atan2(y, x) grows anticlockwise.
  const AzimuthGrid grid(-unwrapped.front() * kDegToRad, width);
  const int first_column = grid.Column(-unwrapped.front() * kDegToRad);

  PointScan out;
  out.model.width = width;
  out.model.ring_elevation_rad = order.elevation_rad;
  out.model.azimuth_start_rad = grid.start_rad;
  if (Status s = out.model.Validate(); !s) return Error{who + ": " + s.message()};
  out.rows.reserve(collected.points.size());
  out.cols.reserve(collected.points.size());
  for (std::size_t i = 0; i < collected.points.size(); ++i) {
    out.rows.push_back(order.row_of_laser[collected.laser_id[i]]);
    out.cols.push_back((first_column + firing[i]) % width);
  }
  out.points = std::move(collected.points);
  out.intensity = std::move(collected.intensity);
  out.laser_id = std::move(collected.laser_id);
  out.layout = "rows from laser ids, elevations from " + calibration_name + "; " +
               std::to_string(width) + " columns, one per firing";
  Frame frame = NewFrame(scan);
  frame.T_body_sensor = FromCPose3D(scan.sensorPose);
  frame.data = std::move(out);
  return frame;
}

Expected<Frame> DecodeRotatingScan(const CObservationRotatingScan& scan) {
  const std::string who = Who(scan);
  const int rows = static_cast<int>(scan.rangeImage.rows());
  const int cols = static_cast<int>(scan.rangeImage.cols());
  if (rows <= 0 || cols <= 0) return Error{who + ": empty range image"};
  if (!(scan.rangeResolution > 0.0) || !std::isfinite(scan.rangeResolution)) {
    return Error{who + ": rangeResolution must be positive"};
  }
  if (!std::isfinite(scan.startAzimuth) || !std::isfinite(scan.azimuthSpan) ||
      scan.azimuthSpan == 0.0) {
    return Error{who + ": startAzimuth and azimuthSpan must be finite, the span non-zero"};
  }
  // MRPT 2.5 stores no calibration in a rotating scan: the elevations come from the default
  // calibration of its lidarModel.
  const std::string name = DefaultCalibrationName(scan.lidarModel);
  if (name.empty()) {
    return Error{who + ": lidarModel '" + scan.lidarModel +
                 "' has no known laser elevations (known: VLP-16, HDL-32E)"};
  }
  const VelodyneCalibration& calibration = VelodyneCalibration::LoadDefaultCalibration(name);
  const std::vector<double> elevation_of_laser = LaserElevations(calibration);
  if (static_cast<int>(elevation_of_laser.size()) != rows) {
    return Error{who + ": " + std::to_string(rows) + " rows, but MRPT's default " + name +
                 " calibration has " + std::to_string(elevation_of_laser.size()) + " lasers"};
  }
  // The columns the sweep covers. MRPT 2.5's fromVelodyne() sizes the matrix for 32 lasers
  // per block (28800 columns for 75 VLP-16 packets) but fills one column per laser firing
  // with a stride of 2, up to 16 x packets x 12 / 16 columns; azimuthSpan covers what is
  // filled. So the sweep is taken to end one stride after the last filled column.
  int last = -1, stride = 0, previous = -1;
  for (int c = 0; c < cols; ++c) {
    bool used = false;
    for (int r = 0; r < rows && !used; ++r) used = scan.rangeImage(r, c) != 0;
    if (!used) continue;
    if (previous >= 0 && (stride == 0 || c - previous < stride)) stride = c - previous;
    previous = last = c;
  }
  if (last < 0) return Error{who + ": no return in the range image"};
  if (stride == 0) stride = 1;
  const double covered = last + stride;
  // Velodyne-made scans (the only lidarModels placed here) count azimuth clockwise seen from
  // above, as the packets do, although MRPT documents anticlockwise for rotating scans.
  const double sign = -1.0;
  const double step_rad = std::abs(scan.azimuthSpan) * stride / covered;
  const int width = std::clamp(static_cast<int>(std::lround(2.0 * kPi / step_rad)), 16, 8192);
  const AzimuthGrid grid(sign * scan.startAzimuth, width);
  const RingOrder order = OrderRings(elevation_of_laser);

  PointScan out;
  out.model.width = width;
  out.model.ring_elevation_rad = order.elevation_rad;
  out.model.azimuth_start_rad = grid.start_rad;
  if (Status s = out.model.Validate(); !s) return Error{who + ": " + s.message()};
  const bool has_intensity =
      scan.intensityImage.rows() == rows && scan.intensityImage.cols() == cols;
  for (int c = 0; c <= last; ++c) {
    const double azimuth = sign * (scan.startAzimuth + scan.azimuthSpan * c / covered);
    const int col = grid.Column(azimuth);
    for (int r = 0; r < rows; ++r) {
      const std::uint16_t units = scan.rangeImage(r, c);
      if (units == 0) continue;
      const double range = units * scan.rangeResolution;
      const double e = elevation_of_laser[r];
      out.points.emplace_back(static_cast<float>(range * std::cos(e) * std::cos(azimuth)),
                              static_cast<float>(range * std::cos(e) * std::sin(azimuth)),
                              static_cast<float>(range * std::sin(e)));
      out.laser_id.push_back(r);
      out.rows.push_back(order.row_of_laser[r]);
      out.cols.push_back(col);
      if (has_intensity) out.intensity.push_back(scan.intensityImage(r, c));
    }
  }
  out.layout = "rows from laser ids, elevations from MRPT's default " + name +
               " calibration; " + std::to_string(width) + " columns from the azimuth span";
  Frame frame = NewFrame(scan);
  frame.T_body_sensor = FromCPose3D(scan.sensorPose);
  frame.data = std::move(out);
  return frame;
}

Expected<Frame> DecodePointCloud(const CObservationPointCloud& cloud,
                                 const DecodeOptions& options) {
  const std::string who = Who(cloud);
  try {
    cloud.load();
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its externally stored points: " + Describe(e)};
  }
  if (!cloud.pointcloud) return Error{who + ": no point map"};
  const ::mrpt::maps::CPointsMap& map = *cloud.pointcloud;
  const auto& xs = map.getPointsBufferRef_x();
  const auto& ys = map.getPointsBufferRef_y();
  const auto& zs = map.getPointsBufferRef_z();
  PointScan out;
  out.points.reserve(xs.size());
  for (std::size_t i = 0; i < xs.size(); ++i) out.points.emplace_back(xs[i], ys[i], zs[i]);
  if (const auto* xyzi = dynamic_cast<const ::mrpt::maps::CPointsMapXYZI*>(&map)) {
    out.intensity.reserve(xs.size());
    for (std::size_t i = 0; i < xs.size(); ++i) out.intensity.push_back(xyzi->getPointIntensity_fast(i));
  }
  // The one ring finder (od::FindLayout): ring after ring, organised orders, elevation
  // clusters, else even elevation bins.
  od::PointCloud cloud_points;
  cloud_points.points = out.points;
  Expected<od::FoundLayout> layout = od::FindLayout(cloud_points, options.layout, who);
  if (!layout) return layout.error();
  out.model = std::move(layout->model);
  out.rows = std::move(layout->rows);
  out.cols = std::move(layout->cols);
  out.layout = std::to_string(out.model.height()) + " rows (" + od::RingSourceName(layout->source) +
               "), " + std::to_string(out.model.width) + " columns";
  if (!layout->note.empty()) out.layout += "; " + layout->note;
  Frame frame = NewFrame(cloud);
  frame.T_body_sensor = FromCPose3D(cloud.sensorPose);
  frame.data = std::move(out);
  return frame;
}

// ---------------------------------------------------------------------------------------
// Stereo

Expected<Frame> DecodeStereoImages(const CObservationStereoImages& stereo) {
  const std::string who = Who(stereo);
  try {
    stereo.load();
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its externally stored images: " + Describe(e)};
  }
  if (!stereo.hasImageRight) return Error{who + ": no right image"};
  CObservationStereoImages pair = stereo;
  if (pair.imageLeft.getWidth() != pair.imageRight.getWidth() ||
      pair.imageLeft.getHeight() != pair.imageRight.getHeight()) {
    return Error{who + ": left and right images differ in size"};
  }
  if (pair.leftCamera.ncols != pair.imageLeft.getWidth() ||
      pair.leftCamera.nrows != pair.imageLeft.getHeight()) {
    return Error{who + ": leftCamera is " + std::to_string(pair.leftCamera.ncols) + "x" +
                 std::to_string(pair.leftCamera.nrows) + " for a " +
                 std::to_string(pair.imageLeft.getWidth()) + "x" +
                 std::to_string(pair.imageLeft.getHeight()) + " image"};
  }
  StereoPair out;
  if (!pair.areImagesRectified()) {
    try {
      ::mrpt::vision::CStereoRectifyMap rectify;
      rectify.setAlpha(0.0);
      rectify.setFromCamParams(pair);
      rectify.rectify(pair, false);
    } catch (const std::exception& e) {
      return Error{who + ": cannot rectify the pair: " + Describe(e)};
    }
    out.rectified_here = true;
  }
  Expected<od::Grid<std::uint8_t>> left = GreyGrid(pair.imageLeft, who, "left");
  if (!left) return left.error();
  Expected<od::Grid<std::uint8_t>> right = GreyGrid(pair.imageRight, who, "right");
  if (!right) return right.error();
  out.left = std::move(*left);
  out.right = std::move(*right);
  out.left_model.width = out.left.width;
  out.left_model.height = out.left.height;
  out.left_model.fx = pair.leftCamera.fx();
  out.left_model.fy = pair.leftCamera.fy();
  out.left_model.cx = pair.leftCamera.cx();
  out.left_model.cy = pair.leftCamera.cy();
  if (Status s = out.left_model.Validate(); !s) return Error{who + ": leftCamera: " + s.message()};
  const auto& t = pair.rightCameraPose;
  out.baseline_m = std::sqrt(t.x() * t.x() + t.y() * t.y() + t.z() * t.z());
  if (!(out.baseline_m > 0.0) || !std::isfinite(out.baseline_m)) {
    return Error{who + ": rightCameraPose gives no baseline"};
  }
  Frame frame = NewFrame(stereo);
  frame.T_body_sensor = FromCPose3D(::mrpt::poses::CPose3D(pair.cameraPose));
  frame.data = std::move(out);
  return frame;
}

Expected<Frame> DecodeRangeObservation(const CObservation& o, const DecodeOptions& options) {
  if (const auto* scan = dynamic_cast<const CObservation3DRangeScan*>(&o)) {
    return DecodeRangeScan(*scan);
  }
  if (const auto* velodyne = dynamic_cast<const CObservationVelodyneScan*>(&o)) {
    return DecodeVelodyneScan(*velodyne, options);
  }
  if (const auto* rotating = dynamic_cast<const CObservationRotatingScan*>(&o)) {
    return DecodeRotatingScan(*rotating);
  }
  if (const auto* cloud = dynamic_cast<const CObservationPointCloud*>(&o)) {
    return DecodePointCloud(*cloud, options);
  }
  if (const auto* stereo = dynamic_cast<const CObservationStereoImages*>(&o)) {
    return DecodeStereoImages(*stereo);
  }
  return Error{Who(o) + ": not a range observation"};
}

// ---------------------------------------------------------------------------------------
// Odometry and IMU

OdometrySample DecodeOdometry(const ::mrpt::obs::CObservationOdometry& odometry) {
  OdometrySample sample;
  sample.stamp_s = FromMrptTime(odometry.timestamp);
  sample.T_odom_body = Eigen::Isometry3d::Identity();
  sample.T_odom_body.linear() =
      Eigen::AngleAxisd(odometry.odometry.phi(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  sample.T_odom_body.translation() << odometry.odometry.x(), odometry.odometry.y(), 0.0;
  sample.source = odometry.sensorLabel.empty() ? "CObservationOdometry" : odometry.sensorLabel;
  return sample;
}

std::optional<ImuAttitude> DecodeImu(const ::mrpt::obs::CObservationIMU& imu) {
  using namespace ::mrpt::obs;
  ImuAttitude attitude;
  attitude.stamp_s = FromMrptTime(imu.timestamp);
  attitude.label = imu.sensorLabel;
  if (imu.has(IMU_ROLL) && imu.has(IMU_PITCH)) {
    attitude.roll_rad = imu.get(IMU_ROLL);
    attitude.pitch_rad = imu.get(IMU_PITCH);
    if (imu.has(IMU_YAW)) attitude.yaw_rad = imu.get(IMU_YAW);
  } else if (imu.has(IMU_ORI_QUAT_W) && imu.has(IMU_ORI_QUAT_X) && imu.has(IMU_ORI_QUAT_Y) &&
             imu.has(IMU_ORI_QUAT_Z)) {
    const Eigen::Quaterniond q(imu.get(IMU_ORI_QUAT_W), imu.get(IMU_ORI_QUAT_X),
                               imu.get(IMU_ORI_QUAT_Y), imu.get(IMU_ORI_QUAT_Z));
    if (!(q.norm() > 0.0)) return std::nullopt;
    const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
    attitude.pitch_rad = std::atan2(-R(2, 0), std::hypot(R(0, 0), R(1, 0)));
    attitude.roll_rad = std::atan2(R(2, 1), R(2, 2));
    attitude.yaw_rad = std::atan2(R(1, 0), R(0, 0));
  } else {
    return std::nullopt;
  }
  if (!std::isfinite(attitude.roll_rad) || !std::isfinite(attitude.pitch_rad)) {
    return std::nullopt;
  }
  return attitude;
}

std::optional<ImuSample> DecodeImuSample(const ::mrpt::obs::CObservationIMU& imu) {
  using namespace ::mrpt::obs;
  auto triple = [&](TIMUDataIndex x, TIMUDataIndex y,
                    TIMUDataIndex z) -> std::optional<Eigen::Vector3d> {
    if (!imu.has(x) || !imu.has(y) || !imu.has(z)) return std::nullopt;
    const Eigen::Vector3d v(imu.get(x), imu.get(y), imu.get(z));
    if (!v.allFinite()) return std::nullopt;
    return v;
  };
  ImuSample sample;
  sample.stamp_s = FromMrptTime(imu.timestamp);
  sample.label = imu.sensorLabel;
  sample.specific_force_mps2 = triple(IMU_X_ACC, IMU_Y_ACC, IMU_Z_ACC);
  sample.angular_rate_radps = triple(IMU_WX, IMU_WY, IMU_WZ);
  if (!sample.specific_force_mps2 && !sample.angular_rate_radps) return std::nullopt;
  sample.T_body_imu = FromCPose3D(imu.sensorPose);
  return sample;
}

}  // namespace cairn::sources
