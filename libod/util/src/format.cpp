#include "cairn/util/format.hpp"

#include <fmt/format.h>

namespace cairn::util {

std::string Fixed(double value, int decimals) { return fmt::format("{:.{}f}", value, decimals); }

std::string Number(double value) { return fmt::format("{:.9g}", value); }

}  // namespace cairn::util
