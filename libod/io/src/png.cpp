#include "png.hpp"

#include <cstdint>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "cairn/util/image_file.hpp"
#include "cairn/od/io/limits.hpp"
#include "cairn/util/yaml.hpp"

namespace cairn::od::io::detail {

namespace {

std::uint32_t BigEndian32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}

/// Walks the chunk list after the signature: IHDR first, every chunk whole, IEND reached.
/// Catching truncation here keeps libpng from printing its own complaint to stderr.
const char* CheckChunks(const std::string& bytes) {
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  std::size_t at = 8;
  bool first = true;
  while (true) {
    if (bytes.size() - at < 12) return "truncated";
    const std::uint32_t length = BigEndian32(data + at);
    const std::string type(bytes, at + 4, 4);
    if (first && type != "IHDR") return "no IHDR header";
    if (first && (length < 8 || bytes.size() - at < 20)) return "truncated IHDR header";
    if (first) {
      // Refused before decoding: the header's size is what the decoder would allocate.
      const std::uint32_t width = BigEndian32(data + at + 8);
      const std::uint32_t height = BigEndian32(data + at + 12);
      if (width == 0 || height == 0) return "IHDR says the image is empty";
      if (width > static_cast<std::uint32_t>(kMaxImageSide) ||
          height > static_cast<std::uint32_t>(kMaxImageSide) ||
          std::int64_t{width} * height > kMaxImagePixels) {
        return "IHDR size beyond the limits of 16384 px a side and 64 Mpx (limits.hpp)";
      }
    }
    first = false;
    if (length > bytes.size() - at - 12) return "truncated";
    at += 12 + static_cast<std::size_t>(length);
    if (type == "IEND") return nullptr;
  }
}

}  // namespace

Expected<cv::Mat> ReadPng(const std::filesystem::path& path, int expected_type,
                          const char* expected) {
  const std::string name = path.string();
  Expected<std::string> bytes = util::ReadTextFile(path);
  if (!bytes) return bytes.error();
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (bytes->size() < 8 || std::memcmp(bytes->data(), kSignature, 8) != 0) {
    return Error{name + ": not a PNG file (expected a " + expected + " PNG)"};
  }
  if (const char* problem = CheckChunks(*bytes)) {
    return Error{name + ": unreadable PNG (" + problem + ")"};
  }
  cv::Mat image;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes->size()), CV_8UC1, bytes->data());
    image = cv::imdecode(raw, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return Error{name + ": unreadable PNG: " + e.what()};
  }
  if (image.empty()) return Error{name + ": unreadable PNG (corrupt or truncated)"};
  if (image.type() != expected_type) {
    return Error{name + ": expected a " + expected + " PNG, got " + util::DescribeImageType(image.type())};
  }
  return image;
}

}  // namespace cairn::od::io::detail
