// Progress of a long command on stderr, the same for every command: a bar rewritten in
// place on a terminal (at most four times a second), otherwise a line every `every` items,
// so that logs stay readable.
#pragma once

#include <chrono>
#include <string>

namespace cairn::apps {

class Progress {
 public:
  /// `command` starts each line ("cairn map"); `unit` names the items ("frames"); `first`
  /// counts items already done when the run starts (a resumed run), left out of the rate;
  /// `start`: when the work began, if before this call.
  Progress(std::string command, int total, int every, int first = 0,
           std::string unit = "frames",
           std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now());
  /// `done` items of the total are done.
  void Update(int done);
  /// A line of its own (a skipped frame), clearing the bar first.
  void Note(const std::string& line);
  /// Ends the bar's line.
  void Finish();

 private:
  std::string command_, unit_;
  int total_, every_, first_;
  bool tty_ = false;
  bool bar_shown_ = false;
  std::chrono::steady_clock::time_point start_;
  double last_bar_s_ = -1.0;
};

}  // namespace cairn::apps
