#include "cairn/od/io/point_cloud.hpp"

#include <bzlib.h>

#include <algorithm>
#include <cassert>
#include <charconv>
#include <cmath>
#include <complex>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <sstream>
#include <string_view>

#include "cairn/od/io/limits.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/image_file.hpp"
#include "png.hpp"
#include "text_fields.hpp"

namespace cairn::od::io {
namespace {

constexpr std::size_t kBinPointBytes = 16;  // 4 x float32

// The formats are little-endian; these builds target little-endian hosts only.
static_assert(sizeof(float) == 4, "float32 expected");

// Files larger than `max_bytes` are refused before they are read (limits.hpp).
Expected<std::string> ReadBytes(const std::filesystem::path& path, const char* what,
                                std::size_t max_bytes) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{name + ": no such file (" + what + ")"};
  if (std::filesystem::is_directory(path, ec)) {
    return Error{name + ": is a directory, expected a " + what + " file"};
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (!ec && size > max_bytes) {
    return Error{name + ": " + std::to_string(size) + " bytes, more than the " +
                 std::to_string(max_bytes) + " a " + what + " may have (limits.hpp)"};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{name + ": cannot open for reading (" + what + ")"};
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) return Error{name + ": read failed (" + what + ")"};
  return buffer.str();
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// Appends a point read from a file under the non-finite rule of point_cloud.hpp: all-NaN
// coordinates are a no return; any other non-finite value is an error. `where` locates the
// point for the message ("point 5 (byte offset 80)", "line 7").
// `where()` names the point in an error (built only then: a scan has 100,000 points).
template <typename Where>
Status AddPoint(PointCloud& cloud, const double xyz[3], double intensity, const std::string& name,
                const Where& where) {
  const bool all_nan = std::isnan(xyz[0]) && std::isnan(xyz[1]) && std::isnan(xyz[2]);
  if (all_nan) {
    cloud.points.emplace_back(0.f, 0.f, 0.f);
    cloud.intensity.push_back(0.f);
    return Status::Ok();
  }
  static const char* kAxis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(xyz[k])) {
      return Error{name + ": " + where() + ": " + kAxis[k] + " is " + std::to_string(xyz[k]) +
                   ", expected finite x, y, z [m] (a no return is (0, 0, 0), or NaN in all "
                   "three)"};
    }
  }
  if (!std::isfinite(intensity)) {
    return Error{name + ": " + where() + ": intensity is " + std::to_string(intensity) +
                 ", expected a finite value"};
  }
  cloud.points.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                            static_cast<float>(xyz[2]));
  cloud.intensity.push_back(static_cast<float>(intensity));
  return Status::Ok();
}

}  // namespace

Expected<PointCloud> ReadKittiBin(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> bytes = ReadBytes(path, "KITTI .bin point cloud", kMaxScanPoints * kBinPointBytes);
  if (!bytes) return bytes.error();
  if (bytes->empty()) {
    return Error{name +
                 ": the file is empty, expected points of 16 bytes each (x, y, z, "
                 "intensity as float32)"};
  }
  if (bytes->size() % kBinPointBytes != 0) {
    const std::size_t whole = bytes->size() / kBinPointBytes;
    return Error{name + ": size " + std::to_string(bytes->size()) +
                 " bytes is not a multiple of 16 (x, y, z, intensity float32 per point): the "
                 "file is truncated or not a KITTI .bin (" +
                 std::to_string(whole) + " whole points, then " +
                 std::to_string(bytes->size() % kBinPointBytes) + " bytes from offset " +
                 std::to_string(whole * kBinPointBytes) + ")"};
  }
  const std::size_t n = bytes->size() / kBinPointBytes;
  PointCloud cloud;
  cloud.points.reserve(n);
  cloud.intensity.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    float v[4];
    std::memcpy(v, bytes->data() + i * kBinPointBytes, kBinPointBytes);
    const double xyz[3] = {v[0], v[1], v[2]};
    const bool all_nan = std::isnan(v[0]) && std::isnan(v[1]) && std::isnan(v[2]);
    const auto where = [i] {
      return "point " + std::to_string(i) + " (byte offset " + std::to_string(i * kBinPointBytes) +
             ")";
    };
    if (Status s = AddPoint(cloud, xyz, all_nan ? 0.0 : v[3], name, where); !s) {
      return s.error();
    }
  }
  return cloud;
}

