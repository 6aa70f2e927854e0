// The text readers' shared field splitting and number parsing (KITTI calibration and poses,
// PLY headers, ASCII and CSV scans): one definition, so they accept the same numbers.
#pragma once

#include <charconv>
#include <string_view>
#include <system_error>
#include <vector>

namespace cairn::od::io::detail {

/// The fields of one line, separated by blanks (space, tab, CR, LF) and, when `commas`, by
/// commas; empty fields are dropped.
inline std::vector<std::string_view> Tokens(std::string_view line, bool commas = false) {
  std::vector<std::string_view> out;
  auto separator = [&](char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || (commas && c == ',');
  };
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && separator(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !separator(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

/// A whole field as a number (a leading '+' allowed, which from_chars takes not); false when
/// anything is left over. "nan" and "inf" parse: callers that need finite values check.
inline bool ParseNumber(std::string_view token, double* value) {
  const char* begin = token.data();
  const char* end = token.data() + token.size();
  if (begin != end && *begin == '+') ++begin;
  const std::from_chars_result r = std::from_chars(begin, end, *value);
  return r.ec == std::errc() && r.ptr == end;
}

}  // namespace cairn::od::io::detail
