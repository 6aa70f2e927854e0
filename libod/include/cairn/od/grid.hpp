// Grid<T>: a row-major image of values with its size (a depth map, a disparity, a grey
// image), as the readers of cairn::od_io give it and stereo matching makes it.
#pragma once

#include <cstddef>
#include <vector>

namespace cairn::od {

/// `data[row * width + col]`; data.size() == width * height.
template <typename T>
struct Grid {
  int width = 0;
  int height = 0;
  std::vector<T> data;

  std::size_t size() const { return data.size(); }
  /// Both sides positive and one value per cell.
  bool well_formed() const {
    return width > 0 && height > 0 && data.size() == static_cast<std::size_t>(width) * height;
  }
  const T& at(int row, int col) const { return data[static_cast<std::size_t>(row) * width + col]; }
  T& at(int row, int col) { return data[static_cast<std::size_t>(row) * width + col]; }
};

}  // namespace cairn::od
