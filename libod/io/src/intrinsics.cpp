#include "cairn/od/io/intrinsics.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "cairn/od/io/limits.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::od::io {
namespace {

Expected<int> PositiveSize(const util::FieldReader& reader, const YAML::Node& node,
                           const std::string& field) {
  if (!node) return reader.Fail(field, "missing (expected a positive integer [px])");
  Expected<std::int64_t> value = reader.Integer(node, field);
  if (!value) return value.error();
  if (*value <= 0 || *value > kMaxImageSide) {
    return reader.Fail(field, "expected a positive integer [px] up to " +
                                  std::to_string(kMaxImageSide) + ", got " +
                                  util::Describe(node));
  }
  return static_cast<int>(*value);
}

Expected<double> RequiredDouble(const util::FieldReader& reader, const YAML::Node& node,
                                const std::string& field, const char* unit) {
  if (!node) return reader.Fail(field, std::string("missing (expected a number ") + unit + ")");
  return reader.Double(node, field);
}

Expected<Eigen::Vector3d> UpVector(const util::FieldReader& reader, const YAML::Node& node) {
  if (!node.IsSequence() || node.size() != 3) {
    return reader.Fail("up",
                       "expected a sequence of 3 numbers [x, y, z] in the optical frame, "
                       "got " +
                           util::Describe(node) +
                           (node.IsSequence() ? " of " + std::to_string(node.size()) : ""));
  }
  Eigen::Vector3d up;
  for (int i = 0; i < 3; ++i) {
    Expected<double> v = reader.Double(node[i], "up[" + std::to_string(i) + "]");
    if (!v) return v.error();
    up[i] = *v;
  }
  const double norm = up.norm();
  if (!(norm > 1e-9) || !std::isfinite(norm)) {
    return reader.Fail("up", "must not be the zero vector (it is gravity's up direction)");
  }
  return Eigen::Vector3d(up / norm);
}

// Focal lengths within (0, 1e6] px; the principal point inside the image, give or take
// its size (a crop may move it out, a typo by a factor of ten may not).
Status CheckPinholeRanges(const util::FieldReader& reader, const PinholeModel& m) {
  if (!(m.fx > 0.0 && m.fx <= 1e6)) {
    return reader.Fail("fx", "expected a focal length in (0, 1e6] px, got " + std::to_string(m.fx));
  }
  if (!(m.fy > 0.0 && m.fy <= 1e6)) {
    return reader.Fail("fy", "expected a focal length in (0, 1e6] px, got " + std::to_string(m.fy));
  }
  if (!(m.cx >= -m.width && m.cx <= 2.0 * m.width)) {
    return reader.Fail("cx", "expected a principal point column in [-width, 2 width] = [" +
                                 std::to_string(-m.width) + ", " + std::to_string(2 * m.width) +
                                 "] px, got " + std::to_string(m.cx));
  }
  if (!(m.cy >= -m.height && m.cy <= 2.0 * m.height)) {
    return reader.Fail("cy", "expected a principal point row in [-height, 2 height] = [" +
                                 std::to_string(-m.height) + ", " + std::to_string(2 * m.height) +
                                 "] px, got " + std::to_string(m.cy));
  }
  return Status::Ok();
}

}  // namespace

