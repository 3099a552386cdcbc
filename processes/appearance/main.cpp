// vslam-appearance: appearance-based topological SLAM (Lee & Sowmya) beside
// the metric stack (see common/stages/appearance_stage.hpp, docs/appearance.md).
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"

int main(int argc, char** argv) {
  return vslam::bus::runStageProcess(argc, argv, "appearance", vslam::stages::builtinStages());
}
