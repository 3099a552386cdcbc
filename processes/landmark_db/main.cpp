// vslam-landmark-db: the landmark database manager (see common/stages/landmark_db_stage.hpp).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "landmark_db", vslam::stages::builtinStages());
}
