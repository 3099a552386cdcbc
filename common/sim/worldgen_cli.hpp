#pragma once
// vslam-worldgen's command line: a random home for the benchmark
// (sim/home_generator.hpp): writes DIR/world.yaml and DIR/scenario.yaml,
// checks that both load, and prints the home's one-line summary.
// processes/worldgen/main.cpp is one call to this.
//
// Exit codes: 0 written, 1 the files cannot be written or do not load,
// 2 bad command line.

#include <string>
#include <vector>

namespace vslam::sim {

int runWorldgenCli(const std::vector<std::string>& args);

}  // namespace vslam::sim
