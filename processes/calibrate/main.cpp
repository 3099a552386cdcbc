// vslam-calibrate: camera intrinsics and distortion from views of a
// chessboard or ChArUco board (see common/calibration/calibration.hpp,
// docs/calibration.md).
#include <iostream>

#include "calibration/calibrate_cli.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("calibrate");
  vslam::installStopSignalHandlers();  // Ctrl-C ends a live capture and calibrates what it has
  return vslam::calibration::runCalibrateCli({argv + 1, argv + argc}, std::cout, std::cerr);
}
