#pragma once
// Reading an LCM log (lcm_eventlog format) event by event, with a choice of
// what damaged bytes mean. LCM's own reader silently passes over garbage
// between events and stops for good at a damaged event header; neither is
// what a tool wants:
//   - kThrow: the log must be intact (the evaluation tools). Every byte must
//     belong to an event and the tail must be complete; else LogError naming
//     the byte offset.
//   - kCutTail: as kThrow, but for an incomplete last event that starts like
//     one (a recording cut short by a power loss): the events before it are
//     read and stats().tail_bytes counts it (the evaluation tools).
//   - kSkip: lose as little as possible (the lock-step replay). At a damaged
//     header the reader skips to the next event's sync word and goes on;
//     gaps in the event numbers and skipped bytes are counted and warned
//     about, and so is an incomplete tail.

#include <cstdint>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <stdexcept>
#include <string>

namespace vslam::bus {

enum class LogDamage { kThrow, kCutTail, kSkip };

// The log cannot be opened or (kThrow) is damaged; what() names the file.
class LogError : public std::runtime_error {
 public:
  explicit LogError(const std::string& what) : std::runtime_error(what) {}
};

// What a reader read and (kSkip) passed over.
struct LogReadStats {
  int64_t events_read = 0;
  int64_t events_missing = 0;  // gaps in the event numbers (events lost to damage)
  int64_t bytes_skipped = 0;   // damaged bytes skipped to resynchronise
  int64_t tail_bytes = 0;      // bytes after the last complete event (a cut or corrupt tail)
};

class LogReader {
 public:
  // Throws LogError if the file is missing, a directory or cannot be opened.
  LogReader(const std::filesystem::path& log, LogDamage on_damage);
  ~LogReader();
  LogReader(const LogReader&) = delete;
  LogReader& operator=(const LogReader&) = delete;

  // The next event, valid until the next call, or nullptr at the end of the
  // log. kThrow: LogError at the first byte that is not part of an event.
  const lcm::LogEvent* next();
  // Byte offset in the file of the event next() returned last.
  long eventOffset() const { return event_offset_; }
  const LogReadStats& stats() const { return stats_; }
  const std::string& name() const { return name_; }

 private:
  long nextOversizedEvent(int64_t* claimed);
  bool skipToNextEvent(long from);
  bool tailIsOneCutEvent();
  void finish();

  std::string name_;
  LogDamage on_damage_;
  std::unique_ptr<lcm::LogFile> file_;
  FILE* fp_ = nullptr;
  long end_of_last_event_ = 0;
  long file_size_ = 0;
  long event_offset_ = 0;
  int64_t last_eventnum_ = -1;
  bool at_end_ = false;
  LogReadStats stats_;
};

}  // namespace vslam::bus