// --- PLY ---------------------------------------------------------------------------------

namespace {

enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

bool ParsePlyType(const std::string& word, PlyType* type, std::size_t* size) {
  static const struct {
    const char* names[2];
    PlyType type;
    std::size_t size;
  } kTypes[] = {
      {{"char", "int8"}, PlyType::kInt8, 1},        {{"uchar", "uint8"}, PlyType::kUint8, 1},
      {{"short", "int16"}, PlyType::kInt16, 2},     {{"ushort", "uint16"}, PlyType::kUint16, 2},
      {{"int", "int32"}, PlyType::kInt32, 4},       {{"uint", "uint32"}, PlyType::kUint32, 4},
      {{"float", "float32"}, PlyType::kFloat32, 4}, {{"double", "float64"}, PlyType::kFloat64, 8}};
  for (const auto& t : kTypes) {
    if (word == t.names[0] || word == t.names[1]) {
      *type = t.type;
      *size = t.size;
      return true;
    }
  }
  return false;
}

double DecodePly(PlyType type, const char* p) {
  switch (type) {
    case PlyType::kInt8: {
      std::int8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case PlyType::kUint8: {
      std::uint8_t v;
      std::memcpy(&v, p, 1);
      return v;
    }
    case PlyType::kInt16: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case PlyType::kUint16: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    case PlyType::kInt32: {
      std::int32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PlyType::kUint32: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PlyType::kFloat32: {
      float v;
      std::memcpy(&v, p, 4);
      return v;
    }
    case PlyType::kFloat64: {
      double v;
      std::memcpy(&v, p, 8);
      return v;
    }
  }
  return 0.0;
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  std::size_t size = 0;
  bool list = false;
  std::size_t offset = 0;  // in a binary record
};

struct PlyElement {
  std::string name;
  std::size_t count = 0;
  std::vector<PlyProperty> properties;
  std::size_t stride = 0;  // binary record size (no list properties)
  bool has_list = false;
};

using detail::ParseNumber;
using detail::Tokens;

// A PLY header: its elements, and where the body starts.
struct PlyHeader {
  bool ascii = false;
  std::vector<PlyElement> elements;
  std::size_t body_offset = 0;  // the byte after the end_header line
  int lines = 0;                // lines up to end_header
};

// Where the points are: the vertex element and its properties' indices (-1: absent).
struct PlyVertexLayout {
  std::size_t element = 0;  // index in PlyHeader::elements
  int x = -1, y = -1, z = -1, intensity = -1, ring = -1;
};

// Adds the property of header line `t` ('property ...') to `element`; errors without the line.
Status AddPlyProperty(const std::vector<std::string_view>& t, PlyElement& element) {
  PlyProperty property;
  if (t.size() == 5 && t[1] == "list") {
    PlyType ignored;
    std::size_t ignored_size;
    if (!ParsePlyType(std::string(t[2]), &ignored, &ignored_size) ||
        !ParsePlyType(std::string(t[3]), &property.type, &property.size)) {
      return Error{"unknown type in list property '" + std::string(t[4]) + "'"};
    }
    property.list = true;
    property.name = std::string(t[4]);
    element.has_list = true;
  } else if (t.size() == 3) {
    if (!ParsePlyType(std::string(t[1]), &property.type, &property.size)) {
      return Error{"unknown type '" + std::string(t[1]) + "' of property '" + std::string(t[2]) +
                   "'"};
    }
    property.name = std::string(t[2]);
    property.offset = element.stride;
    element.stride += property.size;
  } else {
    return Error{
        "expected 'property <type> <name>' or 'property list <count type> "
        "<item type> <name>'"};
  }
  element.properties.push_back(property);
  return Status::Ok();
}

// The header of PLY file `name`, one keyword line at a time up to end_header.
Expected<PlyHeader> ParsePlyHeader(const std::string& data, const std::string& name) {
  PlyHeader header;
  std::size_t& pos = header.body_offset;
  int& line_number = header.lines;
  bool format_seen = false;
  auto header_error = [&](const std::string& what) {
    return Error{name + ": PLY header line " + std::to_string(line_number) + ": " + what};
  };
  for (;;) {
    if (pos >= data.size()) {
      return Error{name + ": PLY header has no 'end_header' line (the file ends at byte " +
                   std::to_string(data.size()) + ")"};
    }
    std::size_t eol = data.find('\n', pos);
    if (eol == std::string::npos) eol = data.size();
    const std::string_view line(data.data() + pos, eol - pos);
    pos = eol + 1;
    ++line_number;
    const std::vector<std::string_view> t = Tokens(line, false);
    if (line_number == 1) {
      if (t.size() != 1 || t[0] != "ply") return header_error("expected 'ply', not a PLY file");
      continue;
    }
    if (t.empty()) continue;
    if (t[0] == "end_header") break;
    if (t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "format") {
      if (t.size() != 3 || t[2] != "1.0") return header_error("expected 'format <kind> 1.0'");
      if (t[1] == "ascii") {
        header.ascii = true;
      } else if (t[1] != "binary_little_endian") {
        return header_error("format '" + std::string(t[1]) +
                            "' is not supported (expected ascii or binary_little_endian)");
      }
      format_seen = true;
    } else if (t[0] == "element") {
      double count = -1.0;
      if (t.size() != 3 || !ParseNumber(t[2], &count) || count < 0 || count != std::floor(count)) {
        return header_error("expected 'element <name> <count>'");
      }
      if (count > static_cast<double>(kMaxScanPoints)) {
        return header_error("element count " + std::string(t[2]) + " is more than the " +
                            std::to_string(kMaxScanPoints) + " a scan may have (limits.hpp)");
      }
      header.elements.push_back({std::string(t[1]), static_cast<std::size_t>(count), {}, 0, false});
    } else if (t[0] == "property") {
      if (header.elements.empty()) return header_error("a property before any element");
      if (Status s = AddPlyProperty(t, header.elements.back()); !s) {
        return header_error(s.message());
      }
    } else {
      return header_error("unknown keyword '" + std::string(t[0]) + "'");
    }
  }
  if (!format_seen) return Error{name + ": PLY header has no 'format' line"};
  return header;
}

// The vertex element and where x, y, z (required), intensity and ring are among its properties.
Expected<PlyVertexLayout> FindPlyVertexLayout(const PlyHeader& header, const std::string& name) {
  const std::vector<PlyElement>& elements = header.elements;
  PlyVertexLayout layout;
  layout.element = elements.size();
  for (std::size_t e = 0; e < elements.size(); ++e) {
    if (elements[e].name == "vertex") {
      layout.element = e;
      break;
    }
  }
  if (layout.element == elements.size()) {
    return Error{name + ": PLY header has no 'element vertex'"};
  }
  const PlyElement& vertex = elements[layout.element];
  if (vertex.count == 0) return Error{name + ": PLY file has no vertices (element vertex 0)"};
  if (vertex.count > kMaxScanPoints) {
    return Error{name + ": PLY header: element vertex " + std::to_string(vertex.count) +
                 ": more than the " + std::to_string(kMaxScanPoints) +
                 " points a scan may have (limits.hpp)"};
  }
  if (vertex.has_list) {
    return Error{name + ": PLY vertex element has a list property; expected scalar properties"};
  }
  for (std::size_t k = 0; k < vertex.properties.size(); ++k) {
    const std::string& n = vertex.properties[k].name;
    if (n == "x") layout.x = static_cast<int>(k);
    if (n == "y") layout.y = static_cast<int>(k);
    if (n == "z") layout.z = static_cast<int>(k);
    if (n == "intensity") layout.intensity = static_cast<int>(k);
    if (n == "ring") layout.ring = static_cast<int>(k);
  }
  if (layout.x < 0 || layout.y < 0 || layout.z < 0) {
    return Error{name + ": PLY vertex element lacks property " +
                 std::string(layout.x < 0   ? "x"
                             : layout.y < 0 ? "y"
                                            : "z") +
                 " (expected x, y, z)"};
  }
  return layout;
}

// An empty cloud with room for `count` points (and their rings).
PointCloud ReservePlyCloud(std::size_t count, bool rings) {
  PointCloud cloud;
  cloud.points.reserve(count);
  cloud.intensity.reserve(count);
  if (rings) cloud.ring.reserve(count);
  return cloud;
}

// Appends a ring number read from a file: a whole number 0..65535 (`where()` names the point).
template <typename Where>
Status AddPlyRing(PointCloud& cloud, double value, const std::string& name, const Where& where) {
  if (!(value >= 0.0 && value <= 65535.0) || value != std::floor(value)) {
    return Error{name + ": " + where() + ": ring is " + std::to_string(value) +
                 ", expected a whole number 0..65535"};
  }
  cloud.ring.push_back(static_cast<std::int32_t>(value));
  return Status::Ok();
}

// The points of a binary_little_endian body: fixed-size records, earlier elements skipped.
Expected<PointCloud> ReadPlyBinaryBody(const std::string& data, const PlyHeader& header,
                                       const PlyVertexLayout& layout, const std::string& name) {
  const std::vector<PlyElement>& elements = header.elements;
  const PlyElement& vertex = elements[layout.element];
  std::size_t pos = header.body_offset;
  for (std::size_t e = 0; e < layout.element; ++e) {
    if (elements[e].has_list) {
      return Error{name + ": PLY element '" + elements[e].name +
                   "' before the vertices has a list property (not supported)"};
    }
    pos += elements[e].count * elements[e].stride;
  }
  const std::size_t need = pos + vertex.count * vertex.stride;
  if (need > data.size()) {
    const std::size_t whole = pos <= data.size() ? (data.size() - pos) / vertex.stride : 0;
    return Error{name + ": PLY body is truncated: " + std::to_string(vertex.count) +
                 " vertices of " + std::to_string(vertex.stride) + " bytes need " +
                 std::to_string(need) + " bytes, the file has " + std::to_string(data.size()) +
                 " (vertex " + std::to_string(whole) + " is incomplete at byte offset " +
                 std::to_string(pos + whole * vertex.stride) + ")"};
  }
  PointCloud cloud = ReservePlyCloud(vertex.count, layout.ring >= 0);
  const auto& props = vertex.properties;
  for (std::size_t i = 0; i < vertex.count; ++i) {
    const char* record = data.data() + pos + i * vertex.stride;
    auto get = [&](int k) { return DecodePly(props[k].type, record + props[k].offset); };
    const double xyz[3] = {get(layout.x), get(layout.y), get(layout.z)};
    const auto where = [&] {
      return "vertex " + std::to_string(i) + " (byte offset " +
             std::to_string(pos + i * vertex.stride) + ")";
    };
    const bool all_nan = std::isnan(xyz[0]) && std::isnan(xyz[1]) && std::isnan(xyz[2]);
    const double intensity = layout.intensity >= 0 && !all_nan ? get(layout.intensity) : 0.0;
    if (Status s = AddPoint(cloud, xyz, intensity, name, where); !s) return s.error();
    if (layout.ring >= 0) {
      if (Status s = AddPlyRing(cloud, get(layout.ring), name, where); !s) return s.error();
    }
  }
  return cloud;
}

// The points of an ascii body: one element a line (blank lines skipped), earlier ones skipped.
Expected<PointCloud> ReadPlyAsciiBody(const std::string& data, const PlyHeader& header,
                                      const PlyVertexLayout& layout, const std::string& name) {
  const std::vector<PlyElement>& elements = header.elements;
  const PlyElement& vertex = elements[layout.element];
  std::size_t pos = header.body_offset;
  int line_number = header.lines;
  auto next_line = [&](std::string_view* line) {
    while (pos < data.size()) {
      std::size_t eol = data.find('\n', pos);
      if (eol == std::string::npos) eol = data.size();
      *line = std::string_view(data.data() + pos, eol - pos);
      pos = eol + 1;
      ++line_number;
      if (!Tokens(*line, false).empty()) return true;
    }
    return false;
  };
  std::string_view line;
  for (std::size_t e = 0; e < layout.element; ++e) {
    for (std::size_t k = 0; k < elements[e].count; ++k) {
      if (!next_line(&line)) {
        return Error{name + ": PLY body ends at line " + std::to_string(line_number) +
                     " inside element '" + elements[e].name + "'"};
      }
    }
  }
  PointCloud cloud = ReservePlyCloud(vertex.count, layout.ring >= 0);
  for (std::size_t i = 0; i < vertex.count; ++i) {
    if (!next_line(&line)) {
      return Error{name + ": PLY body ends at line " + std::to_string(line_number) + " after " +
                   std::to_string(i) + " of " + std::to_string(vertex.count) + " vertices"};
    }
    const std::vector<std::string_view> t = Tokens(line, false);
    const std::string where = "line " + std::to_string(line_number);
    if (t.size() != vertex.properties.size()) {
      return Error{name + ": " + where + ": " + std::to_string(t.size()) + " values, expected " +
                   std::to_string(vertex.properties.size()) + " (one per vertex property)"};
    }
    std::vector<double> v(t.size());
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (!ParseNumber(t[k], &v[k])) {
        return Error{name + ": " + where + ": '" + std::string(t[k]) + "' is not a number (" +
                     vertex.properties[k].name + ")"};
      }
    }
    const double xyz[3] = {v[layout.x], v[layout.y], v[layout.z]};
    const bool all_nan = std::isnan(xyz[0]) && std::isnan(xyz[1]) && std::isnan(xyz[2]);
    const double intensity = layout.intensity >= 0 && !all_nan ? v[layout.intensity] : 0.0;
    const auto where_fn = [&] { return where; };
    if (Status s = AddPoint(cloud, xyz, intensity, name, where_fn); !s) return s.error();
    if (layout.ring >= 0) {
      if (Status s = AddPlyRing(cloud, v[layout.ring], name, where_fn); !s) return s.error();
    }
  }
  return cloud;
}

}  // namespace

Expected<PointCloud> ReadPly(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> bytes = ReadBytes(path, "PLY point cloud", kMaxScanPoints * 256);
  if (!bytes) return bytes.error();
  if (bytes->empty()) return Error{name + ": the file is empty, expected a PLY header"};
  Expected<PlyHeader> header = ParsePlyHeader(*bytes, name);
  if (!header) return header.error();
  Expected<PlyVertexLayout> layout = FindPlyVertexLayout(*header, name);
  if (!layout) return layout.error();
  if (header->ascii) return ReadPlyAsciiBody(*bytes, *header, *layout, name);
  return ReadPlyBinaryBody(*bytes, *header, *layout, name);
}

// --- Text scans ---------------------------------------------------------------------------

namespace {

Expected<std::string> DecompressBzip2(const std::string& compressed, const std::string& name) {
  std::string out;
  std::size_t consumed = 0;
  // A .bz2 file may hold several streams back to back (pbzip2, cat a.bz2 b.bz2).
  while (consumed < compressed.size()) {
    bz_stream stream;
    std::memset(&stream, 0, sizeof(stream));
    if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) {
      return Error{name + ": cannot start bzip2 decompression"};
    }
    stream.next_in = const_cast<char*>(compressed.data() + consumed);
    stream.avail_in = static_cast<unsigned int>(
        std::min<std::size_t>(compressed.size() - consumed, std::numeric_limits<unsigned>::max()));
    const std::size_t stream_start = consumed;
    int rc = BZ_OK;
    char buffer[1 << 16];
    while (rc == BZ_OK) {
      stream.next_out = buffer;
      stream.avail_out = sizeof(buffer);
      rc = BZ2_bzDecompress(&stream);
      out.append(buffer, sizeof(buffer) - stream.avail_out);
      if (out.size() > kMaxDecompressedBytes) {
        BZ2_bzDecompressEnd(&stream);
        return Error{name + ": decompresses to more than " +
                     std::to_string(kMaxDecompressedBytes) +
                     " bytes, the most a text scan may have (limits.hpp)"};
      }
      if (rc == BZ_OK && stream.avail_in == 0 && stream.avail_out != 0) break;  // input ended
    }
    const std::size_t at = stream_start + (compressed.size() - stream_start - stream.avail_in);
    BZ2_bzDecompressEnd(&stream);
    if (rc == BZ_DATA_ERROR_MAGIC) {
      return Error{name + ": not a bzip2 stream at byte offset " + std::to_string(stream_start) +
                   " (expected 'BZh')"};
    }
    if (rc == BZ_DATA_ERROR) {
      return Error{name + ": corrupt bzip2 data near byte offset " + std::to_string(at)};
    }
    if (rc == BZ_MEM_ERROR) return Error{name + ": out of memory decompressing bzip2"};
    if (rc != BZ_STREAM_END) {
      return Error{name + ": bzip2 stream is truncated (the file ends at byte " +
                   std::to_string(compressed.size()) + " inside a stream)"};
    }
    consumed = at;
  }
  return out;
}

}  // namespace

