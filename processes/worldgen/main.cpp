// vslam-worldgen: a random home for the benchmark (common/sim/worldgen_cli.hpp).
#include "sim/worldgen_cli.hpp"

int main(int argc, char** argv) { return vslam::sim::runWorldgenCli({argv + 1, argv + argc}); }
