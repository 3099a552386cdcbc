// vslam-deadreckon: odometry-only pose baseline (see common/stages/deadreckon_stage.hpp).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "deadreckon", vslam::stages::builtinStages());
}
