#pragma once
// TUM RGB-D trajectory files: one pose per line,
//   timestamp tx ty tz qx qy qz qw
// timestamp in seconds, position in metres, orientation as a unit quaternion
// (Hamilton, x y z w order). Lines starting with '#' (after optional blanks)
// and empty lines are skipped; commas and tabs separate fields like blanks,
// as in the TUM scripts. Unlike the scripts, a malformed line is an error
// (DataError naming file:line), not silently skipped.

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "eval/trajectory.hpp"

namespace vslam::eval {

// Reads a TUM file; the result is sorted by time (duplicate timestamps: the
// last line wins, as with the scripts' dictionaries). Throws DataError for a
// missing/unreadable file, a malformed line (file:line), or no poses at all.
Trajectory readTumFile(const std::filesystem::path& file);
// Same, from a stream; `origin` names it in messages.
Trajectory parseTum(std::istream& in, const std::string& origin);

// Writes `traj` in TUM format (timestamps with microsecond precision).
// Throws DataError if the file cannot be written.
void writeTumFile(const std::filesystem::path& file, const Trajectory& traj);

// Splits a line as the TUM scripts do (blanks, tabs and commas separate).
std::vector<std::string> splitTumFields(const std::string& line);
// True for lines the TUM scripts skip: empty, or starting with '#'.
bool isTumCommentOrBlank(const std::string& line);

}  // namespace vslam::eval
