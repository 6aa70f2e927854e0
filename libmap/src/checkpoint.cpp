#include "cairn/map/checkpoint.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <system_error>
#include <type_traits>
#include <vector>

#include "cairn/util/atomic_file.hpp"

namespace cairn::map {
namespace {

constexpr char kMagic[8] = {'C', 'A', 'I', 'R', 'N', 'M', 'C', 'K'};
constexpr std::size_t kHeaderBytes = 8 + 4 + 4 + 8 + 8;

// The config fields in file order, by their config-file key (map_config.cpp's names).
struct ConfigField {
  const char* key;
  double MapConfig::*member;
};
constexpr ConfigField kConfigFields[] = {
    {"voxel_size", &MapConfig::voxel_size_m},
    {"max_range", &MapConfig::max_range_m},
    {"voxel_hit", &MapConfig::voxel_hit_probability},
    {"voxel_miss", &MapConfig::voxel_miss_probability},
    {"voxel_min", &MapConfig::voxel_min_probability},
    {"voxel_max", &MapConfig::voxel_max_probability},
    {"cell_size", &MapConfig::cell_size_m},
    {"window_size", &MapConfig::window_size_m},
    {"cell_hit", &MapConfig::cell_hit_probability},
    {"cell_miss", &MapConfig::cell_miss_probability},
    {"cell_min", &MapConfig::cell_min_probability},
    {"cell_max", &MapConfig::cell_max_probability},
    {"obstacle_probability", &MapConfig::obstacle_probability},
    {"obstacle_min_height", &MapConfig::obstacle_min_height_m},
    {"ground_radius", &MapConfig::ground_radius_m},
    {"ground_max_slope", &MapConfig::ground_max_slope_rad},
    {"merge_distance", &MapConfig::merge_distance_m},
    {"plane_fit_radius", &MapConfig::plane_fit_radius_m},
    {"slope_cost_max", &MapConfig::slope_cost_max_rad},
    {"roughness_cost_max", &MapConfig::roughness_cost_max_m},
    {"robot_radius", &MapConfig::robot_radius_m},
    {"inflation_radius", &MapConfig::inflation_radius_m},
    {"cost_scaling_factor", &MapConfig::cost_scaling_factor},
};
constexpr std::size_t kConfigFieldCount = sizeof(kConfigFields) / sizeof(kConfigFields[0]);

// Bytes of one serialised Cell (fields written one by one, no padding).
constexpr std::size_t kCellBytes = 11 * 4 + 4 * 1 + 4;

std::uint64_t Fnv1a64(std::string_view bytes) {
  std::uint64_t h = 14695981039346656037ull;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ull;
  }
  return h;
}

std::string Quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

// Appends plain values in memory order (the machine's; checkpoints are not exchanged).
class Writer {
 public:
  template <typename T>
  void Put(const T& v) {
    static_assert(std::is_arithmetic_v<T>);
    bytes_.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
  void PutIndex(const CellIndex& c) {
    Put<std::int32_t>(c.x());
    Put<std::int32_t>(c.y());
  }
  template <int N>
  void PutVector(const Eigen::Matrix<double, N, 1>& v) {
    for (int k = 0; k < N; ++k) Put<double>(v[k]);
  }
  void PutBytes(std::string_view b) {
    Put<std::uint64_t>(b.size());
    bytes_.append(b.data(), b.size());
  }
  std::string& bytes() { return bytes_; }

 private:
  std::string bytes_;
};

// Reads what Writer wrote, refusing to read past the end; the first failure is kept.
class Reader {
 public:
  Reader(std::string_view bytes, std::string file) : bytes_(bytes), file_(std::move(file)) {}

