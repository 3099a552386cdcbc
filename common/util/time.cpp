#include "util/time.hpp"

#include <chrono>

namespace vslam {

Utime wallUtime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

Utime monotonicUtime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(steady_clock::now().time_since_epoch()).count();
}

}  // namespace vslam
