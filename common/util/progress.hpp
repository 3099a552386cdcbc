#pragma once
// Progress of a long job on a terminal: done/total, rate and time left, on
// one line at the bottom of stderr (log lines scroll above it), rewritten at
// most twice a second. Silent when stderr is not a terminal, so logs and
// scripts see only the log lines.
//
//   ProgressMeter meter("replay", file_bytes, ProgressMeter::kBytes);
//   while (...) meter.update(bytes_read, "412 s of log, 4.1x real time");
//   meter.finish();

#include <cstdint>
#include <string>

namespace vslam {

class ProgressMeter {
 public:
  enum Unit { kBytes, kSeconds, kItems };
  // total <= 0: unknown (no percentage, no time left). `enabled` is for tests.
  ProgressMeter(std::string label, double total, Unit unit, bool enabled = stderrIsTerminal());
  ~ProgressMeter() { finish(); }
  ProgressMeter(const ProgressMeter&) = delete;
  ProgressMeter& operator=(const ProgressMeter&) = delete;

  // Cheap enough to call for every event: it looks at the clock only every
  // 64th call, and calls `detail` (returning a std::string shown after the
  // rate) only when the line is rewritten.
  void update(double done) {
    if (due()) show(done, "");
  }
  template <class DetailFn>
  void update(double done, DetailFn detail) {
    if (due()) show(done, detail());
  }
  void finish();  // erases the line
  // When the total is only known as the job goes (a simulated route).
  void setTotal(double total) { total_ = total; }

  // The line for `done` after `elapsed_s` (what update shows).
  std::string line(double done, double elapsed_s, const std::string& detail) const;

  static bool stderrIsTerminal();

 private:
  bool due();
  void show(double done, const std::string& detail);

  std::string label_;
  double total_;
  Unit unit_;
  bool enabled_;
  bool shown_ = false;
  int64_t start_us_ = 0, last_us_ = 0;
  uint32_t calls_ = 0;
};

}  // namespace vslam
