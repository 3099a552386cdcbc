#include "util/log.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <mutex>

namespace vslam::log {
namespace {
std::mutex g_mutex;
std::string g_name = "vslam";
std::string g_progress;  // the progress line on the terminal now ("" = none)

// Erases the progress line, if one is showing, so that a log line starts on a
// clean line (g_mutex held).
void clearProgressLine() {
  if (!g_progress.empty()) std::fputs("\r\033[K", stderr);
}

// VSLAM_LOG_LEVEL=debug|info|warn|error sets the start-up level (default
// info); an unknown value is named on stderr and ignored.
int initialLevel() {
  const char* env = std::getenv("VSLAM_LOG_LEVEL");
  if (env == nullptr || *env == '\0') return static_cast<int>(Level::kInfo);
  const char* names[] = {"debug", "info", "warn", "error"};
  for (int i = 0; i < 4; ++i) {
    if (std::strcmp(env, names[i]) == 0) return i;
  }
  std::fprintf(stderr, "VSLAM_LOG_LEVEL=%s: expected debug, info, warn or error; using info\n",
               env);
  return static_cast<int>(Level::kInfo);
}
std::atomic<int> g_min_level{initialLevel()};

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
  clearProgressLine();
  std::fprintf(stderr, "%s.%03d %s [%s] %s\n", stamp, static_cast<int>(ms), levelTag(level),
               g_name.c_str(), message.c_str());
  std::fputs(g_progress.c_str(), stderr);  // back under the log line
  std::fflush(stderr);
}

void progress(const std::string& line) {
  std::lock_guard<std::mutex> lock(g_mutex);
  clearProgressLine();
  g_progress = line;
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
}

void progressDone() {
  std::lock_guard<std::mutex> lock(g_mutex);
  clearProgressLine();
  g_progress.clear();
  std::fflush(stderr);
}

}  // namespace vslam::log
