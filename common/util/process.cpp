#include "util/process.hpp"

#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>

namespace vslam {
namespace {
std::atomic<bool> g_stop{false};
std::atomic<int> g_signals_seen{0};

void onStopSignal(int) {
  if (g_signals_seen.fetch_add(1) >= 1) {
    // Second signal: the clean path is stuck; leave now.
    _exit(130);
  }
  g_stop.store(true);
}
}  // namespace

void installStopSignalHandlers() {
  struct sigaction sa {};
  sa.sa_handler = onStopSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: blocking waits return early with EINTR
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  // A subscriber that goes away must not kill a publisher writing to a pipe.
  std::signal(SIGPIPE, SIG_IGN);
}

bool stopRequested() { return g_stop.load(); }
void requestStop() { g_stop.store(true); }
void clearStopRequest() {
  g_stop.store(false);
  g_signals_seen.store(0);
}

void tuneAllocatorForSteadyState() {
  // Large blocks from the heap, not mmap, and never trimmed back to the OS.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 512 * 1024 * 1024);
  mallopt(M_TOP_PAD, 64 * 1024 * 1024);
}

std::string hostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "";
  return name;
}

ResourceUsage currentResourceUsage() {
  ResourceUsage usage;
  struct rusage ru {};
  if (getrusage(RUSAGE_SELF, &ru) == 0) {
    usage.cpu_seconds = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
                        1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  }
  if (FILE* f = std::fopen("/proc/self/statm", "r")) {
    long pages_total = 0, pages_resident = 0;
    if (std::fscanf(f, "%ld %ld", &pages_total, &pages_resident) == 2) {
      usage.rss_bytes = static_cast<int64_t>(pages_resident) * sysconf(_SC_PAGESIZE);
    }
    std::fclose(f);
  }
  return usage;
}

}  // namespace vslam
