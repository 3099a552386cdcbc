#pragma once
// Human-readable table (stdout) and machine-readable JSON of a trajectory
// evaluation. The JSON layout is documented in docs/evaluation.md.

#include <filesystem>
#include <iosfwd>

#include "eval/evaluate.hpp"
#include "eval/json_report.hpp"

namespace vslam::eval {

// One column per estimate, one row per figure. Errors in metres, rotations
// in degrees.
void printTable(std::ostream& os, const TrajectoryReport& report);

// The report as JSON (non-finite figures as null); writeJson throws
// DataError if the file cannot be written.
Json toJson(const TrajectoryReport& report);
void writeJson(const std::filesystem::path& file, const TrajectoryReport& report);

}  // namespace vslam::eval
