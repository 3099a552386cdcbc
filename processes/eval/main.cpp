// vslam-eval: evaluates estimated trajectories against ground truth, from an
// LCM log or TUM files (see common/eval/eval_cli.hpp, docs/evaluation.md).
#include <iostream>

#include "eval/eval_cli.hpp"
#include "util/log.hpp"

int main(int argc, char** argv) {
  vslam::log::setProcessName("eval");
  return vslam::eval::runEvalCli({argv + 1, argv + argc}, std::cout, std::cerr);
}
