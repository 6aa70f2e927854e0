// Internal: MRPT exceptions as one-line messages.
#pragma once

#include <exception>
#include <string>

namespace cairn::sources::detail {

/// MRPT's messages carry a stack of frames after a "==== MRPT exception ====" banner; the
/// line that says what went wrong is the first after "Message:".
inline std::string Describe(const std::exception& e) {
  std::string what = e.what();
  const auto message = what.find("Message:");
  if (message != std::string::npos) what = what.substr(message + 8);
  const auto begin = what.find_first_not_of(" \t\n");
  if (begin == std::string::npos) return "unknown error";
  what = what.substr(begin);
  const auto end = what.find('\n');
  return end == std::string::npos ? what : what.substr(0, end);
}

}  // namespace cairn::sources::detail