Expected<PointCloud> ReadXyzText(const std::filesystem::path& path) {
  const std::string name = path.string();
  const bool bz2 = EndsWith(Lower(name), ".bz2");
  Expected<std::string> bytes = ReadBytes(path, bz2 ? "bzip2-compressed text scan" : "text scan",
                                             kMaxDecompressedBytes);
  if (!bytes) return bytes.error();
  if (bytes->empty()) return Error{name + ": the file is empty, expected lines of \"x y z\""};
  std::string text;
  if (bz2) {
    Expected<std::string> plain = DecompressBzip2(*bytes, name);
    if (!plain) return plain.error();
    text = std::move(*plain);
  } else {
    text = std::move(*bytes);
  }
  PointCloud cloud;
  std::size_t pos = 0;
  int line_number = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    const std::string_view line(text.data() + pos, eol - pos);
    pos = eol + 1;
    ++line_number;
    const std::vector<std::string_view> t = Tokens(line, true);
    if (t.empty() || t[0].front() == '#') continue;
    const std::string where = "line " + std::to_string(line_number);
    if (t.size() < 3 || t.size() > 4) {
      return Error{name + ": " + where + ": " + std::to_string(t.size()) +
                   " values, expected 3 or 4 (x y z [intensity])"};
    }
    double v[4] = {0.0, 0.0, 0.0, 0.0};
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (!ParseNumber(t[k], &v[k])) {
        return Error{name + ": " + where + ": '" + std::string(t[k]) +
                     "' is not a number (expected x y z [intensity])"};
      }
    }
    const bool all_nan = std::isnan(v[0]) && std::isnan(v[1]) && std::isnan(v[2]);
    if (Status s = AddPoint(cloud, v, all_nan ? 0.0 : v[3], name, [&] { return where; }); !s) {
      return s.error();
    }
    if (cloud.points.size() > kMaxScanPoints) {
      return Error{name + ": " + where + ": more than the " + std::to_string(kMaxScanPoints) +
                   " points a scan may have (limits.hpp)"};
    }
  }
  if (cloud.points.empty()) {
    return Error{name + ": no points (" + std::to_string(line_number) +
                 " lines, none of them \"x y z\")"};
  }
  return cloud;
}