  template <typename T>
  bool Get(T& v, const char* what) {
    static_assert(std::is_arithmetic_v<T>);
    if (!Need(sizeof(T), what)) return false;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool GetIndex(CellIndex& c, const char* what) {
    std::int32_t x = 0, y = 0;
    if (!Get(x, what) || !Get(y, what)) return false;
    c = {x, y};
    return true;
  }
  template <int N>
  bool GetVector(Eigen::Matrix<double, N, 1>& v, const char* what) {
    for (int k = 0; k < N; ++k) {
      if (!Get(v[k], what)) return false;
    }
    return true;
  }
  /// A count of items of `item_bytes` each, checked against what is left.
  bool GetCount(std::uint64_t& n, std::size_t item_bytes, const char* what) {
    if (!Get(n, what)) return false;
    if (item_bytes > 0 && n > (bytes_.size() - pos_) / item_bytes) {
      return Fail(std::string("corrupted: ") + what + " announces " + std::to_string(n) +
                  " items of " + std::to_string(item_bytes) + " bytes but only " +
                  std::to_string(bytes_.size() - pos_) + " bytes are left at byte " +
                  std::to_string(kHeaderBytes + pos_));
    }
    return true;
  }
  bool GetBytes(std::string_view& b, const char* what) {
    std::uint64_t n = 0;
    if (!GetCount(n, 1, what)) return false;
    b = bytes_.substr(pos_, n);
    pos_ += n;
    return true;
  }
  bool Fail(const std::string& message) {
    if (error_.empty()) error_ = "checkpoint " + file_ + ": " + message;
    return false;
  }
  bool AtEnd() const { return pos_ == bytes_.size(); }
  std::size_t left() const { return bytes_.size() - pos_; }
  const std::string& error() const { return error_; }

 private:
  bool Need(std::size_t n, const char* what) {
    if (bytes_.size() - pos_ >= n) return true;
    return Fail(std::string("corrupted: expected ") + std::to_string(n) + " bytes of " + what +
                " at byte " + std::to_string(kHeaderBytes + pos_) + ", only " +
                std::to_string(bytes_.size() - pos_) + " left");
  }

  std::string_view bytes_;
  std::string file_;
  std::size_t pos_ = 0;
  std::string error_;
};

void PutCell(Writer& w, const Cell& c) {
  w.Put(c.elevation_mean_m);
  w.Put(c.elevation_min_m);
  w.Put(c.elevation_max_m);
  w.Put(c.ground_points);
  w.Put(c.obstacle_points);
  w.Put(c.obstacle_top_m);
  w.Put(c.obstacle_log_odds);
  w.Put(c.hits);
  w.Put(c.misses);
  w.Put(c.slope_rad);
  w.Put(c.roughness_m);
  w.Put(c.terrain_cost);
  w.Put(c.cost);
  w.Put<std::uint8_t>(c.observed ? 1 : 0);
  w.Put<std::uint8_t>(c.lethal ? 1 : 0);
  w.Put(c.obstacle_id);
}

bool GetCell(Reader& r, Cell& c) {
  std::uint8_t observed = 0, lethal = 0;
  const char* what = "a grid cell";
  const bool ok = r.Get(c.elevation_mean_m, what) && r.Get(c.elevation_min_m, what) &&
                  r.Get(c.elevation_max_m, what) && r.Get(c.ground_points, what) &&
                  r.Get(c.obstacle_points, what) && r.Get(c.obstacle_top_m, what) &&
                  r.Get(c.obstacle_log_odds, what) && r.Get(c.hits, what) &&
                  r.Get(c.misses, what) && r.Get(c.slope_rad, what) && r.Get(c.roughness_m, what) &&
                  r.Get(c.terrain_cost, what) && r.Get(c.cost, what) && r.Get(observed, what) &&
                  r.Get(lethal, what) && r.Get(c.obstacle_id, what);
  c.observed = observed != 0;
  c.lethal = lethal != 0;
  return ok;
}

void PutObstacle(Writer& w, const Obstacle& o) {
  w.Put<std::int32_t>(o.id);
  w.PutVector<3>(o.bbox_min);
  w.PutVector<3>(o.bbox_max);
  w.PutVector<3>(o.centroid);
  w.Put(o.height_m);
  w.Put<std::int64_t>(o.point_count);
  w.Put<std::uint64_t>(o.cells.size());
  for (const CellIndex& c : o.cells) w.PutIndex(c);
  w.PutVector<2>(o.footprint_min);
  w.PutVector<2>(o.footprint_max);
  w.Put(o.footprint_area_m2);
  w.Put(o.first_seen_s);
  w.Put(o.last_seen_s);
  w.Put<std::uint64_t>(o.frames.size());
  for (const std::int64_t f : o.frames) w.Put<std::int64_t>(f);
  w.Put<std::uint64_t>(o.merged_ids.size());
  for (const int id : o.merged_ids) w.Put<std::int32_t>(id);
}

bool GetObstacle(Reader& r, Obstacle& o) {
  const char* what = "an obstacle";
  std::int32_t id = 0;
  std::int64_t points = 0;
  std::uint64_t n = 0;
  if (!r.Get(id, what) || !r.GetVector<3>(o.bbox_min, what) || !r.GetVector<3>(o.bbox_max, what) ||
      !r.GetVector<3>(o.centroid, what) || !r.Get(o.height_m, what) || !r.Get(points, what) ||
      !r.GetCount(n, 8, "an obstacle's cell count")) {
    return false;
  }
  o.id = id;
  o.point_count = points;
  o.cells.resize(n);
  for (CellIndex& c : o.cells) {
    if (!r.GetIndex(c, "an obstacle cell")) return false;
  }
  if (!r.GetVector<2>(o.footprint_min, what) || !r.GetVector<2>(o.footprint_max, what) ||
      !r.Get(o.footprint_area_m2, what) || !r.Get(o.first_seen_s, what) ||
      !r.Get(o.last_seen_s, what) || !r.GetCount(n, 8, "an obstacle's frame count")) {
    return false;
  }
  o.frames.resize(n);
  for (std::int64_t& f : o.frames) {
    if (!r.Get(f, "an obstacle frame id")) return false;
  }
  if (!r.GetCount(n, 4, "an obstacle's merged id count")) return false;
  o.merged_ids.resize(n);
  for (int& m : o.merged_ids) {
    std::int32_t v = 0;
    if (!r.Get(v, "a merged obstacle id")) return false;
    m = v;
  }
  return true;
}

std::string FormatDouble(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

}  // namespace

namespace detail {

// The one place that reads and writes the private state of TerrainMap and TerrainGrid.
struct CheckpointAccess {
  static std::string Serialise(const TerrainMap& m, std::string_view user_data) {
    Writer w;
    w.Put<std::uint32_t>(static_cast<std::uint32_t>(kConfigFieldCount));
    for (const ConfigField& f : kConfigFields) w.Put<double>(m.config_.*f.member);

    w.Put<std::int32_t>(m.next_obstacle_id_);
    w.Put<std::int64_t>(m.frames_);
    w.Put<std::int64_t>(m.retired_total_);
    w.PutIndex(m.observed_min_);
    w.PutIndex(m.observed_max_);
    w.Put<std::uint8_t>(m.has_observed_ ? 1 : 0);
    w.PutIndex(m.pruned_at_);
    // The octree is saved as it is, inner nodes possibly stale: flushing it here would
    // change the saved map (pruning) and make the saved and the running maps differ.
    w.Put<std::uint8_t>(m.octree_stale_ ? 1 : 0);

    const TerrainGrid& g = m.grid_;
    w.Put<std::int32_t>(g.window_cells_);
    w.PutIndex(g.min_);
    w.PutIndex(g.extent_);
    w.PutIndex(g.buffer_);
    w.Put<std::uint64_t>(g.cells_.size());
    for (const Cell& c : g.cells_) PutCell(w, c);

    w.Put<std::uint64_t>(m.obstacles_.size());
    for (const Obstacle& o : m.obstacles_) PutObstacle(w, o);

    w.PutBytes(user_data);

    std::ostringstream tree;
    m.octree_->writeData(tree);
    w.Put<std::uint64_t>(m.octree_->size());
    w.PutBytes(tree.str());
    return std::move(w.bytes());
  }

