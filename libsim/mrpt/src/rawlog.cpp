#include "cairn/sim/mrpt/rawlog.hpp"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <system_error>

namespace cairn::sim {
namespace {

namespace fs = std::filesystem;
using ::mrpt::obs::CObservation;

// Ticks of mrpt::Clock (100 ns) between 1601-01-01 (its epoch) and 1970-01-01.
constexpr std::int64_t kUnixEpochTicks = 116444736000000000LL;
constexpr double kTicksPerSecond = 1e7;

std::string Describe(const std::exception& e) {
  // MRPT's messages carry a stack of frames; the first line says what went wrong.
  std::string what = e.what();
  const auto end = what.find('\n');
  return end == std::string::npos ? what : what.substr(0, end);
}

}  // namespace

::mrpt::poses::CPose3D ToCPose3D(const Eigen::Isometry3d& T) {
  return ::mrpt::poses::CPose3D(::mrpt::math::CMatrixDouble44(T.matrix()));
}

Eigen::Isometry3d FromCPose3D(const ::mrpt::poses::CPose3D& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = pose.getRotationMatrix().asEigen();
  T.translation() << pose.x(), pose.y(), pose.z();
  return T;
}

::mrpt::Clock::time_point ToMrptTime(double unix_s) {
  const auto ticks = kUnixEpochTicks + std::llround(unix_s * kTicksPerSecond);
  return ::mrpt::Clock::time_point(::mrpt::Clock::duration(ticks));
}

double FromMrptTime(::mrpt::Clock::time_point t) {
  const auto ticks = static_cast<std::int64_t>(t.time_since_epoch().count()) - kUnixEpochTicks;
  return static_cast<double>(ticks) / kTicksPerSecond;
}

// ---------------------------------------------------------------------------------------
// Writer

Expected<RawlogWriter> RawlogWriter::Create(const fs::path& path, int gzip_level) {
  if (gzip_level < 0 || gzip_level > 9) {
    return Error{path.string() + ": gzip level " + std::to_string(gzip_level) + " (expected 0..9)"};
  }
  RawlogWriter writer;
  writer.path_ = path;
  writer.temp_path_ = path;
  writer.temp_path_ += ".tmp-" + std::to_string(::getpid());
  writer.out_ = std::make_unique<::mrpt::io::CFileGZOutputStream>();
  bool opened = false;
  try {
    opened = writer.out_->open(writer.temp_path_.string(), gzip_level);
  } catch (const std::exception&) {
    opened = false;
  }
  if (!opened) {
    writer.out_.reset();
    return Error{path.string() + ": cannot open for writing (is its directory there?)"};
  }
  return writer;
}

RawlogWriter::~RawlogWriter() {
  if (out_) {
    out_.reset();  // closes
    std::error_code ec;
    fs::remove(temp_path_, ec);
  }
}

Status RawlogWriter::Write(const ::mrpt::serialization::CSerializable& object) {
  if (!out_) return Error{path_.string() + ": already committed"};
  try {
    auto archive = ::mrpt::serialization::archiveFrom(*out_);
    archive << object;
  } catch (const std::exception& e) {
    return Error{path_.string() + ": cannot write object " + std::to_string(written_) + ": " +
                 Describe(e)};
  }
  ++written_;
  return {};
}

Status RawlogWriter::Commit() {
  if (!out_) return Error{path_.string() + ": already committed"};
  try {
    out_->close();
  } catch (const std::exception& e) {
    return Error{path_.string() + ": cannot close: " + Describe(e)};
  }
  out_.reset();
  std::error_code ec;
  fs::rename(temp_path_, path_, ec);
  if (ec) {
    fs::remove(temp_path_, ec);
    return Error{path_.string() + ": cannot rename the temporary file into place: " + ec.message()};
  }
  return {};
}

// ---------------------------------------------------------------------------------------
// Reader

// The gzip stream with one byte of look-ahead: MRPT reports both a clean end of file and a
// file cut inside an object as CExceptionEOF, so the reader asks before each object whether
// any byte is left.
class RawlogReader::Stream : public ::mrpt::io::CStream {
 public:
  explicit Stream(::mrpt::io::CFileGZInputStream& file) : file_(file) {}

  bool AtEnd() {
    if (has_peek_) return false;
    has_peek_ = file_.Read(&peek_, 1) == 1;
    return !has_peek_;
  }

  size_t Read(void* buffer, size_t count) override {
    if (count == 0) return 0;
    auto* out = static_cast<std::uint8_t*>(buffer);
    size_t n = 0;
    if (has_peek_) {
      out[0] = peek_;
      has_peek_ = false;
      n = 1;
    }
    // A gzip stream may return fewer bytes than asked before its end: keep reading.
    while (n < count) {
      const size_t got = file_.Read(out + n, count - n);
      if (got == 0) break;
      n += got;
    }
    return n;
  }
  size_t Write(const void*, size_t) override { return 0; }
  uint64_t Seek(int64_t, ::mrpt::io::CStream::TSeekOrigin) override {
    throw std::runtime_error("rawlog stream: seeking is not supported");
  }
  uint64_t getTotalBytesCount() const override { return file_.getTotalBytesCount(); }
  uint64_t getPosition() const override { return file_.getPosition() - (has_peek_ ? 1 : 0); }

