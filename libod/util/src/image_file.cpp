#include "cairn/util/image_file.hpp"

#include <cctype>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <string_view>

#include "cairn/util/atomic_file.hpp"

namespace cairn::util {

cv::Mat GreyMatView(const od::Grid<std::uint8_t>& image) {
  return cv::Mat(image.height, image.width, CV_8UC1, const_cast<std::uint8_t*>(image.data.data()));
}

od::Grid<std::uint8_t> GreyGridOf(const cv::Mat& m) {
  od::Grid<std::uint8_t> image;
  image.width = m.cols;
  image.height = m.rows;
  image.data.resize(static_cast<std::size_t>(m.cols) * m.rows);
  for (int r = 0; r < m.rows; ++r) {
    std::memcpy(&image.data[static_cast<std::size_t>(r) * m.cols], m.ptr<std::uint8_t>(r), m.cols);
  }
  return image;
}

std::string DescribeImageType(int type) {
  std::string depth;
  switch (CV_MAT_DEPTH(type)) {
    case CV_8U:
      depth = "8-bit";
      break;
    case CV_8S:
      depth = "8-bit signed";
      break;
    case CV_16U:
      depth = "16-bit";
      break;
    case CV_16S:
      depth = "16-bit signed";
      break;
    case CV_32S:
      depth = "32-bit integer";
      break;
    case CV_32F:
      depth = "32-bit float";
      break;
    case CV_64F:
      depth = "64-bit float";
      break;
    default:
      depth = "unknown-depth";
      break;
  }
  const int channels = CV_MAT_CN(type);
  return depth + (channels == 1 ? " single-channel" : " " + std::to_string(channels) + "-channel");
}

Status WriteImageAtomic(const std::filesystem::path& path, const cv::Mat& image,
                        const std::string& format, const std::vector<int>& params) {
  const std::size_t dot = format.rfind('.');
  std::string name = format.substr(dot == std::string::npos ? 0 : dot + 1);  // "png" -> "PNG"
  for (char& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  std::vector<unsigned char> buffer;
  try {
    if (!cv::imencode(format, image, buffer, params)) {
      return Error{path.string() + ": " + name + " encoding failed for a " +
                   DescribeImageType(image.type()) + " image"};
    }
  } catch (const cv::Exception& e) {
    return Error{path.string() + ": " + name + " encoding failed for a " +
                 DescribeImageType(image.type()) + " image: " + e.what()};
  }
  return WriteFileAtomic(
      path, std::string_view(reinterpret_cast<const char*>(buffer.data()), buffer.size()));
}

}  // namespace cairn::util
