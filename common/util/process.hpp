#pragma once
// Process-level plumbing shared by every vslam-* program: stop signals,
// allocator tuning, resource usage.

#include <cstdint>
#include <string>

namespace vslam {

// Installs SIGINT/SIGTERM handlers that set a flag (a second signal of the
// same kind exits at once, for a wedged process). Loops poll stopRequested()
// between blocking waits of at most ~100 ms.
void installStopSignalHandlers();
bool stopRequested();
void requestStop();  // for tests and for fatal conditions found in a handler
void clearStopRequest();

// Keeps freed memory in the process instead of returning it to the kernel.
// On these VMs a first-touch page fault costs ~10 us per 4 KiB page and
// glibc's default thresholds made SIFT 3x slower by re-faulting its image
// pyramid every frame (docs/measured-facts). Call once at start-up.
void tuneAllocatorForSteadyState();

struct ResourceUsage {
  double cpu_seconds = 0.0;  // user + system
  int64_t rss_bytes = 0;
};
ResourceUsage currentResourceUsage();

// This machine's host name ("" if the system will not say).
std::string hostName();

}  // namespace vslam
