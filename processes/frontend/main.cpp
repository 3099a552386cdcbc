// vslam-frontend: the visual front-end for one camera (common/stages/frontend_stage.hpp).
// One instance per camera: --instance frontend_forward, --instance frontend_backward.
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "frontend", vslam::stages::builtinStages());
}
