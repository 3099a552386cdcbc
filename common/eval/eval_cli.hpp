#pragma once
// The command line of vslam-eval, as a function so tests can run it in
// process. A mode flag selects what is evaluated: --trajectory (the
// default), --appearance or --measurements; each mode has its own options.
//
// Returns the exit code: 0 ok, 1 data problem, 2 bad command line.

#include <iosfwd>
#include <string>
#include <vector>

namespace vslam::eval {

int runEvalCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);
void printEvalUsage(std::ostream& os);

}  // namespace vslam::eval