Expected<CameraIntrinsics> ParseIntrinsics(const std::string& yaml_text,
                                           const std::string& source) {
  Expected<YAML::Node> root = util::ParseYaml(yaml_text, source);
  if (!root) return root.error();
  const util::FieldReader reader(source);
  if (Status s = reader.CheckMapping(*root, "",
                                     {"width", "height", "fx", "fy", "cx", "cy", "depth_scale",
                                      "up", "pitch_deg", "roll_deg"});
      !s) {
    return s.error();
  }
  const YAML::Node& node = *root;

  CameraIntrinsics out;
  PinholeModel& m = out.model;
  {
    Expected<int> w = PositiveSize(reader, node["width"], "width");
    if (!w) return w.error();
    Expected<int> h = PositiveSize(reader, node["height"], "height");
    if (!h) return h.error();
    m.width = *w;
    m.height = *h;
  }
  struct NumberField {
    const char* key;
    const char* unit;
    double* target;
  };
  const NumberField numbers[] = {{"fx", "[px]", &m.fx},
                                 {"fy", "[px]", &m.fy},
                                 {"cx", "[px]", &m.cx},
                                 {"cy", "[px]", &m.cy},
                                 {"depth_scale", "[m per unit]", &out.depth_scale_m}};
  for (const NumberField& f : numbers) {
    Expected<double> v = RequiredDouble(reader, node[f.key], f.key, f.unit);
    if (!v) return v.error();
    *f.target = *v;
  }
  if (std::int64_t{m.width} * m.height > kMaxImagePixels) {
    return reader.Fail("height", "width x height is more than the " +
                                     std::to_string(kMaxImagePixels) + " pixels an image may have");
  }
  if (Status s = CheckPinholeRanges(reader, m); !s) return s.error();
  if (!(out.depth_scale_m > 0.0 && out.depth_scale_m <= 1.0)) {
    return reader.Fail("depth_scale", "expected metres per PNG unit in (0, 1], got " +
                                          util::Describe(node["depth_scale"]));
  }
  if (Status s = m.Validate(); !s) return Error{source + ": " + s.message()};

  const bool has_up = static_cast<bool>(node["up"]);
  const bool has_pitch = static_cast<bool>(node["pitch_deg"]);
  const bool has_roll = static_cast<bool>(node["roll_deg"]);
  if (has_up && (has_pitch || has_roll)) {
    return reader.Fail(has_pitch ? "pitch_deg" : "roll_deg",
                       "give either up or pitch_deg/roll_deg, not both");
  }
  if (has_up) {
    Expected<Eigen::Vector3d> up = UpVector(reader, node["up"]);
    if (!up) return up.error();
    out.up = *up;
  } else if (has_pitch) {
    Expected<double> pitch = util::Angle(reader, node["pitch_deg"], "pitch_deg", 90.0);
    if (!pitch) return pitch.error();
    double roll = 0.0;
    if (has_roll) {
      Expected<double> r = util::Angle(reader, node["roll_deg"], "roll_deg", 90.0);
      if (!r) return r.error();
      roll = *r;
    }
    out.up = CameraUpFromPitchRoll(*pitch * kDegToRad, roll * kDegToRad);
  } else if (has_roll) {
    return reader.Fail("pitch_deg", "missing: roll_deg is given, pitch_deg must be too");
  } else {
    return reader.Fail("up",
                       "missing (expected up: [x, y, z] in the optical frame, or "
                       "pitch_deg and optionally roll_deg)");
  }
  return out;
}

Expected<CameraIntrinsics> LoadIntrinsics(const std::filesystem::path& path) {
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  return ParseIntrinsics(*text, path.string());
}

Status WriteIntrinsics(const std::filesystem::path& path, const CameraIntrinsics& intrinsics,
                       const std::string& comment) {
  const PinholeModel& m = intrinsics.model;
  if (Status s = m.Validate(); !s) return Error{path.string() + ": " + s.message()};
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "width: %d\nheight: %d\nfx: %.12g\nfy: %.12g\ncx: %.12g\ncy: %.12g\n"
                "depth_scale: %.9g  # metres per depth.png unit\n"
                "up: [%.12g, %.12g, %.12g]  # gravity's up in the optical frame\n",
                m.width, m.height, m.fx, m.fy, m.cx, m.cy, intrinsics.depth_scale_m,
                intrinsics.up.x(), intrinsics.up.y(), intrinsics.up.z());
  return util::WriteFileAtomic(path, "# " + comment + "\n" + buf);
}

}  // namespace cairn::od::io
