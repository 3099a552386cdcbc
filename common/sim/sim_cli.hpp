#pragma once
// vslam-sim's command line: the simulated robot (sim/simulator.hpp), either
// publishing live on the bus, paced to real time (or --speed times it), or
// writing an LCM log as fast as it can (--out). processes/sim/main.cpp is one
// call to this. It lives in vslam_sim, which links the bus: the live run
// publishes on LCM and waits for its consumers' health.
//
// Exit codes: 0 done (or stopped by a signal), 1 the bus cannot be opened,
// the processes waited for are silent, or the run fails, 2 bad command line,
// configuration or scenario.

#include <string>
#include <vector>

namespace vslam::sim {

int runSimCli(const std::vector<std::string>& args);

}  // namespace vslam::sim
