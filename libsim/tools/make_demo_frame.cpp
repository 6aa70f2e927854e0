// Writes the bundled demo frame: a synthetic cross-country scene seen by a 640x480 depth
// camera, with its ground truth.
//
//   cairn_make_demo_frame OUT_DIR
//
// OUT_DIR/depth.png       16-bit z-depth, depth_scale 0.001 m per unit, 0 = no return
// OUT_DIR/truth.png       8-bit object id per pixel: 0 terrain, 1..254 objects, 255 nothing
// OUT_DIR/intrinsics.yaml width, height, fx, fy, cx, cy, depth_scale, up
// OUT_DIR/truth.yaml      the objects: id, name, is_obstacle, height above ground
// Every file is written to a temporary name and renamed into place.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cairn/od/io/intrinsics.hpp"
#include "cairn/od/units.hpp"
#include "cairn/sim/camera.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"

namespace {

namespace fs = std::filesystem;
namespace sim = cairn::sim;
namespace util = cairn::util;
using cairn::Status;
using cairn::kDegToRad;
constexpr double kDepthScale = 0.001;  // m per unit in depth.png
constexpr int kNoHitLabel = 255;

struct DemoObject {
  int id;
  double height_m;  // above the ground at its centre
};

// The scene: gentle rolling hills, poles and trunks, rocks above and below 0.3 m, a mound
// whose steep face points sideways (towards the line of sight), and a bush that covers a
// tree trunk in the image while standing 6 m in front of it.
sim::Scene MakeScene(std::vector<DemoObject>& heights) {
  sim::Scene scene(sim::Terrain::Hills(
      0.0, {{0.35, 28.0, 0.3, 0.0}, {0.20, 14.0, 1.9, 1.0}, {0.06, 5.5, 0.9, 2.0}}));
  auto add = [&](int id, double h) { heights.push_back({id, h}); };
  // Obstacles stand farther apart than their reaches (min(height, Hmax) / tan(theta) for
  // the default HT 0.3 m, Hmax 1 m, theta 45 deg), so each is one segment of its own.
  add(scene.AddPole(7.0, -2.6, 0.05, 1.4, true, "pole"), 1.4);
  add(scene.AddPole(18.0, -6.0, 0.25, 5.0, true, "trunk"), 5.0);
  add(scene.AddPole(16.0, -1.6, 0.2, 4.0, true, "tree behind bush"), 4.0);
  add(scene.AddRock(10.0, -1.0, {0.55, 0.5, 0.45}, 0.75, 0.0, true, "bush"), 0.75);
  add(scene.AddRock(7.5, 0.2, {0.45, 0.35, 0.3}, 0.5, 0.4, true, "rock"), 0.5);
  add(scene.AddRock(12.5, -3.8, {0.6, 0.5, 0.4}, 0.65, -0.3, true, "rock"), 0.65);
  add(scene.AddRock(5.5, 0.9, {0.25, 0.2, 0.15}, 0.15, 0.2, false, "small rock"), 0.15);
  add(scene.AddRock(10.5, 1.0, {0.3, 0.3, 0.2}, 0.22, 0.0, false, "small rock"), 0.22);
  sim::Ridge mound;
  mound.base_centre = {11.0, 4.2, 0.0};
  mound.yaw_rad = 0.0;  // runs along the line of sight
  mound.top_length_m = 5.0;
  mound.top_width_m = 0.5;
  mound.height_m = 0.8;
  mound.right_slope_rad = 65.0 * kDegToRad;  // the steep face, turned towards the image centre
  mound.left_slope_rad = 20.0 * kDegToRad;
  mound.end_slope_rad = 18.0 * kDegToRad;
  add(scene.AddRidge(mound, true, "mound, steep side face"), 0.8);
  add(scene.AddBox(5.5, 2.0, {2.0, 0.3, 0.35}, -0.4, true, "log"), 0.35);
  return scene;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const fs::path out_dir = argv[1];
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) {
    std::fprintf(stderr, "cannot create %s: %s\n", out_dir.c_str(), ec.message().c_str());
    return 1;
  }

  std::vector<DemoObject> heights;
  const sim::Scene scene = MakeScene(heights);
  cairn::od::PinholeModel model;
  model.width = 640;
  model.height = 480;
  model.fx = model.fy = 525.0;
  model.cx = 319.5;
  model.cy = 239.5;
  const sim::Camera camera = sim::Camera::AboveGround(model, scene.terrain(), 0.0, 0.0, 1.6, 0.0,
                                                      8.0 * kDegToRad, 2.0 * kDegToRad);
  sim::RenderOptions options;
  options.max_range_m = 60.0;  // keeps every depth below 65.535 m, the PNG's limit
  const auto frame = sim::RenderDepth(scene, camera, options);
  if (!frame) {
    std::fprintf(stderr, "render failed: %s\n", frame.error().message.c_str());
    return 1;
  }

  cv::Mat depth(model.height, model.width, CV_16UC1);
  cv::Mat truth(model.height, model.width, CV_8UC1);
  for (int r = 0; r < model.height; ++r) {
    for (int c = 0; c < model.width; ++c) {
      const int i = r * model.width + c;
      depth.at<std::uint16_t>(r, c) =
          static_cast<std::uint16_t>(std::lround(frame->depth_m[i] / kDepthScale));
      const int id = frame->object_id[i];
      truth.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(id < 0 ? kNoHitLabel : id);
    }
  }

  char buf[512];

  std::string objects =
      "# Ground truth for truth.png: 0 = terrain, 255 = no return, else the object id.\n"
      "# height_m: top above the ground at the object's centre.\nobjects:\n";
  for (const DemoObject& d : heights) {
    const sim::Object* o = scene.Find(d.id);
    std::snprintf(buf, sizeof(buf), "  - {id: %d, name: \"%s\", is_obstacle: %s, height_m: %.2f}\n",
                  o->id, o->name.c_str(), o->is_obstacle ? "true" : "false", d.height_m);
    objects += buf;
  }

  for (const Status& s :
       {util::WriteImageAtomic(out_dir / "depth.png", depth, ".png", {cv::IMWRITE_PNG_COMPRESSION, 9}),
        util::WriteImageAtomic(out_dir / "truth.png", truth, ".png", {cv::IMWRITE_PNG_COMPRESSION, 9}),
        cairn::od::io::WriteIntrinsics(out_dir / "intrinsics.yaml",
                                       {model, kDepthScale, frame->up_optical},
                                       "Demo frame made by cairn_make_demo_frame "
                                       "(libsim/tools/make_demo_frame.cpp)."),
        util::WriteFileAtomic(out_dir / "truth.yaml", objects)}) {
    if (!s) {
      std::fprintf(stderr, "cairn_make_demo_frame: %s\n", s.message().c_str());
      return 1;
    }
  }
  std::printf("wrote %s/{depth.png, truth.png, intrinsics.yaml, truth.yaml}\n", out_dir.c_str());
  return 0;
}
