// vslam-viewer: a live top-down view of the stack (common/viewer/viewer_cli.hpp).
#include "util/command_line.hpp"
#include "util/log.hpp"
#include "viewer/viewer_cli.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("viewer");
  return vslam::viewer::runViewerCli(vslam::argumentsOf(argc, argv));
}
