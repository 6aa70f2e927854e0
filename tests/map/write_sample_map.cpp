// Writes the map files of a small mapped scene into the directory given, for the CTest
// checks that run OctoMap's own tools (bt2vrml, convert_octree, compare_octrees) on them.
#include <cstdio>
#include <filesystem>

#include "cairn/map/map_files.hpp"
#include "map_scene.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  cairn::Expected<cairn::map::TerrainMap> map = cairn::test::SmallMappedScene();
  if (!map) {
    std::fprintf(stderr, "%s\n", map.error().message.c_str());
    return 1;
  }
  if (cairn::Status s = cairn::map::WriteMapFiles(*map, argv[1]); !s) {
    std::fprintf(stderr, "%s\n", s.message().c_str());
    return 1;
  }
  return 0;
}
