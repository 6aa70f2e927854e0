// The one quantile of the project's figures: the nearest rank, as reports and `cairn bench`
// quote medians and 95th percentiles.
#pragma once

#include <algorithm>
#include <vector>

namespace cairn::util {

/// The q-quantile (q in 0..1, clamped) of `values` by the nearest rank: the value at rank
/// round(q (n - 1)) of the sorted values; 0 when empty.
inline double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1);
  return values[std::min(values.size() - 1, static_cast<std::size_t>(rank + 0.5))];
}

}  // namespace cairn::util
