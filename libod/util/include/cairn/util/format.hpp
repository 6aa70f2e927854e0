// Numbers as text for reports, summaries and messages, one way everywhere (fmt underneath).
#pragma once

#include <chrono>
#include <string>

namespace cairn::util {

/// `value` with `decimals` digits after the point, as printf's "%.*f" writes it
/// (Fixed(2.345, 1) == "2.3"; NaN is "nan", infinity "inf").
std::string Fixed(double value, int decimals);

/// `value` in its shortest form with up to 9 significant digits, as printf's "%.9g" writes
/// it (Number(0.063) == "0.063", Number(1e-12) == "1e-12"): values quoted back in messages.
std::string Number(double value);

/// Seconds of a steady clock since `start`.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace cairn::util
