// Conversions between MRPT's types and cairn's: poses and times.
//
// Times: mrpt::Clock counts 100 ns ticks since 1601-01-01 (Windows FILETIME); cairn uses Unix
// seconds as double (about 0.2 us resolution today, finer than any sensor's clock).
#pragma once

#include <mrpt/core/Clock.h>
#include <mrpt/poses/CPose3D.h>

#include <Eigen/Geometry>
#include <string>

namespace cairn::sources {

/// Frame conversions between Eigen and MRPT poses (exact up to rounding).
::mrpt::poses::CPose3D ToCPose3D(const Eigen::Isometry3d& T);
Eigen::Isometry3d FromCPose3D(const ::mrpt::poses::CPose3D& pose);

/// Unix seconds <-> mrpt::Clock, to the 100 ns tick (rounded to nearest). FromMrptTime
/// gives NaN for MRPT's INVALID_TIMESTAMP (tick 0), which files use for "no time".
::mrpt::Clock::time_point ToMrptTime(double unix_s);
double FromMrptTime(::mrpt::Clock::time_point t);

/// An MRPT class name without its namespace: "CObservation3DRangeScan".
std::string ShortClassName(const char* mrpt_class_name);

}  // namespace cairn::sources
