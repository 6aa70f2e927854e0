// OpenRawlogFrames: an MRPT rawlog as a FrameSource (frame_source.hpp). A first pass gathers
// the odometry and IMU (and checks the whole file), a second decodes the range frames one at
// a time (stereo pairs are matched with the given StereoConfig).
#pragma once

#include <memory>
#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/stereo.hpp"
#include "cairn/sources/frame_source.hpp"

namespace cairn::sources {

/// An MRPT rawlog's range frames (of sensor `label`, or every one when empty). Fails, naming
/// the file, when it cannot be read to its end, holds no range frames (of that label: the
/// labels it holds are named) or no odometry.
Expected<std::unique_ptr<FrameSource>> OpenRawlogFrames(const std::string& path,
                                                        const std::string& label,
                                                        const od::StereoConfig& stereo);

}  // namespace cairn::sources
