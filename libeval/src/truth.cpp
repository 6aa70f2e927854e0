#include "cairn/eval/truth.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <utility>

#include "cairn/od/io/depth_png.hpp"
#include "cairn/od/io/intrinsics.hpp"
#include "cairn/sim/geometry.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::eval {
namespace {

constexpr int kNoReturnLabel8 = 255;     ///< "no return" in an 8-bit truth.png
constexpr int kNoReturnLabel16 = 65535;  ///< .. and in a 16-bit one

bool ValidDepth(float d) { return std::isfinite(d) && d > 0.0f; }

std::string At(std::size_t index, int width) {
  return "row " + std::to_string(index / width) + ", col " + std::to_string(index % width);
}

using util::Describe;

Expected<std::vector<TruthObject>> ParseObjects(const std::filesystem::path& path) {
  const std::string file = path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    return Error{file + ": cannot open for reading"};
  } catch (const YAML::Exception& e) {
    return Error{file + ":" + std::to_string(e.mark.line + 1) + ":" +
                 std::to_string(e.mark.column + 1) + ": invalid YAML: " + e.msg};
  }
  if (!root.IsMap()) return Error{file + ": expected a mapping with an 'objects' list"};
  for (const auto& entry : root) {
    const std::string key = entry.first.Scalar();
    if (key != "objects") return Error{file + ": " + key + ": unknown key (expected objects)"};
  }
  const YAML::Node list = root["objects"];
  if (!list || !(list.IsSequence() || list.IsNull())) {
    return Error{file + ": objects: expected a list of {id, name, is_obstacle}"};
  }
  std::vector<TruthObject> objects;
  for (std::size_t i = 0; list.IsSequence() && i < list.size(); ++i) {
    const YAML::Node item = list[i];
    const std::string where = file + ": objects[" + std::to_string(i) + "]";
    if (!item.IsMap()) return Error{where + ": expected a mapping, got " + Describe(item)};
    for (const auto& entry : item) {
      const std::string key = entry.first.Scalar();
      if (key != "id" && key != "name" && key != "is_obstacle" && key != "height_m") {
        return Error{where + "." + key +
                     ": unknown key (expected id, name, is_obstacle, height_m)"};
      }
    }
    TruthObject object;
    try {
      if (!item["id"]) return Error{where + ".id: missing"};
      object.id = item["id"].as<int>();
    } catch (const YAML::Exception&) {
      return Error{where + ".id: expected an integer, got " + Describe(item["id"])};
    }
    if (object.id < 1 || object.id >= kNoReturnLabel16) {
      return Error{where + ".id: expected 1..65534, got " + std::to_string(object.id)};
    }
    try {
      if (!item["is_obstacle"]) return Error{where + ".is_obstacle: missing"};
      object.is_obstacle = item["is_obstacle"].as<bool>();
    } catch (const YAML::Exception&) {
      return Error{where + ".is_obstacle: expected true or false, got " +
                   Describe(item["is_obstacle"])};
    }
    if (item["name"]) {
      if (!item["name"].IsScalar()) {
        return Error{where + ".name: expected a string, got " + Describe(item["name"])};
      }
      object.name = item["name"].Scalar();
    }
    objects.push_back(std::move(object));
  }
  return objects;
}

}  // namespace

const TruthObject* FrameTruth::Find(int id) const {
  const auto it = std::lower_bound(objects.begin(), objects.end(), id,
                                   [](const TruthObject& o, int v) { return o.id < v; });
  return it != objects.end() && it->id == id ? &*it : nullptr;
}

std::vector<std::uint8_t> FrameTruth::ObstacleMask() const {
  int max_id = 0;
  for (const TruthObject& o : objects) max_id = std::max(max_id, o.id);
  std::vector<std::uint8_t> obstacle_id(static_cast<std::size_t>(max_id) + 1, 0);
  for (const TruthObject& o : objects) obstacle_id[o.id] = o.is_obstacle ? 1 : 0;
  std::vector<std::uint8_t> mask(object_id.size(), 0);
  for (std::size_t i = 0; i < object_id.size(); ++i) {
    const int id = object_id[i];
    if (id > 0 && id <= max_id) mask[i] = obstacle_id[id];
  }
  return mask;
}

Status FrameTruth::Validate() const {
  if (width <= 0 || height <= 0 ||
      object_id.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    return Error{"truth: " + std::to_string(object_id.size()) + " object ids for a " +
                 std::to_string(width) + "x" + std::to_string(height) + " image"};
  }
  for (std::size_t k = 0; k < objects.size(); ++k) {
    if (objects[k].id < 1) {
      return Error{"truth: object id " + std::to_string(objects[k].id) + " is not positive"};
    }
    if (k > 0 && objects[k].id <= objects[k - 1].id) {
      return Error{"truth: objects are not sorted by id or id " + std::to_string(objects[k].id) +
                   " is listed twice"};
    }
  }
  for (std::size_t i = 0; i < object_id.size(); ++i) {
    const int id = object_id[i];
    if (id < sim::kNoHitId) {
      return Error{"truth: object id " + std::to_string(id) + " at " + At(i, width)};
    }
    if (id > 0 && Find(id) == nullptr) {
      return Error{"truth: object id " + std::to_string(id) + " at " + At(i, width) +
                   " is not listed among the objects"};
    }
  }
  return Status::Ok();
}

