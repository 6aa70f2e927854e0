#include "cairn/sources/file_frame.hpp"

#include <chrono>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/point_cloud.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "stereo_pair_files.hpp"

namespace cairn::sources {
namespace {

class OneFrame final : public FrameSource {
 public:
  OneFrame(FileFrame frame, Trajectory trajectory)
      : frame_(std::move(frame)), trajectory_(std::move(trajectory)) {}

  Expected<std::optional<SequenceFrame>> Next() override {
    if (taken_) return std::optional<SequenceFrame>();
    taken_ = true;
    SequenceFrame out;
    out.index = 0;
    out.stamp_s = 0.0;
    out.name = frame_.name;
    out.T_world_body = out.T_world_sensor = Placed(frame_.up);
    out.image = std::move(frame_.image);
    return std::optional<SequenceFrame>(std::move(out));
  }
  Status Skip(int n) override {
    if (n > (taken_ ? 0 : 1)) return Error{frame_.name + ": holds one frame"};
    taken_ = taken_ || n == 1;
    return {};
  }
  int total() const override { return 1; }
  SourceInfo Describe() const override {
    return {{"kind", std::string("file")}, {"path", frame_.name}, {"frames", std::int64_t{1}}};
  }
  const Trajectory& trajectory() const override { return trajectory_; }

  /// A pose at the origin whose rotation takes the sensor's `up` to the world's z.
  static Eigen::Isometry3d Placed(const Eigen::Vector3d& up) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond::FromTwoVectors(up.normalized(), Eigen::Vector3d::UnitZ())
                     .toRotationMatrix();
    return T;
  }

 private:
  FileFrame frame_;
  Trajectory trajectory_;
  bool taken_ = false;
};

}  // namespace

Expected<FileFrame> ReadDepthFrame(const std::string& depth, const std::string& intrinsics) {
  Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(intrinsics);
  if (!camera) return camera.error();
  Expected<od::Grid<float>> depth_m = od::io::ReadDepthImage(depth, *camera);
  if (!depth_m) return depth_m.error();
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(depth_m->data, camera->model, camera->up);
  if (!image) return Error{depth + ": " + image.error().message};
  FileFrame out;
  out.name = depth;
  out.image = std::move(*image);
  out.up = camera->up;
  out.depth_m = std::move(*depth_m);
  out.model = camera->model;
  return out;
}

Expected<FileFrame> ReadScanFrame(const std::string& points, const od::LayoutOptions& layout,
                                  const Eigen::Vector3d& up) {
  Expected<od::PointCloud> cloud = od::io::ReadPointFile(points);
  if (!cloud) return cloud.error();
  Expected<od::PlacedScan> placed = od::PlaceScan(*cloud, layout, up, points);
  if (!placed) return placed.error();
  FileFrame out;
  out.name = points;
  out.image = std::move(placed->image);
  out.up = up;
  out.cloud = std::move(*cloud);
  out.layout = std::move(placed->layout);
  return out;
}

namespace internal {

Expected<MatchedPair> MatchStereoFiles(const std::string& left, const std::string& right,
                                       const od::StereoCalibration& rig,
                                       const od::StereoConfig& stereo,
                                       const std::string& failure_prefix) {
  Expected<od::GreyImage> left_image = od::io::ReadGreyImage(left);
  if (!left_image) return left_image.error();
  Expected<od::GreyImage> right_image = od::io::ReadGreyImage(right);
  if (!right_image) return right_image.error();
  Expected<od::StereoPair> pair =
      od::PrepareStereoPair(std::move(*left_image), std::move(*right_image), rig, left, right);
  if (!pair) return pair.error();
  const auto start = std::chrono::steady_clock::now();
  Expected<od::StereoDepth> depth = od::ComputeStereoDepth(*pair, stereo);
  if (!depth) return Error{failure_prefix + ": " + depth.error().message};
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return MatchedPair{std::move(*pair), std::move(*depth), seconds};
}

}  // namespace internal

Expected<FileFrame> ReadStereoFrame(const std::string& left, const std::string& right,
                                    const std::string& calibration, const od::StereoConfig& stereo,
                                    const std::string& settings_name) {
  Expected<od::StereoCalibration> rig = od::io::LoadStereoCalibration(calibration);
  if (!rig) return rig.error();
  Expected<internal::MatchedPair> matched = internal::MatchStereoFiles(
      left, right, *rig, stereo, calibration + " / " + settings_name);
  if (!matched) return matched.error();
  FileFrame out;
  out.name = left + " + " + right;
  out.rectified_here = rig->rectification.has_value();
  out.matching_s = matched->matching_s;
  // Without an up vector in the calibration the camera is taken to be level: heights are
  // then measured along the image's -y axis.
  out.up_given = matched->pair.calibration.up.has_value();
  out.up = out.up_given ? *matched->pair.calibration.up : Eigen::Vector3d(0.0, -1.0, 0.0);
  out.model = matched->pair.calibration.model;
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(matched->depth.depth_m.data, out.model, out.up);
  if (!image) return Error{left + ": " + image.error().message};
  out.image = std::move(*image);
  out.depth_m = matched->depth.depth_m;
  out.pair = std::move(matched->pair);
  out.stereo = std::move(matched->depth);
  return out;
}

Expected<std::unique_ptr<FrameSource>> OneFrameSource(FileFrame frame) {
  if (!frame.up.allFinite() || frame.up.norm() == 0.0) {
    return Error{frame.name + ": the up vector must be finite and not zero"};
  }
  StampedPose pose;
  pose.stamp_s = 0.0;
  pose.T_world_x = OneFrame::Placed(frame.up);
  Expected<Trajectory> trajectory = Trajectory::FromPoses({pose}, frame.name);
  if (!trajectory) return trajectory.error();
  return std::unique_ptr<FrameSource>(
      std::make_unique<OneFrame>(std::move(frame), std::move(*trajectory)));
}

}  // namespace cairn::sources
