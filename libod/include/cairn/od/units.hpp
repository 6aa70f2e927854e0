// Angles: the one definition of pi and of the degree conversions for every cairn library,
// app, test and benchmark. Configs and files speak degrees; the code works in radians.
#pragma once

namespace cairn {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDegToRad = kPi / 180.0;  ///< degrees -> radians
inline constexpr double kRadToDeg = 180.0 / kPi;  ///< radians -> degrees

}  // namespace cairn
