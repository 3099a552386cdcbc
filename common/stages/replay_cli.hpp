#pragma once
// vslam-replay's command line: runs the stack's stages in lock-step over a
// recorded LCM log (bus/lockstep_replay.hpp). processes/replay/main.cpp is
// one call to this.
//
// Exit codes: 0 replayed, 1 the log is damaged or cut short (what could be
// read was replayed and written), 2 bad command line or configuration.

#include <string>
#include <vector>

namespace vslam::stages {

int runReplayCli(const std::vector<std::string>& args);

}  // namespace vslam::stages
