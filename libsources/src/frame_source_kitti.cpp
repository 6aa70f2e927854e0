// OpenKittiFrames (frame_source.hpp): velodyne scans placed by poses.txt; scans that should
// be there and are not, or hold no whole point, come back skipped with their reason.
#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <set>
#include <sstream>
#include <system_error>

#include "cairn/od/io/kitti.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/sources/frame_source.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

constexpr std::uintmax_t kKittiPointBytes = 16;  // x, y, z, reflectance as float32

class KittiFrames final : public FrameSource {
 public:
  KittiFrames(od::io::KittiSequence sequence, std::vector<od::io::KittiFrame> selected,
              std::set<int> missing, Trajectory trajectory, od::LayoutOptions layout,
              std::string lidar)
      : sequence_(std::move(sequence)),
        selected_(std::move(selected)),
        missing_(std::move(missing)),
        trajectory_(std::move(trajectory)),
        layout_(std::move(layout)),
        lidar_(std::move(lidar)) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    if (next_ >= selected_.size()) return std::optional<SequenceFrame>();
    const od::io::KittiFrame& k = selected_[next_];
    SequenceFrame out;
    out.index = static_cast<int>(next_++);
    out.stamp_s = k.stamp_s;
    out.name = k.scan.string();
    if (missing_.count(k.index) != 0) {
      out.skip = SourceSkip::kMissing;
      out.skip_detail = "no such file (poses.txt and the scans around it list it)";
      return std::optional<SequenceFrame>(std::move(out));
    }
    std::error_code ec;
    const std::uintmax_t bytes = fs::file_size(k.scan, ec);
    if (!ec && (bytes == 0 || bytes % kKittiPointBytes != 0)) {
      out.skip = SourceSkip::kTruncated;
      out.skip_detail = std::to_string(bytes) + " bytes, not a whole number of " +
                        std::to_string(kKittiPointBytes) + "-byte points";
      return std::optional<SequenceFrame>(std::move(out));
    }
    Expected<BodyPose> pose = trajectory_.PoseAt(k.stamp_s);
    if (!pose) return Error{out.name + ": " + pose.error().message};
    out.T_world_body = out.T_world_sensor = pose->T_world_body;
    Expected<od::PointCloud> cloud = od::io::ReadKittiBin(k.scan);
    if (!cloud) return cloud.error();
    Expected<od::FoundLayout> layout = od::FindLayout(*cloud, layout_, out.name);
    if (!layout) return layout.error();
    const Eigen::Vector3d up = out.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    Expected<od::RangeImage> image =
        od::RangeImage::FromPoints(cloud->points, layout->model, up, layout->rows, layout->cols);
    if (!image) return Error{out.name + ": " + image.error().message};
    out.image = std::move(*image);
    return std::optional<SequenceFrame>(std::move(out));
  }

  Status Skip(int n) override {
    if (next_ + n > selected_.size()) {
      return Error{sequence_.folder.string() + ": holds fewer scans than the checkpoint fused"};
    }
    next_ += n;
    return {};
  }

  int total() const override { return static_cast<int>(selected_.size()); }
  SourceInfo Describe() const override {
    return {{"kind", std::string("kitti")},
            {"path", sequence_.folder.string()},
            {"lidar", lidar_},
            {"frames", std::int64_t{total()}},
            {"poses", trajectory_.source()}};
  }
  const Trajectory& trajectory() const override { return trajectory_; }

 private:
  od::io::KittiSequence sequence_;
  std::vector<od::io::KittiFrame> selected_;  // with the missing scans
  std::set<int> missing_;                     // their indices
  Trajectory trajectory_;
  od::LayoutOptions layout_;
  std::string lidar_;
  std::size_t next_ = 0;
};

std::string ScanName(int index) {
  std::ostringstream name;
  name << std::setw(6) << std::setfill('0') << index << ".bin";
  return name.str();
}

}  // namespace

Expected<std::unique_ptr<FrameSource>> OpenKittiFrames(const std::string& dir,
                                                       const std::string& sequence,
                                                       const std::string& range,
                                                       const std::string& lidar) {
  fs::path folder = dir;
  if (!sequence.empty()) {
    folder = fs::path(dir) / "sequences" / sequence;
    if (!fs::is_directory(folder)) {
      return Error{folder.string() +
                   ": no such sequence folder (--kitti DIR --sequence NN reads DIR/sequences/NN)"};
    }
  }
  Expected<od::io::KittiSequence> opened = od::io::OpenKittiSequence(folder);
  if (!opened) return opened.error();
  Expected<Trajectory> trajectory = Trajectory::FromKitti(*opened);
  if (!trajectory) return trajectory.error();
  // The scans the sequence should hold: one per line of poses.txt (as far as times.txt
  // goes), and every index up to the highest scan there is.
  int expected = opened->frames.back().index + 1;
  Expected<std::vector<double>> times = od::io::ReadKittiTimes(folder / "times.txt");
  if (!times) return times.error();
  if (opened->has_poses) {
    Expected<std::vector<Eigen::Isometry3d>> poses = od::io::ReadKittiPoses(folder / "poses.txt");
    if (!poses) return poses.error();
    expected = std::max(expected, static_cast<int>(std::min(poses->size(), times->size())));
  }
  od::io::KittiSequence listed = *opened;  // with the missing scans, for the selection
  std::set<int> missing;
  listed.frames.clear();
  std::size_t next = 0;
  for (int index = 0; index < expected; ++index) {
    if (next < opened->frames.size() && opened->frames[next].index == index) {
      listed.frames.push_back(opened->frames[next++]);
      continue;
    }
    od::io::KittiFrame absent;
    absent.index = index;
    absent.stamp_s = (*times)[static_cast<std::size_t>(index)];
    absent.scan = folder / "velodyne" / ScanName(index);
    listed.frames.push_back(absent);
    missing.insert(index);
  }
  std::vector<od::io::KittiFrame> selected = listed.frames;
  if (!range.empty()) {
    Expected<std::vector<od::io::KittiFrame>> in_range = od::io::SelectKittiFrames(listed, range);
    if (!in_range) return Error{"--range: " + in_range.error().message};
    selected = std::move(*in_range);
  }
  Expected<od::SphericalModel> preset = od::SphericalModel::Preset(lidar);
  if (!preset) return Error{"--lidar: " + preset.error().message};
  od::LayoutOptions layout;
  layout.preset = *preset;
  return std::unique_ptr<FrameSource>(
      std::make_unique<KittiFrames>(std::move(*opened), std::move(selected), std::move(missing),
                                    std::move(*trajectory), std::move(layout), lidar));
}

}  // namespace cairn::sources
