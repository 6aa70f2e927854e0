// sources::OpenStereoFolderFrames: rendered stereo pairs written as left/ and right/ PNGs
// with their TUM poses and the rig's stereo.yaml come back as frames at their poses, each
// range image the one matching that pair gives, close to the rendered truth; a left image
// without its right one and a missing calibration are named. And single files
// (file_frame.hpp): one pair, one depth image, each as a source of one frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <vector>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/io/stereo_files.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/stereo.hpp"
#include "cairn/sources/file_frame.hpp"
#include "cairn/sources/frame_source.hpp"
#include "io/cairn_command.hpp"
#include "io/temp_dir.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

struct WrittenFolder {
  std::vector<StampedPose> poses;  ///< the left camera's
  std::vector<sim::DepthFrame> truth;
  od::PinholeModel model;
  double baseline_m = 0.3;
};

/// Three pairs along x through a field of textured obstacles, named by their stamps.
WrittenFolder WriteStereoFolder(const fs::path& dir) {
  sim::Scene scene(sim::Terrain::Plane(0.0, Eigen::Vector2d(0.01, 0.02)));
  scene.AddPole(9, 1.5, 0.15, 1.5, true);
  scene.AddRock(7, -1.5, {0.6, 0.5, 0.5}, 0.6, 0.3, true);
  scene.AddBox(15, 2, {1, 1, 1}, 0.5, true);
  sim::StereoRigSpec rig;
  rig.model.width = 320;
  rig.model.height = 240;
  rig.model.fx = rig.model.fy = 256.0;
  rig.model.cx = 159.5;
  rig.model.cy = 119.5;
  rig.baseline_m = 0.3;
  rig.image.supersampling = 2;
  WrittenFolder out;
  out.model = rig.model;
  fs::create_directories(dir / "left");
  fs::create_directories(dir / "right");
  for (int k = 0; k < 3; ++k) {
    const sim::Camera camera = sim::Camera::AboveGround(rig.model, scene.terrain(), 1.0 * k, 0.0,
                                                        1.5, 0.0, 8 * kDegToRad, 0.0);
    Expected<sim::StereoFrame> frame = sim::RenderStereoPair(scene, camera, rig, 5 + k);
    EXPECT_TRUE(frame.ok()) << frame.error().message;
    if (!frame) return out;
    const double stamp = 1700000000.0 + 0.5 * k;
    char name[64];
    std::snprintf(name, sizeof name, "%.6f.png", stamp);
    const auto grey = [](const sim::GreyImage& g) {
      return od::GreyImage{g.width, g.height, g.data};
    };
    EXPECT_TRUE(od::io::WriteGreyPng(dir / "left" / name, grey(frame->left)).ok());
    EXPECT_TRUE(od::io::WriteGreyPng(dir / "right" / name, grey(frame->right)).ok());
    out.poses.push_back({stamp, camera.T_world_camera});
    out.truth.push_back(frame->left_truth);
  }
  EXPECT_TRUE(WriteTumPoses(dir / "poses.tum", out.poses, "test").ok());
  std::ofstream(dir / "stereo.yaml") << "width: 320\nheight: 240\nfx: 256\ncx: 159.5\ncy: 119.5\n"
                                        "baseline: 0.3\n";
  return out;
}

