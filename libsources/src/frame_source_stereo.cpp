// OpenStereoFolderFrames (frame_source.hpp): stereo pairs matched into depth, placed by a TUM
// pose file.
#include <filesystem>

#include "cairn/od/io/stereo_files.hpp"
#include "cairn/sources/frame_source.hpp"
#include "image_folder.hpp"
#include "stereo_pair_files.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

class StereoFolderFrames final : public FrameSource {
 public:
  StereoFolderFrames(std::string dir, std::string poses, internal::ImageFolder left,
                     od::StereoCalibration calibration, od::StereoConfig stereo)
      : dir_(std::move(dir)),
        poses_(std::move(poses)),
        left_(std::move(left)),
        calibration_(std::move(calibration)),
        stereo_(stereo) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    if (next_ >= left_.files.size()) return std::optional<SequenceFrame>();
    SequenceFrame out;
    out.index = static_cast<int>(next_);
    out.stamp_s = left_.stamps[next_];
    const fs::path& left_file = left_.files[next_];
    const fs::path right_file = fs::path(dir_) / "right" / left_file.filename();
    out.name = left_file.string();
    ++next_;
    Expected<BodyPose> pose = left_.trajectory.PoseAt(out.stamp_s);
    if (!pose) return Error{out.name + ": " + pose.error().message};
    out.T_world_body = out.T_world_sensor = pose->T_world_body;
    Expected<internal::MatchedPair> matched = internal::MatchStereoFiles(
        left_file.string(), right_file.string(), calibration_, stereo_, out.name);
    if (!matched) return matched.error();
    const Eigen::Vector3d up = out.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    Expected<od::RangeImage> image =
        od::RangeImage::FromDepth(matched->depth.depth_m.data, matched->pair.calibration.model, up);
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<SequenceFrame>(std::move(out));
  }

  Status Skip(int n) override {
    if (next_ + n > left_.files.size()) {
      return Error{dir_ + ": holds fewer pairs than the checkpoint fused"};
    }
    next_ += n;
    return {};
  }

  int total() const override { return static_cast<int>(left_.files.size()); }
  SourceInfo Describe() const override {
    return {{"kind", std::string("stereo_frames")},
            {"path", dir_},
            {"frames", std::int64_t{total()}},
            {"poses", poses_}};
  }
  const Trajectory& trajectory() const override { return left_.trajectory; }

 private:
  std::string dir_, poses_;
  internal::ImageFolder left_;
  od::StereoCalibration calibration_;
  od::StereoConfig stereo_;
  std::size_t next_ = 0;
};

}  // namespace

bool IsStereoFolder(const std::string& dir) {
  return fs::is_directory(fs::path(dir) / "left") && fs::is_directory(fs::path(dir) / "right");
}

Expected<std::unique_ptr<FrameSource>> OpenStereoFolderFrames(const std::string& dir,
                                                              const std::string& poses,
                                                              const std::string& calibration,
                                                              const od::StereoConfig& stereo) {
  if (!IsStereoFolder(dir)) return Error{dir + ": no left/ and right/ folders of stereo pairs"};
  if (Status st = stereo.Validate(); !st) return Error{"stereo: " + st.message()};
  Expected<internal::ImageFolder> left =
      internal::ListImageFolder(fs::path(dir) / "left", poses, "left images");
  if (!left) return left.error();
  for (const fs::path& f : left->files) {  // every pair whole before the first is matched
    const fs::path right = fs::path(dir) / "right" / f.filename();
    if (!fs::is_regular_file(right)) {
      return Error{right.string() +
                   ": missing: each left image needs the right image of the "
                   "same name"};
    }
  }
  const fs::path calibration_path =
      calibration.empty() ? fs::path(dir) / "stereo.yaml" : fs::path(calibration);
  Expected<od::StereoCalibration> rig = od::io::LoadStereoCalibration(calibration_path);
  if (!rig) return rig.error();
  return std::unique_ptr<FrameSource>(
      std::make_unique<StereoFolderFrames>(dir, poses, std::move(*left), *rig, stereo));
}

}  // namespace cairn::sources
