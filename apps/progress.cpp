#include "progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <utility>

#include "cairn/util/format.hpp"

namespace cairn::apps {

namespace {

// "m:ss".
std::string ProgressMinutes(double seconds) {
  const long s = std::lround(seconds);
  char text[32];
  std::snprintf(text, sizeof text, "%ld:%02ld", s / 60, s % 60);
  return text;
}

}  // namespace

Progress::Progress(std::string command, int total, int every, int first, std::string unit,
                   std::chrono::steady_clock::time_point start)
    : command_(std::move(command)),
      unit_(std::move(unit)),
      total_(std::max(total, 1)),
      every_(std::max(every, 1)),
      first_(first),
      tty_(isatty(fileno(stderr)) != 0),
      start_(start) {}

void Progress::Update(int done) {
  const double elapsed = util::SecondsSince(start_);
  const double rate = elapsed > 0.0 ? (done - first_) / elapsed : 0.0;
  const double left = rate > 0.0 ? (total_ - done) / rate : 0.0;
  if (tty_) {
    if (done < total_ && elapsed - last_bar_s_ < 0.25) return;
    last_bar_s_ = elapsed;
    constexpr int kWidth = 30;
    const int filled = kWidth * std::clamp(done, 0, total_) / total_;
    std::cerr << "\r[" << std::string(filled, '#') << std::string(kWidth - filled, '.') << "] "
              << done << "/" << total_ << " " << unit_ << ", " << util::Fixed(rate, 1) << " "
              << unit_ << "/s, " << ProgressMinutes(left) << " left   " << std::flush;
    bar_shown_ = true;
  } else if (done % every_ == 0 || done == total_) {
    std::cerr << command_ << ": " << done << "/" << total_ << " " << unit_ << " ("
              << 100 * done / total_ << "%), " << util::Fixed(rate, 1) << " " << unit_
              << "/s, about " << ProgressMinutes(left) << " left\n";
  }
}

void Progress::Note(const std::string& line) {
  if (tty_ && bar_shown_) std::cerr << "\r" << std::string(79, ' ') << "\r";
  std::cerr << command_ << ": " << line << "\n";
}

void Progress::Finish() {
  if (tty_ && bar_shown_) std::cerr << "\n";
  bar_shown_ = false;
}

}  // namespace cairn::apps
