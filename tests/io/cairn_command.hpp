// Running the built `cairn` (or any command) from a test: its exit code and what it printed
// on stdout and stderr together.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>
#include <vector>

namespace cairn::test {

struct CommandResult {
  int exit_code = -1;  ///< -1 when the command did not exit normally (a crash, a signal)
  std::string output;  ///< stdout and stderr
};

/// `s` in single quotes for the shell, inner quotes escaped.
inline std::string ShellQuote(const std::string& s) {
  std::string q = "'";
  for (const char ch : s) q += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return q + "'";
}

/// Runs a shell command line (stderr joined to stdout).
inline CommandResult RunShell(const std::string& command_line) {
  CommandResult result;
  FILE* pipe = ::popen((command_line + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer;
  while (std::fgets(buffer.data(), static_cast<int>(buffer.size()), pipe) != nullptr) {
    result.output += buffer.data();
  }
  const int status = ::pclose(pipe);
  if (WIFEXITED(status)) result.exit_code = WEXITSTATUS(status);
  return result;
}

/// Runs `exe` with `args`, each quoted.
inline CommandResult RunProgram(const std::string& exe, const std::vector<std::string>& args) {
  std::string command = ShellQuote(exe);
  for (const std::string& a : args) command += " " + ShellQuote(a);
  return RunShell(command);
}

}  // namespace cairn::test
