// Ground truth of one frame, and a frame ready to be evaluated: depth, points and truth.
//
// Truth is per pixel: the object id the pixel sees (0 terrain, > 0 an object, -1 nothing)
// and, per object, whether it is an obstacle (the world author's statement). Only pixels
// with a valid depth take part in an evaluation: a pixel whose return was dropped is
// neither an obstacle to find nor a detection to check, so its truth is set to -1 here.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/grid.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/sim/render.hpp"
#include "cairn/sim/scene.hpp"

namespace cairn::eval {

struct TruthObject {
  int id = 1;  ///< > 0
  std::string name;
  bool is_obstacle = true;
};

struct FrameTruth {
  int width = 0;
  int height = 0;
  /// Per pixel, row-major: kTerrainId (0), an object id (> 0) or kNoHitId (-1, also where
  /// the depth is not valid).
  std::vector<std::int32_t> object_id;
  /// Every object id that object_id holds, sorted by id.
  std::vector<TruthObject> objects;

  /// The object with this id, or nullptr.
  const TruthObject* Find(int id) const;
  /// Per pixel: 1 where the pixel sees an obstacle object.
  std::vector<std::uint8_t> ObstacleMask() const;
  /// Names the first inconsistency: size mismatch, an id < -1, an object id not listed,
  /// a listed id that is not positive or listed twice.
  Status Validate() const;
};

/// One frame to evaluate. depth_m and image hold the same depths (the grey rendering of the
/// figures is made from depth_m); truth is aligned with them.
struct EvalFrame {
  std::string name;  ///< e.g. "forest/view0"
  od::Grid<float> depth_m;
  od::RangeImage image;
  FrameTruth truth;
};

/// Truth of a rendered frame: the renderer's object ids (set to kNoHitId where the depth,
/// noise included, is not valid) and every object of the scene that is seen.
Expected<FrameTruth> TruthFromRender(const sim::DepthFrame& frame, const sim::Scene& scene);

/// A rendered frame (see TruthFromRender), its points made with the frame's up vector.
Expected<EvalFrame> FrameFromRender(const std::string& name, const sim::DepthFrame& frame,
                                    const sim::Scene& scene);

/// Truth from files: `truth_png` holds the object id per pixel, 8-bit (0 terrain, 1..254
/// objects, 255 no return) or 16-bit (65535 no return); `truth_yaml` lists the objects:
///   objects:
///     - {id: 1, name: "pole", is_obstacle: true, height_m: 1.4}   # name, height_m optional
/// Every id in the image must be listed. Errors name the file and the field.
Expected<FrameTruth> LoadTruth(const std::filesystem::path& truth_png,
                               const std::filesystem::path& truth_yaml);

/// A frame from files: depth PNG + intrinsics YAML (see cairn/od/io) + truth (above), all
/// of the same size. `name` defaults to the depth file's directory name.
Expected<EvalFrame> LoadFrame(const std::filesystem::path& depth_png,
                              const std::filesystem::path& intrinsics_yaml,
                              const std::filesystem::path& truth_png,
                              const std::filesystem::path& truth_yaml, std::string name = {});

}  // namespace cairn::eval