 private:
  ::mrpt::io::CFileGZInputStream& file_;
  std::uint8_t peek_ = 0;
  bool has_peek_ = false;
};

Expected<RawlogReader> RawlogReader::Open(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return Error{path.string() + ": no such file"};
  RawlogReader reader;
  reader.path_ = path;
  reader.file_ = std::make_unique<::mrpt::io::CFileGZInputStream>();
  std::string message;
  bool opened = false;
  try {
    opened = reader.file_->open(path.string(), message);
  } catch (const std::exception& e) {
    message = Describe(e);
  }
  if (!opened) {
    return Error{path.string() + ": cannot open for reading" +
                 (message.empty() ? std::string() : ": " + message)};
  }
  reader.stream_ = std::make_unique<Stream>(*reader.file_);
  return reader;
}

RawlogReader::RawlogReader(RawlogReader&&) noexcept = default;
RawlogReader& RawlogReader::operator=(RawlogReader&&) noexcept = default;
RawlogReader::~RawlogReader() = default;

Expected<CObservation::Ptr> RawlogReader::Next() {
  while (pending_.empty()) {
    if (stream_->AtEnd()) return CObservation::Ptr();
    ::mrpt::serialization::CSerializable::Ptr object;
    try {
      auto archive = ::mrpt::serialization::archiveFrom(*stream_);
      object = archive.ReadObject();
    } catch (const std::exception& e) {
      return Error{path_.string() + ": entry " + std::to_string(entries_) +
                   ": truncated or corrupt rawlog: " + Describe(e)};
    }
    ++entries_;
    if (auto obs = std::dynamic_pointer_cast<CObservation>(object)) {
      pending_.push_back(std::move(obs));
    } else if (auto frame = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>(object)) {
      for (const CObservation::Ptr& o : *frame) {
        if (o) pending_.push_back(o);
      }
    } else if (!std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>(object)) {
      return Error{path_.string() + ": entry " + std::to_string(entries_ - 1) + ": a " +
                   (object ? object->GetRuntimeClass()->className : std::string("null")) +
                   ", not an observation, sensory frame or action"};
    }
  }
  CObservation::Ptr next = std::move(pending_.front());
  pending_.pop_front();
  return next;
}

Expected<std::vector<CObservation::Ptr>> ReadRawlogObservations(const fs::path& path) {
  Expected<RawlogReader> reader = RawlogReader::Open(path);
  if (!reader) return reader.error();
  std::vector<CObservation::Ptr> observations;
  while (true) {
    Expected<CObservation::Ptr> next = reader->Next();
    if (!next) return next.error();
    if (!*next) break;
    observations.push_back(std::move(*next));
  }
  return observations;
}

// ---------------------------------------------------------------------------------------
// Observations

Expected<::mrpt::obs::CObservation3DRangeScan::Ptr> MakeRangeScan(
    const DepthFrame& frame, const Eigen::Isometry3d& T_body_camera, double range_units_m,
    double max_range_m, ::mrpt::Clock::time_point stamp) {
  if (!(range_units_m > 0.0)) {
    return Error{"range scan: range units must be > 0, got " + std::to_string(range_units_m)};
  }
  auto scan = std::make_shared<::mrpt::obs::CObservation3DRangeScan>();
  scan->sensorLabel = kCameraLabel;
  scan->timestamp = stamp;
  scan->hasRangeImage = true;
  scan->range_is_depth = true;
  scan->rangeUnits = static_cast<float>(range_units_m);
  scan->rangeImage_setSize(frame.height(), frame.width());
  for (int r = 0; r < frame.height(); ++r) {
    for (int c = 0; c < frame.width(); ++c) {
      const float d = frame.depth_m[static_cast<std::size_t>(r) * frame.width() + c];
      long units = 0;
      if (std::isfinite(d) && d > 0.0f) units = std::lround(d / range_units_m);
      if (units > 65535) {
        return Error{"range scan: depth " + std::to_string(d) + " m at row " + std::to_string(r) +
                     ", col " + std::to_string(c) + " exceeds 65535 x " +
                     std::to_string(range_units_m) + " m"};
      }
      scan->rangeImage(r, c) = static_cast<std::uint16_t>(units);
    }
  }
  ::mrpt::img::TCamera camera;
  camera.ncols = static_cast<std::uint32_t>(frame.model.width);
  camera.nrows = static_cast<std::uint32_t>(frame.model.height);
  camera.setIntrinsicParamsFromValues(frame.model.fx, frame.model.fy, frame.model.cx,
                                      frame.model.cy);
  camera.cameraName = kCameraLabel;
  scan->cameraParams = camera;
  scan->cameraParamsIntensity = camera;
  scan->maxRange = static_cast<float>(max_range_m);
  scan->stdError = static_cast<float>(range_units_m);
  Eigen::Isometry3d T_body_flu = T_body_camera;
  T_body_flu.linear() = T_body_camera.linear() * RotationOpticalFromFlu();
  scan->sensorPose = ToCPose3D(T_body_flu);
  return scan;
}

::mrpt::obs::CObservationPointCloud::Ptr MakePointCloud(const LidarScan& scan,
                                                        const Eigen::Isometry3d& T_body_lidar,
                                                        ::mrpt::Clock::time_point stamp) {
  auto cloud = std::make_shared<::mrpt::obs::CObservationPointCloud>();
  cloud->sensorLabel = kLidarLabel;
  cloud->timestamp = stamp;
  auto points = ::mrpt::maps::CSimplePointsMap::Create();
  points->reserve(scan.points.size());
  for (const Eigen::Vector3f& p : scan.points) points->insertPointFast(p.x(), p.y(), p.z());
  cloud->pointcloud = points;
  cloud->sensorPose = ToCPose3D(T_body_lidar);
  return cloud;
}

::mrpt::obs::CObservationOdometry::Ptr MakeOdometry(const Pose2D& odometry,
                                                    const Eigen::Vector3d& velocity_local,
                                                    ::mrpt::Clock::time_point stamp) {
  auto obs = std::make_shared<::mrpt::obs::CObservationOdometry>();
  obs->sensorLabel = kOdometryLabel;
  obs->timestamp = stamp;
  obs->odometry = ::mrpt::poses::CPose2D(odometry.x_m, odometry.y_m, odometry.yaw_rad);
  obs->hasVelocities = true;
  obs->velocityLocal =
      ::mrpt::math::TTwist2D(velocity_local.x(), velocity_local.y(), velocity_local.z());
  return obs;
}

::mrpt::obs::CObservationIMU::Ptr MakeImu(const Attitude& attitude,
                                          ::mrpt::Clock::time_point stamp) {
  auto obs = std::make_shared<::mrpt::obs::CObservationIMU>();
  obs->sensorLabel = kImuLabel;
  obs->timestamp = stamp;
  obs->set(::mrpt::obs::IMU_YAW, attitude.yaw_rad);
  obs->set(::mrpt::obs::IMU_PITCH, attitude.pitch_rad);
  obs->set(::mrpt::obs::IMU_ROLL, attitude.roll_rad);
  return obs;
}

Expected<RangeScanFrame> DecodeRangeScan(const ::mrpt::obs::CObservation3DRangeScan& scan) {
  const std::string who = "range scan '" + scan.sensorLabel + "'";
  try {
    scan.load();
  } catch (const std::exception& e) {
    return Error{who + ": cannot load its external data: " + Describe(e)};
  }
  if (!scan.hasRangeImage) return Error{who + ": no range image"};
  const int rows = static_cast<int>(scan.rangeImage.rows());
  const int cols = static_cast<int>(scan.rangeImage.cols());
  if (rows <= 0 || cols <= 0) return Error{who + ": empty range image"};
  RangeScanFrame frame;
  frame.label = scan.sensorLabel;
  frame.stamp_s = FromMrptTime(scan.timestamp);
  frame.model.width = cols;
  frame.model.height = rows;
  frame.model.fx = scan.cameraParams.fx();
  frame.model.fy = scan.cameraParams.fy();
  frame.model.cx = scan.cameraParams.cx();
  frame.model.cy = scan.cameraParams.cy();
  if (static_cast<int>(scan.cameraParams.ncols) != cols ||
      static_cast<int>(scan.cameraParams.nrows) != rows) {
    return Error{who + ": cameraParams are " + std::to_string(scan.cameraParams.ncols) + "x" +
                 std::to_string(scan.cameraParams.nrows) + " for a " + std::to_string(cols) + "x" +
                 std::to_string(rows) + " range image"};
  }
  if (Status s = frame.model.Validate(); !s) return Error{who + ": cameraParams: " + s.message()};
  frame.depth_m.resize(static_cast<std::size_t>(rows) * cols);
  const double units = scan.rangeUnits;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      double d = scan.rangeImage(r, c) * units;
      if (!scan.range_is_depth && d > 0.0) {
        const double kx = (c - frame.model.cx) / frame.model.fx;
        const double ky = (r - frame.model.cy) / frame.model.fy;
        d /= std::sqrt(1.0 + kx * kx + ky * ky);
      }
      frame.depth_m[static_cast<std::size_t>(r) * cols + c] = static_cast<float>(d);
    }
  }
  frame.T_body_camera = FromCPose3D(scan.sensorPose);
  frame.T_body_camera.linear() =
      frame.T_body_camera.linear() * RotationOpticalFromFlu().transpose();
  return frame;
}

}  // namespace cairn::sim
