// Scene: a synthetic world in the world frame (z up): terrain plus objects with ground
// truth (an id and whether it is an obstacle).
//
// Ids are positive so that 0 can mean "terrain" and -1 "nothing" in rendered id images;
// whether an object counts as an obstacle is the scene author's statement, which the
// evaluation compares detections against.
//
// Ditches and banks are objects too (ids, names, ground truth) but live in the terrain: the
// scene's terrain() is the base terrain with every such object carved in, in the order the
// objects were added. Add them before the solids that should stand on them.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/sim/shapes.hpp"
#include "cairn/sim/terrain.hpp"

namespace cairn::sim {

struct Object {
  int id = 1;               ///< > 0, unique in the scene
  bool is_obstacle = true;  ///< ground truth for evaluation
  Shape shape;
  std::string name;  ///< for reports, e.g. "pole", "rock"
};

class Scene {
 public:
  explicit Scene(Terrain terrain = Terrain())
      : base_terrain_(terrain), terrain_(std::move(terrain)) {}

  /// The ground: the base terrain with the ditches and banks among the objects carved in.
  const Terrain& terrain() const { return terrain_; }
  /// The ground without the ditches and banks.
  const Terrain& base_terrain() const { return base_terrain_; }
  /// Replaces the base terrain; ditches and banks already added are carved into it again
  /// (solids are not moved).
  void set_terrain(Terrain terrain);
  const std::vector<Object>& objects() const { return objects_; }
  /// The object with this id, or nullptr.
  const Object* Find(int id) const;

  /// Adds an object with the next free id (one more than the largest so far); returns it.
  int Add(const Shape& shape, bool is_obstacle, std::string name = {});
  /// Adds an object with a chosen id. Fails when the id is not positive or already used,
  /// or the shape is invalid.
  Status Add(Object object);

  // Helpers that stand an object on the terrain: its base is sunk to the least terrain
  // height under its footprint, so that no gap shows under it on a slope; heights are
  // measured from the terrain at (x, y).

  /// A vertical cylinder whose top is `height_m` above the ground at (x, y).
  int AddPole(double x, double y, double radius_m, double height_m, bool is_obstacle,
              std::string name = "pole");
  /// An ellipsoid partly buried so that its top is `height_m` above the ground at (x, y);
  /// requires 0 < height_m <= 2 * radii.z().
  int AddRock(double x, double y, const Eigen::Vector3d& radii, double height_m, double yaw_rad,
              bool is_obstacle, std::string name = "rock");
  /// A box whose top is `size.z()` above the ground at (x, y).
  int AddBox(double x, double y, const Eigen::Vector3d& size, double yaw_rad, bool is_obstacle,
             std::string name = "box");
  /// A ridge whose top is `ridge.height_m` above the ground at its base centre's (x, y);
  /// base_centre.z() is ignored.
  int AddRidge(Ridge ridge, bool is_obstacle, std::string name = "ridge");
  /// A rod between two points given as (x, y, height of the axis above the ground there):
  /// a branch, a wire, a log. Requires radius_m > 0 and distinct ends.
  int AddRod(const Eigen::Vector3d& start_above_ground, const Eigen::Vector3d& end_above_ground,
             double radius_m, bool is_obstacle, std::string name = "rod");
  /// A bush (see MakeBush) whose top is `height_m` above the ground at (x, y), its core
  /// partly buried; requires 0 < height_m <= 2 * radii.z().
  int AddBush(double x, double y, const Eigen::Vector3d& radii, double height_m, double yaw_rad,
              int lumps, double lump_scale, std::uint64_t seed, bool is_obstacle,
              std::string name = "bush");
  /// A ditch or a bank, carved into the terrain (see terrain.hpp): hits on its walls or face
  /// carry the returned id. The feature must validate (asserted).
  int AddDitch(const Ditch& ditch, bool is_obstacle, std::string name = "ditch");
  int AddBank(const Bank& bank, bool is_obstacle, std::string name = "bank");

  /// Names the first bad object (id not positive or repeated, invalid shape).
  Status Validate() const;

 private:
  void Carve(const Object& object);

  Terrain base_terrain_;
  Terrain terrain_;
  std::vector<Object> objects_;
};

}  // namespace cairn::sim
