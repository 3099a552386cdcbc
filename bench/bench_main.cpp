// The main() of every vslam benchmark program: tunes the allocator as every
// vslam process does at start-up (util/process.hpp; VSLAM_DEFAULT_MALLOC=1
// measures without it), then runs the registered benchmarks.
#include <benchmark/benchmark.h>

#include <cstdlib>

#include "util/process.hpp"

int main(int argc, char** argv) {
  if (!std::getenv("VSLAM_DEFAULT_MALLOC")) vslam::tuneAllocatorForSteadyState();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