TEST(StereoFolderFrames, EachPairComesBackMatchedAtItsPose) {
  test::TempDir dir;
  const WrittenFolder written = WriteStereoFolder(dir.path());
  ASSERT_EQ(written.poses.size(), 3u);
  ASSERT_TRUE(IsStereoFolder(dir.path().string()));
  od::StereoConfig stereo;
  stereo.min_depth_m = 2.0;
  Expected<std::unique_ptr<FrameSource>> source =
      OpenStereoFolderFrames(dir.path().string(), (dir.path() / "poses.tum").string(), "", stereo);
  ASSERT_TRUE(source.ok()) << source.error().message;
  EXPECT_EQ((*source)->total(), 3);
  EXPECT_EQ(std::get<std::string>((*source)->Describe().at("kind")), "stereo_frames");
  for (int k = 0; k < 3; ++k) {
    Expected<std::optional<SequenceFrame>> frame = (*source)->Next();
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    ASSERT_TRUE(frame->has_value());
    const SequenceFrame& f = **frame;
    EXPECT_EQ(f.index, k);
    EXPECT_NEAR(f.stamp_s, written.poses[k].stamp_s, 1e-6);
    EXPECT_TRUE(f.T_world_sensor.isApprox(written.poses[k].T_world_x, 1e-6));

    // The range image is the one matching the pair gives, levelled with the pose's up.
    const std::string name = fs::path(f.name).filename().string();
    Expected<od::GreyImage> left = od::io::ReadGreyImage(dir.path() / "left" / name);
    Expected<od::GreyImage> right = od::io::ReadGreyImage(dir.path() / "right" / name);
    ASSERT_TRUE(left.ok() && right.ok());
    Expected<od::StereoPair> pair = od::PrepareStereoPair(
        std::move(*left), std::move(*right), od::StereoCalibration{written.model, 0.3});
    ASSERT_TRUE(pair.ok()) << pair.error().message;
    Expected<od::StereoDepth> depth = od::ComputeStereoDepth(*pair, stereo);
    ASSERT_TRUE(depth.ok()) << depth.error().message;
    const Eigen::Vector3d up = f.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    Expected<od::RangeImage> expected =
        od::RangeImage::FromDepth(depth->depth_m.data, written.model, up);
    ASSERT_TRUE(expected.ok());
    ASSERT_EQ(f.image.size(), expected->size());
    int valid = 0;
    std::vector<double> relative_error;
    for (int i = 0; i < f.image.size(); ++i) {
      ASSERT_EQ(f.image.valid(i), expected->valid(i)) << "pixel " << i;
      if (!f.image.valid(i)) continue;
      ++valid;
      ASSERT_EQ(f.image.point(i), expected->point(i)) << "pixel " << i;
      const double z_true = written.truth[k].depth_m[i];
      if (z_true > 0.0) {
        relative_error.push_back(std::abs(f.image.point(i).z() - z_true) / z_true);
      }
    }
    // Against the rendered truth: most pixels matched, the typical depth within 2 %.
    EXPECT_GT(valid, f.image.size() / 2);
    ASSERT_FALSE(relative_error.empty());
    std::nth_element(relative_error.begin(), relative_error.begin() + relative_error.size() / 2,
                     relative_error.end());
    EXPECT_LT(relative_error[relative_error.size() / 2], 0.02);
  }
  Expected<std::optional<SequenceFrame>> end = (*source)->Next();
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(end->has_value());
}

TEST(StereoFolderFrames, AMissingRightImageOrCalibrationIsNamed) {
  test::TempDir dir;
  const WrittenFolder written = WriteStereoFolder(dir.path());
  ASSERT_EQ(written.poses.size(), 3u);
  const std::string poses = (dir.path() / "poses.tum").string();
  std::vector<fs::path> right;
  for (const fs::directory_entry& e : fs::directory_iterator(dir.path() / "right")) {
    right.push_back(e.path());
  }
  std::sort(right.begin(), right.end());
  fs::remove(right[1]);
  Expected<std::unique_ptr<FrameSource>> missing =
      OpenStereoFolderFrames(dir.path().string(), poses, "", od::StereoConfig{});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find(right[1].string() + ": missing"), std::string::npos)
      << missing.error().message;

  fs::copy_file(dir.path() / "left" / right[1].filename(), right[1]);
  fs::remove(dir.path() / "stereo.yaml");
  Expected<std::unique_ptr<FrameSource>> uncalibrated =
      OpenStereoFolderFrames(dir.path().string(), poses, "", od::StereoConfig{});
  ASSERT_FALSE(uncalibrated.ok());
  EXPECT_NE(uncalibrated.error().message.find("stereo.yaml"), std::string::npos)
      << uncalibrated.error().message;
  EXPECT_FALSE(IsStereoFolder((dir.path() / "left").string()));
}

