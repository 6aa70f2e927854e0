#include "cairn/sources/mrpt_convert.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace cairn::sources {
namespace {

// Ticks of mrpt::Clock (100 ns) between 1601-01-01 (its epoch) and 1970-01-01.
constexpr std::int64_t kUnixEpochTicks = 116444736000000000LL;
constexpr double kTicksPerSecond = 1e7;

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
  const auto count = static_cast<std::int64_t>(t.time_since_epoch().count());
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();
  return static_cast<double>(count - kUnixEpochTicks) / kTicksPerSecond;
}

std::string ShortClassName(const char* mrpt_class_name) {
  if (mrpt_class_name == nullptr) return "(null)";
  const char* colon = std::strrchr(mrpt_class_name, ':');
  return colon != nullptr ? std::string(colon + 1) : std::string(mrpt_class_name);
}

}  // namespace cairn::sources
