// cairn: obstacle detection and terrain mapping for off-road robots.
//
// main() only parses and dispatches; every error a user can cause comes back from the
// library as a message and leaves through stderr with a non-zero exit, and anything else
// that escapes is caught here rather than crashing.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <vector>

#include "subcommands.hpp"

int cairn::apps::CommandFailure(const char* command, const std::string& message) {
  std::cerr << "cairn " << command << ": error: " << message << "\n";
  return kExitFailure;
}

int main(int argc, char** argv) {
  using namespace cairn::apps;
  try {
    CLI::App app{
        "cairn: finds obstacles in range images of cross-country terrain "
        "(the cone detector of Talukder et al., IEEE IV 2002)",
        "cairn"};
    app.set_version_flag("--version", CAIRN_VERSION);
    app.require_subcommand(1);
    std::vector<Subcommand> commands = {AddDetectCommand(app)};
#ifdef CAIRN_HAVE_SYNTH
    commands.push_back(AddSynthCommand(app));
#endif
#ifdef CAIRN_HAVE_EVAL
    commands.push_back(AddEvalCommand(app));
#endif
#ifdef CAIRN_HAVE_SOURCES
    commands.push_back(AddInfoCommand(app));
#endif
#ifdef CAIRN_HAVE_MAP
    commands.push_back(AddMapCommand(app));
#endif
    commands.push_back(AddBenchCommand(app));
    try {
      app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
      // --help and --version exit 0; every bad command line exits 1, as bad input does,
      // whichever CLI11 error it was.
      return app.exit(e) == 0 ? kExitOk : kExitFailure;
    }
    for (const Subcommand& command : commands) {
      if (command.app->parsed()) return command.run();
    }
    std::cerr << "cairn: no subcommand given (see cairn --help)\n";
    return kExitFailure;
  } catch (const std::exception& e) {
    std::cerr << "cairn: internal error: " << e.what() << "\n";
  } catch (...) {
    std::cerr << "cairn: internal error: unknown exception\n";
  }
  return kExitInternal;
}