Expected<PointCloud> ReadPointFile(const std::filesystem::path& path) {
  const std::string name = path.string();
  {
    std::ifstream in(path, std::ios::binary);
    char magic[4] = {0, 0, 0, 0};
    if (in && in.read(magic, 4) && std::string_view(magic, 3) == "ply" &&
        (magic[3] == '\n' || magic[3] == '\r')) {
      return ReadPly(path);
    }
  }
  std::string lower = Lower(name);
  if (EndsWith(lower, ".ply")) return ReadPly(path);
  if (EndsWith(lower, ".bin")) return ReadKittiBin(path);
  if (EndsWith(lower, ".bz2")) lower.resize(lower.size() - 4);
  for (const char* ext : {".txt", ".xyz", ".dat", ".pts", ".asc", ".csv"}) {
    if (EndsWith(lower, ext)) return ReadXyzText(path);
  }
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{name + ": no such file (point cloud)"};
  return Error{name +
               ": unknown point file type, expected .bin (KITTI), .ply, or text "
               "(.txt .xyz .dat .pts .asc .csv, optionally .bz2)"};
}

Status WriteKittiBin(const std::filesystem::path& path, const PointCloud& cloud) {
  assert(cloud.intensity.empty() || cloud.intensity.size() == cloud.points.size());
  std::string bytes(cloud.points.size() * kBinPointBytes, '\0');
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    const float v[4] = {cloud.points[i].x(), cloud.points[i].y(), cloud.points[i].z(),
                        cloud.intensity.empty() ? 0.f : cloud.intensity[i]};
    std::memcpy(bytes.data() + i * kBinPointBytes, v, kBinPointBytes);
  }
  return util::WriteFileAtomic(path, bytes);
}

