#pragma once
// Human-readable table (stdout) and machine-readable JSON of a trajectory
// evaluation. The JSON layout is documented in docs/evaluation.md.

#include <filesystem>
#include <iosfwd>

#include "eval/evaluate.hpp"

namespace vslam::eval {

// One column per estimate, one row per figure. Errors in metres, rotations
// in degrees.
void printTable(std::ostream& os, const TrajectoryReport& report);

// Writes the report as JSON; throws DataError if the file cannot be written.
void writeJson(const std::filesystem::path& file, const TrajectoryReport& report);
std::string toJson(const TrajectoryReport& report);

}  // namespace vslam::eval
