// vslam-odometry-bridge: a robot base's odometry lines to vslam.odometry_t
// (see common/stages/odometry_bridge_stage.hpp, docs/odometry.md).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "odometry_bridge", vslam::stages::driverStages());
}
