// vslam-camera: a camera driver, one process per camera (see common/stages/camera_stage.hpp).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "camera", vslam::stages::driverStages());
}
