// vslam-backend: the vSLAM pre-filter and SLAM back-end (see common/stages/backend_stage.hpp).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "backend", vslam::stages::builtinStages());
}
