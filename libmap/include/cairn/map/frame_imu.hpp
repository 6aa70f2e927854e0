// A recorded frame's IMU readings (cairn::sources) as the Mapper takes them (imu.hpp).
#pragma once

#include <vector>

#include "cairn/map/imu.hpp"
#include "cairn/sources/frame_source.hpp"

namespace cairn::map {

/// The frame's IMU readings, by stamp: each attitude, and each raw sample with both an
/// accelerometer and a gyro reading, rotated from the IMU's frame into the body's (the IMU's
/// lever arm is not modelled).
std::vector<ImuSample> ImuSamplesOf(const sources::SequenceFrame& frame);

}  // namespace cairn::map
