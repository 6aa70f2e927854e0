#include "cairn/sim/scene.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <string>
#include <unordered_set>
#include <utility>
#include <variant>

namespace cairn::sim {

const Object* Scene::Find(int id) const {
  for (const Object& o : objects_) {
    if (o.id == id) return &o;
  }
  return nullptr;
}

void Scene::Carve(const Object& object) {
  if (const auto* ditch = std::get_if<Ditch>(&object.shape)) {
    terrain_.AddDitch(*ditch, object.id);
  } else if (const auto* bank = std::get_if<Bank>(&object.shape)) {
    terrain_.AddBank(*bank, object.id);
  }
}

void Scene::set_terrain(Terrain terrain) {
  base_terrain_ = std::move(terrain);
  terrain_ = base_terrain_;
  for (const Object& o : objects_) Carve(o);
}

int Scene::Add(const Shape& shape, bool is_obstacle, std::string name) {
  int id = 1;
  for (const Object& o : objects_) id = std::max(id, o.id + 1);
  assert(!IsTerrainFeature(shape) || ValidateShape(shape).ok());
  objects_.push_back(Object{id, is_obstacle, shape, std::move(name)});
  Carve(objects_.back());
  return id;
}

Status Scene::Add(Object object) {
  if (object.id <= 0) {
    return Error{"object '" + object.name + "': id must be > 0, got " + std::to_string(object.id)};
  }
  if (Find(object.id) != nullptr) {
    return Error{"object '" + object.name + "': id " + std::to_string(object.id) +
                 " is already used"};
  }
  if (Status s = ValidateShape(object.shape); !s.ok()) {
    return Error{"object " + std::to_string(object.id) + ": " + s.message()};
  }
  objects_.push_back(std::move(object));
  Carve(objects_.back());
  return Status::Ok();
}

int Scene::AddPole(double x, double y, double radius_m, double height_m, bool is_obstacle,
                   std::string name) {
  assert(radius_m > 0.0 && height_m > 0.0);
  const double base = terrain_.MinHeightOver({x, y}, radius_m);
  const double top = terrain_.Height(x, y) + height_m;
  return Add(Cylinder{{x, y, base}, radius_m, top - base}, is_obstacle, std::move(name));
}

int Scene::AddRock(double x, double y, const Eigen::Vector3d& radii, double height_m,
                   double yaw_rad, bool is_obstacle, std::string name) {
  assert(radii.minCoeff() > 0.0 && height_m > 0.0 && height_m <= 2.0 * radii.z());
  const double top = terrain_.Height(x, y) + height_m;
  return Add(Ellipsoid{{x, y, top - radii.z()}, radii, yaw_rad}, is_obstacle, std::move(name));
}

int Scene::AddBox(double x, double y, const Eigen::Vector3d& size, double yaw_rad, bool is_obstacle,
                  std::string name) {
  assert(size.minCoeff() > 0.0);
  const double base = terrain_.MinHeightOver({x, y}, 0.5 * std::hypot(size.x(), size.y()));
  const double top = terrain_.Height(x, y) + size.z();
  const double height = top - base;
  return Add(Box{{x, y, base + 0.5 * height}, {size.x(), size.y(), height}, yaw_rad}, is_obstacle,
             std::move(name));
}

int Scene::AddRidge(Ridge ridge, bool is_obstacle, std::string name) {
  assert(ridge.height_m > 0.0);
  const double x = ridge.base_centre.x(), y = ridge.base_centre.y();
  const double top = terrain_.Height(x, y) + ridge.height_m;
  // Sinking the base keeps the top where asked and lengthens the sides at their slopes.
  const double reach = Bound(ridge).radius_m;
  const double base = terrain_.MinHeightOver({x, y}, reach);
  ridge.base_centre.z() = base;
  ridge.height_m = top - base;
  return Add(ridge, is_obstacle, std::move(name));
}

int Scene::AddRod(const Eigen::Vector3d& start_above_ground,
                  const Eigen::Vector3d& end_above_ground, double radius_m, bool is_obstacle,
                  std::string name) {
  assert(radius_m > 0.0 && (end_above_ground - start_above_ground).norm() > 0.0);
  Eigen::Vector3d start = start_above_ground, end = end_above_ground;
  start.z() += terrain_.Height(start.x(), start.y());
  end.z() += terrain_.Height(end.x(), end.y());
  return Add(Rod{start, end, radius_m}, is_obstacle, std::move(name));
}

int Scene::AddBush(double x, double y, const Eigen::Vector3d& radii, double height_m,
                   double yaw_rad, int lumps, double lump_scale, std::uint64_t seed,
                   bool is_obstacle, std::string name) {
  assert(radii.minCoeff() > 0.0 && height_m > 0.0 && height_m <= 2.0 * radii.z());
  const double top = terrain_.Height(x, y) + height_m;
  return Add(MakeBush(x, y, top, radii, yaw_rad, lumps, lump_scale, seed), is_obstacle,
             std::move(name));
}

int Scene::AddDitch(const Ditch& ditch, bool is_obstacle, std::string name) {
  return Add(ditch, is_obstacle, std::move(name));
}

int Scene::AddBank(const Bank& bank, bool is_obstacle, std::string name) {
  return Add(bank, is_obstacle, std::move(name));
}

Status Scene::Validate() const {
  std::unordered_set<int> seen;
  for (const Object& o : objects_) {
    const std::string what =
        "object " + std::to_string(o.id) + (o.name.empty() ? std::string() : " '" + o.name + "'");
    if (o.id <= 0) return Error{what + ": id must be > 0"};
    if (!seen.insert(o.id).second) return Error{what + ": id is used twice"};
    if (Status s = ValidateShape(o.shape); !s.ok()) return Error{what + ": " + s.message()};
  }
  return Status::Ok();
}

}  // namespace cairn::sim
