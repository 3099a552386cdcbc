#pragma once
// The command line of vslam-import (see tum_import.hpp), as a function so
// tests can run it in process. Returns 0 ok, 1 data problem, 2 bad command line.

#include <iosfwd>
#include <string>
#include <vector>

namespace vslam::eval {

int runImportCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace vslam::eval
