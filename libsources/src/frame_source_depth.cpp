// OpenDepthFolderFrames (frame_source.hpp): depth PNGs placed by a TUM pose file.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/sources/frame_source.hpp"
#include "image_folder.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

class DepthFolderFrames final : public FrameSource {
 public:
  DepthFolderFrames(std::string dir, std::string poses, std::vector<fs::path> files,
                    std::vector<double> stamps, od::io::CameraIntrinsics camera,
                    Trajectory trajectory)
      : dir_(std::move(dir)),
        poses_(std::move(poses)),
        files_(std::move(files)),
        stamps_(std::move(stamps)),
        camera_(std::move(camera)),
        trajectory_(std::move(trajectory)) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    if (next_ >= files_.size()) return std::optional<SequenceFrame>();
    SequenceFrame out;
    out.index = static_cast<int>(next_);
    out.stamp_s = stamps_[next_];
    out.name = files_[next_].string();
    ++next_;
    Expected<BodyPose> pose = trajectory_.PoseAt(out.stamp_s);
    if (!pose) return Error{out.name + ": " + pose.error().message};
    out.T_world_body = out.T_world_sensor = pose->T_world_body;
    Expected<od::Grid<float>> depth = od::io::ReadDepthPng(out.name, camera_);
    if (!depth) return depth.error();
    const Eigen::Vector3d up = out.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    Expected<od::RangeImage> image = od::RangeImage::FromDepth(depth->data, camera_.model, up);
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<SequenceFrame>(std::move(out));
  }

  Status Skip(int n) override {
    if (next_ + n > files_.size()) {
      return Error{dir_ + ": holds fewer images than the checkpoint fused"};
    }
    next_ += n;
    return {};
  }

  int total() const override { return static_cast<int>(files_.size()); }
  SourceInfo Describe() const override {
    return {{"kind", std::string("depth_frames")},
            {"path", dir_},
            {"frames", std::int64_t{total()}},
            {"poses", poses_}};
  }
  const Trajectory& trajectory() const override { return trajectory_; }

 private:
  std::string dir_, poses_;
  std::vector<fs::path> files_;
  std::vector<double> stamps_;
  od::io::CameraIntrinsics camera_;
  Trajectory trajectory_;
  std::size_t next_ = 0;
};

}  // namespace

namespace internal {

Expected<ImageFolder> ListImageFolder(const fs::path& dir, const std::string& poses,
                                      const std::string& what) {
  std::vector<fs::path> files;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && e.path().extension() == ".png") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) return Error{dir.string() + ": no .png " + what + " (--frames)"};
  Expected<std::vector<StampedPose>> tum = ReadTumPoses(poses);
  if (!tum) return tum.error();
  Expected<Trajectory> trajectory = Trajectory::FromPoses(*tum, poses);
  if (!trajectory) return trajectory.error();
  // Stamps from the names, when every name is a number.
  std::vector<double> stamps;
  bool named_by_stamp = true;
  for (const fs::path& f : files) {
    const std::string stem = f.stem().string();
    char* end = nullptr;
    const double stamp = std::strtod(stem.c_str(), &end);
    if (stem.empty() || end != stem.c_str() + stem.size() || !std::isfinite(stamp)) {
      named_by_stamp = false;
      break;
    }
    stamps.push_back(stamp);
  }
  if (!named_by_stamp) {
    stamps.clear();
    if (tum->size() != files.size()) {
      return Error{dir.string() + ": " + std::to_string(files.size()) + " " + what +
                   " not named by their stamps, but " + poses + " holds " +
                   std::to_string(tum->size()) + " poses (the k-th image takes the k-th pose)"};
    }
    for (const StampedPose& p : *tum) stamps.push_back(p.stamp_s);
  }
  return ImageFolder{std::move(files), std::move(stamps), std::move(*trajectory)};
}

}  // namespace internal

Expected<std::unique_ptr<FrameSource>> OpenDepthFolderFrames(const std::string& dir,
                                                             const std::string& poses,
                                                             const std::string& intrinsics) {
  if (!fs::is_directory(dir)) return Error{dir + ": no such folder (--frames)"};
  const fs::path intrinsics_path =
      intrinsics.empty() ? fs::path(dir) / "intrinsics.yaml" : fs::path(intrinsics);
  Expected<internal::ImageFolder> folder = internal::ListImageFolder(dir, poses, "depth images");
  if (!folder) return folder.error();
  Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(intrinsics_path);
  if (!camera) return camera.error();
  return std::unique_ptr<FrameSource>(std::make_unique<DepthFolderFrames>(
      dir, poses, std::move(folder->files), std::move(folder->stamps), *camera,
      std::move(folder->trajectory)));
}

const char* SourceSkipName(SourceSkip skip) {
  switch (skip) {
    case SourceSkip::kNone:
      return "none";
    case SourceSkip::kMissing:
      return "missing";
    case SourceSkip::kTruncated:
      return "truncated";
  }
  return "?";
}

}  // namespace cairn::sources
