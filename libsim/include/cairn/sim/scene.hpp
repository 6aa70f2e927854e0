// Scene: a synthetic world in the world frame (z up): terrain plus objects with ground
// truth (an id and whether it is an obstacle).
//
// Ids are positive so that 0 can mean "terrain" and -1 "nothing" in rendered id images;
// whether an object counts as an obstacle is the scene author's statement, which the
// evaluation compares detections against.
#pragma once

#include <Eigen/Core>
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
  explicit Scene(Terrain terrain = Terrain()) : terrain_(std::move(terrain)) {}

  const Terrain& terrain() const { return terrain_; }
  void set_terrain(Terrain terrain) { terrain_ = std::move(terrain); }
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

  /// Names the first bad object (id not positive or repeated, invalid shape).
  Status Validate() const;

 private:
  Terrain terrain_;
  std::vector<Object> objects_;
};

}  // namespace cairn::sim
