#include "util/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "util/log.hpp"
#include "util/time.hpp"

namespace vslam {
namespace {

std::string amount(double v, ProgressMeter::Unit unit) {
  char buf[48];
  switch (unit) {
    case ProgressMeter::kBytes:
      if (v >= 1e9) {
        std::snprintf(buf, sizeof(buf), "%.2f GB", v / 1e9);
      } else {
        std::snprintf(buf, sizeof(buf), "%.0f MB", v / 1e6);
      }
      break;
    case ProgressMeter::kSeconds:
      std::snprintf(buf, sizeof(buf), "%.0f s", v);
      break;
    case ProgressMeter::kItems:
      std::snprintf(buf, sizeof(buf), "%.0f", v);
      break;
  }
  return buf;
}

std::string rate(double per_s, ProgressMeter::Unit unit) {
  char buf[48];
  switch (unit) {
    case ProgressMeter::kBytes:
      std::snprintf(buf, sizeof(buf), "%.1f MB/s", per_s / 1e6);
      break;
    case ProgressMeter::kSeconds:
      std::snprintf(buf, sizeof(buf), "%.1fx real time", per_s);
      break;
    case ProgressMeter::kItems:
      std::snprintf(buf, sizeof(buf), "%.1f/s", per_s);
      break;
  }
  return buf;
}

std::string duration(double s) {
  char buf[32];
  const long t = std::lround(s);
  if (t >= 3600) {
    std::snprintf(buf, sizeof(buf), "%ldh%02ldm", t / 3600, t / 60 % 60);
  } else {
    std::snprintf(buf, sizeof(buf), "%ldm%02lds", t / 60, t % 60);
  }
  return buf;
}

}  // namespace

ProgressMeter::ProgressMeter(std::string label, double total, Unit unit, bool enabled)
    : label_(std::move(label)), total_(total), unit_(unit), enabled_(enabled) {
  start_us_ = last_us_ = monotonicUtime();
}

bool ProgressMeter::stderrIsTerminal() { return isatty(STDERR_FILENO) == 1; }

std::string ProgressMeter::line(double done, double elapsed_s, const std::string& detail) const {
  std::string s = label_ + ": " + amount(done, unit_);
  const bool known = total_ > 0;
  if (known) {
    char pct[16];
    std::snprintf(pct, sizeof(pct), " (%.0f%%)", 100.0 * std::min(1.0, done / total_));
    s += " of " + amount(total_, unit_) + pct;
  }
  if (elapsed_s > 0 && done > 0) {
    const double per_s = done / elapsed_s;
    s += ", " + rate(per_s, unit_);
    if (known && done < total_) s += ", " + duration((total_ - done) / per_s) + " left";
  }
  if (!detail.empty()) s += ", " + detail;
  return s;
}

bool ProgressMeter::due() {
  if (!enabled_ || (++calls_ & 63u) != 1u) return false;
  const int64_t now = monotonicUtime();
  if (shown_ && now - last_us_ < 500000) return false;
  last_us_ = now;
  return true;
}

void ProgressMeter::show(double done, const std::string& detail) {
  shown_ = true;
  log::progress(line(done, toSeconds(last_us_ - start_us_), detail));
}

void ProgressMeter::finish() {
  if (!shown_) return;
  shown_ = false;
  log::progressDone();
}

}  // namespace vslam
