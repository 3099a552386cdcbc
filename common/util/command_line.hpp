#pragma once
// What every vslam binary's command line shares: the exit statuses, and the
// CLI11 parse with one way of answering --help and a bad command line
// ("TOOL: what (see --help)" on err, exit 2).

#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace vslam {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // a tool may name its own meaning of 1
inline constexpr int kExitUsage = 2;    // a bad command line or configuration

// Parses args (argv without the program name). Returns the exit status when
// the program should stop here: kExitOk after printing the help to out
// (--help), kExitUsage after naming the error on err; nothing when it should
// go on. `check` runs after a successful parse and may throw
// CLI::ValidationError for rules across options.
std::optional<int> parseCommandLine(CLI::App& app, const std::string& tool,
                                    const std::vector<std::string>& args, std::ostream& out,
                                    std::ostream& err, const std::function<void()>& check = {});

// argv[1..argc) as parseCommandLine takes it.
std::vector<std::string> argumentsOf(int argc, const char* const* argv);

}  // namespace vslam