// One pair read as single files is matched as the folder source matches it; as a source of
// one frame it is placed with the level camera's up (the calibration gives none) on z.
TEST(FileFrames, OnePairIsMatchedAsItsFolderMatchesIt) {
  test::TempDir dir;
  const WrittenFolder written = WriteStereoFolder(dir.path());
  ASSERT_EQ(written.poses.size(), 3u);
  od::StereoConfig stereo;
  stereo.min_depth_m = 2.0;
  Expected<std::unique_ptr<FrameSource>> folder =
      OpenStereoFolderFrames(dir.path().string(), (dir.path() / "poses.tum").string(), "", stereo);
  ASSERT_TRUE(folder.ok()) << folder.error().message;
  Expected<std::optional<SequenceFrame>> first = (*folder)->Next();
  ASSERT_TRUE(first.ok() && first->has_value());
  const std::string name = fs::path((*first)->name).filename().string();
  Expected<FileFrame> file =
      ReadStereoFrame((dir.path() / "left" / name).string(), (dir.path() / "right" / name).string(),
                      (dir.path() / "stereo.yaml").string(), stereo, "test settings");
  ASSERT_TRUE(file.ok()) << file.error().message;
  EXPECT_FALSE(file->up_given);
  EXPECT_FALSE(file->rectified_here);
  ASSERT_TRUE(file->stereo.has_value());
  ASSERT_EQ(static_cast<int>(file->depth_m.data.size()), (*first)->image.size());
  for (int i = 0; i < (*first)->image.size(); ++i) {
    const bool valid = (*first)->image.valid(i);
    ASSERT_EQ(valid, file->depth_m.data[i] > 0.0f) << "pixel " << i;
    if (valid) {
      ASSERT_FLOAT_EQ((*first)->image.point(i).z(), file->depth_m.data[i]) << "pixel " << i;
    }
  }
  const int valid_points = file->image.valid_count();
  FileFrame level_less = *file;  // a frame without a usable up vector is refused
  level_less.up = Eigen::Vector3d::Zero();
  EXPECT_FALSE(OneFrameSource(std::move(level_less)).ok());
  Expected<std::unique_ptr<FrameSource>> source = OneFrameSource(std::move(*file));
  ASSERT_TRUE(source.ok()) << source.error().message;
  FrameSource* one = source->get();
  EXPECT_EQ(one->total(), 1);
  Expected<std::optional<SequenceFrame>> only = one->Next();
  ASSERT_TRUE(only.ok() && only->has_value());
  EXPECT_EQ((*only)->image.valid_count(), valid_points);
  const Eigen::Vector3d up =
      (*only)->T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_TRUE(up.isApprox(Eigen::Vector3d(0.0, -1.0, 0.0), 1e-12));
  Expected<std::optional<SequenceFrame>> end = one->Next();
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(end->has_value());

  // A failed matching names the calibration and the settings.
  od::StereoConfig too_near = stereo;
  too_near.min_depth_m = 0.05;
  Expected<FileFrame> bad =
      ReadStereoFrame((dir.path() / "left" / name).string(), (dir.path() / "right" / name).string(),
                      (dir.path() / "stereo.yaml").string(), too_near, "test settings");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("stereo.yaml / test settings: "), std::string::npos)
      << bad.error().message;
}

// The bundled demo depth frame read as single files: the range image od_io's readers and
// RangeImage::FromDepth make, levelled with the camera YAML's up.
TEST(FileFrames, TheDemoDepthFrameIsItsRangeImage) {
  const fs::path demo = fs::path(CAIRN_SOURCE_DIR) / "datasets" / "frames" / "demo";
  Expected<FileFrame> file =
      ReadDepthFrame((demo / "depth.png").string(), (demo / "intrinsics.yaml").string());
  ASSERT_TRUE(file.ok()) << file.error().message;
  Expected<od::io::CameraIntrinsics> camera = od::io::LoadIntrinsics(demo / "intrinsics.yaml");
  ASSERT_TRUE(camera.ok());
  Expected<od::Grid<float>> depth = od::io::ReadDepthImage(demo / "depth.png", *camera);
  ASSERT_TRUE(depth.ok());
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(depth->data, camera->model, camera->up);
  ASSERT_TRUE(image.ok());
  ASSERT_EQ(file->image.size(), image->size());
  EXPECT_EQ(file->image.valid_count(), image->valid_count());
  for (int i = 0; i < image->size(); ++i) {
    ASSERT_EQ(file->image.valid(i), image->valid(i));
    if (image->valid(i)) {
      ASSERT_EQ(file->image.point(i), image->point(i));
    }
  }
  EXPECT_TRUE(file->up.isApprox(camera->up));
  Expected<FileFrame> missing =
      ReadDepthFrame((demo / "nothing.png").string(), (demo / "intrinsics.yaml").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("nothing.png"), std::string::npos);
}

#ifdef CAIRN_EXE
// `cairn map --frames DIR` on a stereo folder: the pairs are matched with the settings'
// stereo section and fused; the summary names the kind of input.
TEST(StereoFolderFrames, CairnMapFusesAStereoFolder) {
  test::TempDir dir;
  const WrittenFolder written = WriteStereoFolder(dir.path() / "pairs");
  ASSERT_EQ(written.poses.size(), 3u);
  const fs::path out = dir.path() / "map";
  const test::CommandResult run = test::RunProgram(
      CAIRN_EXE, {"map", "--frames", (dir.path() / "pairs").string(), "--poses",
                  (dir.path() / "pairs" / "poses.tum").string(), "--out", out.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const std::string summary = test::ReadFile(out / "summary.json");
  EXPECT_NE(summary.find("\"stereo_frames\""), std::string::npos) << summary;
  EXPECT_NE(run.output.find("3 frames from"), std::string::npos) << run.output;
  EXPECT_TRUE(fs::exists(out / "cost.pgm"));
  // Without the calibration: exit 1 naming the file, and no output folder.
  fs::remove(dir.path() / "pairs" / "stereo.yaml");
  const test::CommandResult bad =
      test::RunProgram(CAIRN_EXE, {"map", "--frames", (dir.path() / "pairs").string(), "--poses",
                                   (dir.path() / "pairs" / "poses.tum").string(), "--out",
                                   (dir.path() / "map2").string()});
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("stereo.yaml"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(dir.path() / "map2"));
}
#endif  // CAIRN_EXE

}  // namespace
}  // namespace cairn::sources
