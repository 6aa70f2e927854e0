# cairn::map — TerrainMap: OctoMap fusion, the 2.5-D cost grid, persistent obstacles, map
# files, the Mapper. Included by libmap/CMakeLists.txt. OctoMap and cairn::od_io are public
# (TerrainOcTree is part of the API; mapper_config_file.hpp hands out od_io's StereoConfig);
# OpenCV, yaml-cpp and nlohmann_json stay private (files at the edge).
find_package(octomap REQUIRED)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgcodecs)
find_package(yaml-cpp REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(Ceres REQUIRED)  # tilt_refiner.cpp

cairn_add_library(cairn_map EXPORT_NAME map SOURCES
  src/checkpoint.cpp
  src/cost.cpp
  src/gravity_cues.cpp
  src/gravity_estimator.cpp
  src/gravity_tilt.cpp
  src/map_config.cpp
  src/map_config_file.cpp
  src/map_files.cpp
  src/mapper.cpp
  src/mapper_config_file.cpp
  src/terrain_grid.cpp
  src/terrain_map.cpp
  src/terrain_octree.cpp
  src/tilt_refiner.cpp
  src/tilt_step.cpp
)
# OctoMap's package exports the imported targets octomap and octomath. An installed cairn
# needs find_dependency(octomap) in cmake/cairn-config.cmake.in for cairn::map.
# The estimator's Ceres cost functors (anonymous types held by GravityEstimator::State) take
# longest to compile: alone, outside the unity batches, it builds beside the rest.
set_source_files_properties(src/gravity_estimator.cpp PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
target_link_libraries(cairn_map
  PUBLIC cairn::od cairn::od_io cairn::util Eigen3::Eigen octomap
  PRIVATE cairn::util_image opencv_core opencv_imgcodecs yaml-cpp Ceres::ceres
          $<BUILD_INTERFACE:nlohmann_json::nlohmann_json>)
