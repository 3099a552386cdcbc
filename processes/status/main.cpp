// vslam-status: the status board of a running stack, from HEALTH
// (common/status/status_cli.hpp).
#include "status/status_cli.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("status");
  return vslam::status::runStatusCli(vslam::argumentsOf(argc, argv));
}