  static Expected<TerrainMap> Deserialise(Reader& r, const MapConfig& expected,
                                          const std::string& file, std::string* user_data) {
    const auto error = [&r]() -> Expected<TerrainMap> { return Error{r.error()}; };
    std::uint32_t field_count = 0;
    if (!r.Get(field_count, "the config field count")) return error();
    if (field_count != kConfigFieldCount) {
      return Error{"checkpoint " + file + ": corrupted: the config has " +
                   std::to_string(field_count) + " fields, expected " +
                   std::to_string(kConfigFieldCount)};
    }
    MapConfig saved;
    for (const ConfigField& f : kConfigFields) {
      if (!r.Get(saved.*f.member, "the config")) return error();
    }
    for (const ConfigField& f : kConfigFields) {
      const double a = saved.*f.member;
      const double b = expected.*f.member;
      if (std::memcmp(&a, &b, sizeof(double)) != 0) {
        return Error{"checkpoint " + file + ": made with map config '" + f.key +
                     "' = " + FormatDouble(a) + " but the run's config has " + FormatDouble(b) +
                     " (resume with the config the checkpoint was made with)"};
      }
    }
    if (Status s = saved.Validate(); !s) {
      return Error{"checkpoint " + file + ": corrupted: " + s.message()};
    }

    TerrainMap m(saved);
    std::int32_t next_id = 0;
    std::uint8_t has_observed = 0, stale = 0;
    if (!r.Get(next_id, "the next obstacle id") || !r.Get(m.frames_, "the frame count") ||
        !r.Get(m.retired_total_, "the retired count") ||
        !r.GetIndex(m.observed_min_, "the observed bounds") ||
        !r.GetIndex(m.observed_max_, "the observed bounds") ||
        !r.Get(has_observed, "the observed flag") ||
        !r.GetIndex(m.pruned_at_, "the pruning position") ||
        !r.Get(stale, "the octree flush flag")) {
      return error();
    }
    m.next_obstacle_id_ = next_id;
    m.has_observed_ = has_observed != 0;
    m.octree_stale_ = stale != 0;

    TerrainGrid& g = m.grid_;
    std::int32_t window_cells = 0;
    std::uint64_t cell_count = 0;
    CellIndex min, extent, buffer;
    if (!r.Get(window_cells, "the grid window") || !r.GetIndex(min, "the grid extent") ||
        !r.GetIndex(extent, "the grid extent") || !r.GetIndex(buffer, "the grid buffer") ||
        !r.GetCount(cell_count, kCellBytes, "the grid cell count")) {
      return error();
    }
    const bool consistent =
        window_cells == g.window_cells_ && buffer.minCoeff() >= 0 && extent.minCoeff() >= 0 &&
        extent.x() <= buffer.x() && extent.y() <= buffer.y() &&
        cell_count == static_cast<std::uint64_t>(buffer.x()) * buffer.y() &&
        (window_cells == 0 || (extent == CellIndex::Constant(window_cells) && buffer == extent));
    if (!consistent) {
      return Error{"checkpoint " + file + ": corrupted: grid of " + std::to_string(window_cells) +
                   " window cells, extent " + std::to_string(extent.x()) + "x" +
                   std::to_string(extent.y()) + ", buffer " + std::to_string(buffer.x()) + "x" +
                   std::to_string(buffer.y()) + " and " + std::to_string(cell_count) +
                   " cells; expected a buffer holding the extent (the window, " +
                   std::to_string(g.window_cells_) + " cells a side, when rolling)"};
    }
    g.min_ = min;
    g.extent_ = extent;
    g.buffer_ = buffer;
    g.cells_.assign(cell_count, Cell{});
    for (Cell& c : g.cells_) {
      if (!GetCell(r, c)) return error();
    }
    m.PrepareScratch();  // slots follow the buffer

    std::uint64_t obstacle_count = 0;
    if (!r.GetCount(obstacle_count, 8, "the obstacle count")) return error();
    m.obstacles_.resize(obstacle_count);
    for (Obstacle& o : m.obstacles_) {
      if (!GetObstacle(r, o)) return error();
    }

    std::string_view data;
    if (!r.GetBytes(data, "the application data")) return error();
    if (user_data != nullptr) user_data->assign(data.data(), data.size());

    std::uint64_t node_count = 0;
    std::string_view tree_bytes;
    if (!r.Get(node_count, "the octree node count") || !r.GetBytes(tree_bytes, "the octree")) {
      return error();
    }
    if (!r.AtEnd()) {
      return Error{"checkpoint " + file + ": corrupted: " + std::to_string(r.left()) +
                   " bytes after the octree, expected none"};
    }
    if (!tree_bytes.empty()) {
      // OctoMap's reader trusts its input; the checksum has already vouched for these bytes,
      // and the node count and the bytes consumed are checked after.
      std::istringstream in{std::string(tree_bytes)};
      m.octree_->readData(in);
      const std::streampos consumed = in.tellg();
      if (!in || consumed != static_cast<std::streampos>(tree_bytes.size()) ||
          m.octree_->size() != node_count) {
        return Error{"checkpoint " + file + ": corrupted octree: expected " +
                     std::to_string(node_count) + " nodes in " + std::to_string(tree_bytes.size()) +
                     " bytes, read " + std::to_string(m.octree_->size()) + " nodes"};
      }
    } else if (node_count != 0) {
      return Error{"checkpoint " + file + ": corrupted octree: expected " +
                   std::to_string(node_count) + " nodes in 0 bytes"};
    }
    return Expected<TerrainMap>(std::move(m));
  }
};

}  // namespace detail

std::filesystem::path CheckpointPath(const std::filesystem::path& dir_or_file) {
  std::error_code ec;
  if (std::filesystem::is_directory(dir_or_file, ec)) return dir_or_file / kCheckpointFileName;
  return dir_or_file;
}

Status SaveCheckpoint(const TerrainMap& map, const std::filesystem::path& dir_or_file,
                      std::string_view user_data) {
  const std::filesystem::path path = CheckpointPath(dir_or_file);
  const std::string payload = detail::CheckpointAccess::Serialise(map, user_data);
  Writer header;
  header.bytes().append(kMagic, sizeof(kMagic));
  header.Put<std::uint32_t>(kCheckpointVersion);
  header.Put<std::uint32_t>(0);
  header.Put<std::uint64_t>(payload.size());
  header.Put<std::uint64_t>(Fnv1a64(payload));
  std::string bytes = std::move(header.bytes());
  bytes += payload;
  if (Status s = util::WriteFileAtomic(path, bytes); !s) {
    return Error{"checkpoint " + Quoted(path) + ": " + s.message()};
  }
  return {};
}

Expected<TerrainMap> LoadCheckpoint(const std::filesystem::path& dir_or_file,
                                    const MapConfig& expected_config, std::string* user_data) {
  const std::filesystem::path path = CheckpointPath(dir_or_file);
  const std::string file = Quoted(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return Error{"checkpoint " + file + ": cannot open: " + std::strerror(errno)};
  }
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) return Error{"checkpoint " + file + ": read failed: " + std::strerror(errno)};
  if (bytes.size() < kHeaderBytes) {
    return Error{"checkpoint " + file + ": truncated: " + std::to_string(bytes.size()) +
                 " bytes, expected a " + std::to_string(kHeaderBytes) + "-byte header"};
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    return Error{"checkpoint " + file + ": not a cairn map checkpoint (expected the magic '" +
                 std::string(kMagic, sizeof(kMagic)) + "' at the start)"};
  }
  Reader header(std::string_view(bytes).substr(sizeof(kMagic)), file);
  std::uint32_t version = 0, reserved = 0;
  std::uint64_t payload_size = 0, checksum = 0;
  (void)(header.Get(version, "the version") && header.Get(reserved, "the header") &&
         header.Get(payload_size, "the header") && header.Get(checksum, "the header"));
  if (version != kCheckpointVersion) {
    return Error{"checkpoint " + file + ": format version " + std::to_string(version) +
                 ", expected " + std::to_string(kCheckpointVersion)};
  }
  if (reserved != 0) {  // written as 0: anything else is a corrupted header
    return Error{"checkpoint " + file + ": corrupted header: the reserved field at byte 12 is " +
                 std::to_string(reserved) + ", expected 0"};
  }
  const std::size_t actual = bytes.size() - kHeaderBytes;
  if (payload_size != actual) {
    return Error{"checkpoint " + file + ": " + (actual < payload_size ? "truncated" : "corrupted") +
                 ": the header announces " + std::to_string(payload_size) +
                 " bytes after it, the file has " + std::to_string(actual)};
  }
  const std::string_view payload = std::string_view(bytes).substr(kHeaderBytes);
  if (Fnv1a64(payload) != checksum) {
    return Error{"checkpoint " + file +
                 ": corrupted: the checksum of the payload does not match the header's"};
  }
  Reader reader(payload, file);
  return detail::CheckpointAccess::Deserialise(reader, expected_config, file, user_data);
}

}  // namespace cairn::map
