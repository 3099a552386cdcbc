#pragma once
// The command line of vslam-calibrate (see calibration.hpp), as a function
// so tests can run it in process. Returns 0 ok, 1 data problem (unreadable
// input, too few usable views), 2 bad command line.

#include <iosfwd>
#include <string>
#include <vector>

namespace vslam::calibration {

int runCalibrateCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace vslam::calibration
