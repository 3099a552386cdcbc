// vslam-sim: the simulated robot, live on the bus or into an LCM log
// (common/sim/sim_cli.hpp).
#include "sim/sim_cli.hpp"

int main(int argc, char** argv) { return vslam::sim::runSimCli({argv + 1, argv + argc}); }
