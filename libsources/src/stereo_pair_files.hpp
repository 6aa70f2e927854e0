// One stereo pair read from its two image files and matched with a rig already loaded:
// shared by ReadStereoFrame (file_frame.hpp) and the stereo folder source.
#pragma once

#include <string>

#include "cairn/od/expected.hpp"
#include "cairn/od/stereo.hpp"

namespace cairn::sources::internal {

struct MatchedPair {
  od::StereoPair pair;    ///< rectified
  od::StereoDepth depth;  ///< of the left camera
  double matching_s = 0.0;
};

/// Reads both images (errors name the file), rectifies them with `rig` when it is of raw
/// cameras, and matches them with `stereo`; a failed matching is named by `failure_prefix`.
Expected<MatchedPair> MatchStereoFiles(const std::string& left, const std::string& right,
                                       const od::StereoCalibration& rig,
                                       const od::StereoConfig& stereo,
                                       const std::string& failure_prefix);

}  // namespace cairn::sources::internal