Expected<std::vector<std::uint32_t>> PointLabels(const RangeImage& image,
                                                 const Detection& detection,
                                                 const Classification& classification) {
  assert(detection.width == image.width() && detection.height == image.height());
  if (detection.segments.size() > 0xFFFF) {
    return Error{std::to_string(detection.segments.size()) +
                 " segments: ids above 65535 do not fit the upper 16 bits of a .label entry"};
  }
  const std::vector<std::uint8_t> cls = ClassImage(detection, classification);
  const std::vector<std::int32_t>& cell = image.cell_of_point();
  std::vector<std::uint32_t> labels(cell.size(), 0u);
  for (std::size_t i = 0; i < cell.size(); ++i) {
    if (cell[i] < 0) continue;
    const auto id = static_cast<std::uint32_t>(detection.labels[cell[i]]);
    labels[i] = (id << 16) | static_cast<std::uint32_t>(cls[cell[i]]);
  }
  return labels;
}

Status WriteLabelFile(const std::filesystem::path& path, const std::vector<std::uint32_t>& labels) {
  return util::WriteFileAtomic(
      path, std::string_view(reinterpret_cast<const char*>(labels.data()), labels.size() * 4));
}

Expected<std::vector<std::uint32_t>> ReadLabelFile(const std::filesystem::path& path) {
  Expected<std::string> bytes = ReadBytes(path, "SemanticKITTI .label file", kMaxScanPoints * 4);
  if (!bytes) return bytes.error();
  if (bytes->size() % 4 != 0) {
    return Error{path.string() + ": size " + std::to_string(bytes->size()) +
                 " bytes is not a multiple of 4 (one uint32 per point): the file is truncated"};
  }
  std::vector<std::uint32_t> labels(bytes->size() / 4);
  // An empty file gives no labels; memcpy must not see the empty vector's null data()
  // (found by the corpus under UBSan).
  if (!labels.empty()) std::memcpy(labels.data(), bytes->data(), bytes->size());
  return labels;
}

