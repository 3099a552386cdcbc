#pragma once
// Minimal structured logging: every line carries wall-clock time, level and the
// process instance name, so the interleaved output of a process group stays
// readable. Thread-safe; writes to stderr. The environment variable
// VSLAM_LOG_LEVEL (debug, info, warn, error) sets the level at start-up.

#include <array>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

namespace vslam::log {

enum class Level { kDebug = 0, kInfo = 1, kWarn = 2, kError = 3 };

// Sets the name printed on every line (e.g. "frontend_forward").
void setProcessName(const std::string& name);
void setMinLevel(Level level);
Level minLevel();
void write(Level level, const std::string& message);

// A status line kept at the bottom of a terminal (util/progress.hpp writes
// it): log lines are printed above it. Only for a stderr that is a terminal.
void progress(const std::string& line);
void progressDone();  // erases it

namespace detail {
inline void append(std::ostringstream&) {}
template <class T, class... Rest>
void append(std::ostringstream& os, const T& first, const Rest&... rest) {
  os << first;
  append(os, rest...);
}
template <class... Args>
void emit(Level level, const Args&... args) {
  if (level < minLevel()) return;
  std::ostringstream os;
  append(os, args...);
  write(level, os.str());
}
}  // namespace detail

template <class... Args>
void debug(const Args&... args) {
  detail::emit(Level::kDebug, args...);
}
template <class... Args>
void info(const Args&... args) {
  detail::emit(Level::kInfo, args...);
}
template <class... Args>
void warn(const Args&... args) {
  detail::emit(Level::kWarn, args...);
}
template <class... Args>
void error(const Args&... args) {
  detail::emit(Level::kError, args...);
}

// Warnings for a stream of bad input: at most one line per reason per
// period, the next line counting those it suppressed. Time is the caller's
// (stage time, so a replay logs the same lines as the live run).
template <std::size_t NumReasons>
class RateLimitedWarnings {
 public:
  explicit RateLimitedWarnings(int64_t period_us) : period_us_(period_us) {}

  template <class... Args>
  void warn(std::size_t reason, int64_t now_us, const Args&... args) {
    if (last_us_[reason] != 0 && now_us - last_us_[reason] < period_us_) {
      ++suppressed_[reason];
      return;
    }
    if (suppressed_[reason] > 0) {
      log::warn(args..., " (", suppressed_[reason], " more like it not logged)");
    } else {
      log::warn(args...);
    }
    last_us_[reason] = now_us;
    suppressed_[reason] = 0;
  }

 private:
  int64_t period_us_;
  std::array<int64_t, NumReasons> last_us_{};
  std::array<int64_t, NumReasons> suppressed_{};
};

}  // namespace vslam::log
