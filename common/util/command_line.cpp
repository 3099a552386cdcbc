#include "util/command_line.hpp"

#include <CLI/CLI.hpp>
#include <ostream>

namespace vslam {

std::optional<int> parseCommandLine(CLI::App& app, const std::string& tool,
                                    const std::vector<std::string>& args, std::ostream& out,
                                    std::ostream& err, const std::function<void()>& check) {
  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them reversed
    app.parse(reversed);
    if (check) check();
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {  // --help
      out << app.help();
      return kExitOk;
    }
    err << tool << ": " << e.what() << " (see --help)\n";
    return kExitUsage;
  }
  return std::nullopt;
}

std::vector<std::string> argumentsOf(int argc, const char* const* argv) {
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return args;
}

}  // namespace vslam