Grid<float> RangeGrid(const RangeImage& image) {
  Grid<float> grid{image.width(), image.height(),
                   std::vector<float>(static_cast<std::size_t>(image.size()), 0.f)};
  for (int i = 0; i < image.size(); ++i) {
    if (image.valid(i)) grid.data[i] = static_cast<float>(image.range(i));
  }
  return grid;
}

Expected<RgbImage> RenderBirdsEye(const RangeImage& image,
                                  const std::vector<Eigen::Vector3f>& points,
                                  const std::vector<std::uint8_t>& point_class,
                                  const BirdsEyeOptions& options) {
  if (point_class.size() != points.size()) {
    return Error{"bird's-eye view: " + std::to_string(point_class.size()) + " classes for " +
                 std::to_string(points.size()) + " points"};
  }
  if (!(options.metres_per_pixel > 0.0) || !(options.half_extent_m > 0.0) ||
      options.half_extent_m / options.metres_per_pixel > 10000.0) {
    return Error{
        "bird's-eye view: metres_per_pixel and half_extent_m must be positive, "
        "at most 20000 px across"};
  }
  const int side =
      static_cast<int>(std::ceil(2.0 * options.half_extent_m / options.metres_per_pixel));
  RgbImage out{
      side, side,
      std::vector<std::array<std::uint8_t, 3>>(static_cast<std::size_t>(side) * side, {0, 0, 0})};
  const Eigen::Matrix3f R = image.R_level_sensor().cast<float>();
  auto draw = [&](std::uint8_t wanted, std::array<std::uint8_t, 3> colour, int radius) {
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (point_class[i] != wanted || !IsReturn(points[i])) continue;
      const Eigen::Vector3f q = R * points[i];
      const double row_f = (options.half_extent_m - q.x()) / options.metres_per_pixel;
      const double col_f = (options.half_extent_m - q.y()) / options.metres_per_pixel;
      const int row = static_cast<int>(std::floor(row_f)),
                col = static_cast<int>(std::floor(col_f));
      for (int dr = -radius; dr <= radius; ++dr) {
        for (int dc = -radius; dc <= radius; ++dc) {
          const int rr = row + dr, cc = col + dc;
          if (rr >= 0 && rr < side && cc >= 0 && cc < side) out.at(rr, cc) = colour;
        }
      }
    }
  };
  draw(static_cast<std::uint8_t>(SegmentClass::kNone), {110, 110, 110}, 0);
  draw(static_cast<std::uint8_t>(SegmentClass::kRejected), {255, 0, 0}, 1);
  draw(kBirdsEyeFoot, {120, 220, 255}, 1);
  draw(static_cast<std::uint8_t>(SegmentClass::kKept), {0, 40, 255}, 1);
  return out;
}

