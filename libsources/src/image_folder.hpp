// The frames of a folder of images placed by a TUM pose file, shared by the depth and the
// stereo folder sources (frame_source.hpp): which files, at which stamps, and the poses.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sources/trajectory.hpp"

namespace cairn::sources::internal {

struct ImageFolder {
  std::vector<std::filesystem::path> files;  ///< the .png files, sorted by name
  /// Per file: its name as a number (TUM RGB-D's "1305031102.160407.png") when every name
  /// is one, otherwise the k-th pose's stamp.
  std::vector<double> stamps;
  Trajectory trajectory;  ///< the TUM file's poses
};

/// Lists `dir`'s .png files and reads `poses`. Fails, naming the folder or the file, on no
/// images (`what` names them: "depth images"), unreadable poses, or unnamed images whose
/// count differs from the poses'.
Expected<ImageFolder> ListImageFolder(const std::filesystem::path& dir, const std::string& poses,
                                      const std::string& what);

}  // namespace cairn::sources::internal
