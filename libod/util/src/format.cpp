#include "cairn/util/format.hpp"

#include <fmt/format.h>

namespace cairn::util {

std::string Fixed(double value, int decimals) { return fmt::format("{:.{}f}", value, decimals); }

}  // namespace cairn::util
