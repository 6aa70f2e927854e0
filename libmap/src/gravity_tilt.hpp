// The kGravity tilt step (tilt_step.hpp), made by MakeTiltStep.
#pragma once

#include <memory>

#include "cairn/map/tilt_step.hpp"

namespace cairn::map {

/// `config` validated by the caller.
std::unique_ptr<TiltStep> MakeGravityTilt(const TiltConfig& config);

}  // namespace cairn::map