Expected<FrameTruth> TruthFromRender(const sim::DepthFrame& frame, const sim::Scene& scene) {
  FrameTruth truth;
  truth.width = frame.width();
  truth.height = frame.height();
  truth.object_id = frame.object_id;
  if (frame.depth_m.size() != truth.object_id.size()) {
    return Error{"rendered frame: " + std::to_string(frame.depth_m.size()) + " depths and " +
                 std::to_string(truth.object_id.size()) + " object ids"};
  }
  std::set<int> seen;
  for (std::size_t i = 0; i < truth.object_id.size(); ++i) {
    if (!ValidDepth(frame.depth_m[i])) truth.object_id[i] = sim::kNoHitId;
    if (truth.object_id[i] > 0) seen.insert(truth.object_id[i]);
  }
  for (const int id : seen) {
    const sim::Object* object = scene.Find(id);
    if (object == nullptr) {
      return Error{"rendered frame: object id " + std::to_string(id) + " is not in the scene"};
    }
    truth.objects.push_back({id, object->name, object->is_obstacle});
  }
  if (Status s = truth.Validate(); !s) return s.error();
  return truth;
}

Expected<EvalFrame> FrameFromRender(const std::string& name, const sim::DepthFrame& frame,
                                    const sim::Scene& scene) {
  Expected<FrameTruth> truth = TruthFromRender(frame, scene);
  if (!truth) return Error{name + ": " + truth.error().message};
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(frame.depth_m, frame.model, frame.up_optical);
  if (!image) return Error{name + ": " + image.error().message};
  EvalFrame out;
  out.name = name;
  out.depth_m = {frame.width(), frame.height(), frame.depth_m};
  out.image = std::move(image).value();
  out.truth = std::move(truth).value();
  return out;
}

Expected<FrameTruth> LoadTruth(const std::filesystem::path& truth_png,
                               const std::filesystem::path& truth_yaml) {
  const std::string png = truth_png.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(truth_png, ec)) return Error{png + ": no such file"};
  cv::Mat image;
  try {
    image = cv::imread(png, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) return Error{png + ": cannot be read as a PNG image"};
  if (image.type() != CV_8UC1 && image.type() != CV_16UC1) {
    return Error{png + ": expected an 8- or 16-bit single-channel object-id image"};
  }
  const bool wide = image.type() == CV_16UC1;
  const int no_return = wide ? kNoReturnLabel16 : kNoReturnLabel8;
  Expected<std::vector<TruthObject>> objects = ParseObjects(truth_yaml);
  if (!objects) return objects.error();

  FrameTruth truth;
  truth.width = image.cols;
  truth.height = image.rows;
  truth.object_id.reserve(static_cast<std::size_t>(image.cols) * image.rows);
  std::map<int, TruthObject> listed;
  for (const TruthObject& o : *objects) {
    if (!listed.emplace(o.id, o).second) {
      return Error{truth_yaml.string() + ": objects: id " + std::to_string(o.id) +
                   " is listed twice"};
    }
  }
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const int label = wide ? image.at<std::uint16_t>(r, c) : image.at<std::uint8_t>(r, c);
      if (label == no_return) {
        truth.object_id.push_back(sim::kNoHitId);
        continue;
      }
      if (label > 0 && listed.count(label) == 0) {
        return Error{png + ": object id " + std::to_string(label) + " at row " + std::to_string(r) +
                     ", col " + std::to_string(c) + " is not listed in " + truth_yaml.string()};
      }
      truth.object_id.push_back(label);
    }
  }
  for (const auto& [id, object] : listed) truth.objects.push_back(object);
  return truth;
}

Expected<EvalFrame> LoadFrame(const std::filesystem::path& depth_png,
                              const std::filesystem::path& intrinsics_yaml,
                              const std::filesystem::path& truth_png,
                              const std::filesystem::path& truth_yaml, std::string name) {
  Expected<od::io::CameraIntrinsics> intrinsics = od::io::LoadIntrinsics(intrinsics_yaml);
  if (!intrinsics) return intrinsics.error();
  Expected<od::Grid<float>> depth = od::io::ReadDepthPng(depth_png, *intrinsics);
  if (!depth) return depth.error();
  Expected<FrameTruth> truth = LoadTruth(truth_png, truth_yaml);
  if (!truth) return truth.error();
  if (truth->width != depth->width || truth->height != depth->height) {
    return Error{truth_png.string() + ": image is " + std::to_string(truth->width) + "x" +
                 std::to_string(truth->height) + " px, the depth image " +
                 std::to_string(depth->width) + "x" + std::to_string(depth->height)};
  }
  // Pixels without a return take no part, whatever the truth image says.
  for (std::size_t i = 0; i < depth->data.size(); ++i) {
    if (!ValidDepth(depth->data[i])) truth->object_id[i] = sim::kNoHitId;
  }
  Expected<od::RangeImage> image =
      od::RangeImage::FromDepth(depth->data, intrinsics->model, intrinsics->up);
  if (!image) return Error{depth_png.string() + ": " + image.error().message};
  EvalFrame frame;
  frame.name = name.empty() ? std::filesystem::absolute(depth_png).parent_path().filename().string()
                            : std::move(name);
  frame.depth_m = std::move(depth).value();
  frame.image = std::move(image).value();
  frame.truth = std::move(truth).value();
  return frame;
}

}  // namespace cairn::eval
