// Grid<T>: a row-major image of values with its size, as read from or written to a file.
#pragma once

#include <cstddef>
#include <vector>

namespace cairn::od::io {

/// `data[row * width + col]`; data.size() == width * height.
template <typename T>
struct Grid {
  int width = 0;
  int height = 0;
  std::vector<T> data;

  std::size_t size() const { return data.size(); }
  const T& at(int row, int col) const { return data[static_cast<std::size_t>(row) * width + col]; }
  T& at(int row, int col) { return data[static_cast<std::size_t>(row) * width + col]; }
};

}  // namespace cairn::od::io
