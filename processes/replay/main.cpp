// vslam-replay: runs the stack's stages in lock-step over a recorded LCM log
// (common/stages/replay_cli.hpp, common/bus/lockstep_replay.hpp).
#include "stages/replay_cli.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("replay");
  vslam::tuneAllocatorForSteadyState();
  return vslam::stages::runReplayCli({argv + 1, argv + argc});
}
