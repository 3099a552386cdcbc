#include "util/log.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <mutex>

namespace vslam::log {
namespace {
std::mutex g_mutex;
std::string g_name = "vslam";
std::atomic<int> g_min_level{static_cast<int>(Level::kInfo)};

const char* levelTag(Level level) {
  switch (level) {
    case Level::kDebug:
      return "DEBUG";
    case Level::kInfo:
      return "INFO ";
    case Level::kWarn:
      return "WARN ";
    case Level::kError:
      return "ERROR";
  }
  return "?";
}
}  // namespace

void setProcessName(const std::string& name) {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_name = name;
}

void setMinLevel(Level level) { g_min_level = static_cast<int>(level); }
Level minLevel() { return static_cast<Level>(g_min_level.load()); }

void write(Level level, const std::string& message) {
  using namespace std::chrono;
  const auto now = system_clock::now();
  const std::time_t secs = system_clock::to_time_t(now);
  const auto ms = duration_cast<milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  localtime_r(&secs, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%H:%M:%S", &tm);
  std::lock_guard<std::mutex> lock(g_mutex);
  std::fprintf(stderr, "%s.%03d %s [%s] %s\n", stamp, static_cast<int>(ms), levelTag(level),
               g_name.c_str(), message.c_str());
  std::fflush(stderr);
}

}  // namespace vslam::log