Status WriteRgbPng(const std::filesystem::path& path, const RgbImage& image) {
  cv::Mat bgr(image.height, image.width, CV_8UC3);
  for (int r = 0; r < image.height; ++r) {
    for (int c = 0; c < image.width; ++c) {
      const auto& p = image.at(r, c);
      bgr.at<cv::Vec3b>(r, c) = cv::Vec3b(p[2], p[1], p[0]);
    }
  }
  return util::WriteImageAtomic(path, bgr);
}

Expected<ScanOutputs> WriteScanOutputs(const std::filesystem::path& dir, const RangeImage& image,
                                       const std::vector<Eigen::Vector3f>& points,
                                       const Detection& detection,
                                       const Classification& classification,
                                       const RunDescription& run) {
  ScanOutputs out;
  Expected<std::vector<std::uint32_t>> labels = PointLabels(image, detection, classification);
  if (!labels) return Error{dir.string() + ": " + labels.error().message};
  Expected<DetectionFiles> files =
      WriteDetectionFiles(dir, RangeGrid(image), detection, classification, run);
  if (!files) return files.error();
  out.images = std::move(*files);
  out.labels = dir / "labels.label";
  if (Status s = WriteLabelFile(out.labels, *labels); !s) return s.error();
  std::vector<std::uint8_t> point_class(labels->size());
  const bool feet_known = detection.foot.size() == detection.labels.size();
  const std::vector<std::int32_t>& cell = image.cell_of_point();
  for (std::size_t i = 0; i < labels->size(); ++i) {
    point_class[i] = (*labels)[i] & 0xFFFFu;
    if (feet_known && point_class[i] == static_cast<std::uint8_t>(SegmentClass::kKept) &&
        i < cell.size() && cell[i] >= 0 && detection.foot[cell[i]] != 0) {
      point_class[i] = kBirdsEyeFoot;
    }
  }
  Expected<RgbImage> birds_eye = RenderBirdsEye(image, points, point_class);
  if (!birds_eye) return birds_eye.error();
  out.birds_eye = dir / "birds_eye.png";
  if (Status s = WriteRgbPng(out.birds_eye, *birds_eye); !s) return s.error();
  out.point_labels = std::move(*labels);
  return out;
}

}  // namespace cairn::od::io
