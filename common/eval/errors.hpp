#pragma once
// The two kinds of failure of the evaluation tools, mapped to exit codes by
// their command lines: a bad command line (exit 2) and bad or missing data
// (exit 1: unreadable or malformed files, missing channels, empty
// trajectories, no associated poses, damaged logs).

#include <stdexcept>
#include <string>

#include "util/command_line.hpp"

namespace vslam::eval {

inline constexpr int kExitDataError = 1;

class UsageError : public std::runtime_error {
 public:
  explicit UsageError(const std::string& what) : std::runtime_error(what) {}
};

class DataError : public std::runtime_error {
 public:
  explicit DataError(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace vslam::eval
