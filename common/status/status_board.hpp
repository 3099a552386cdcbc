#pragma once
// The status board of a running stack (vslam-status): every process that
// publishes HEALTH, one row each, from the messages alone (no LCM here: the
// command line decodes and feeds them, tests feed them directly).
//
// A row is a process instance on a host. From two successive messages of one
// pid come the rates (CPU %, messages received and published per second);
// a new pid under the same instance is a restart, counted. A row is stale
// when nothing came for `stale_after_s`; an input channel (the stage's
// rx_hz_<CHANNEL> figures) is quiet when a steady input (messages in each
// of `steady_reports` reports in a row: odometry, images, measurements; not
// the bursts of landmark proposals) has had none for `quiet_reports`
// reports, which a process's own level does not always say (a back-end
// without odometry stays OK). Key figures are picked per program.
//
// Everything here arrived over the network: strings are cut to a width when
// shown, non-finite numbers shown as "-", and the board holds at most
// `max_rows` rows (the oldest silent ones make way), so a flood of invented
// instance names cannot grow it without bound.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace vslam::status {

struct Metric {
  std::string name;
  double value = 0;
  std::string unit;
};

// One HEALTH message, as received.
struct HealthSample {
  double received_s = 0;  // when it arrived, on the board's clock (seconds)
  std::string process, instance, host;
  int32_t pid = 0;
  double uptime_s = 0;
  int level = 0;  // 0 OK, 1 WARN, 2 ERROR (health_t's LEVEL_*)
  std::string message;
  double cpu_seconds = 0;
  int64_t rss_bytes = 0;
  int64_t received = 0, published = 0, dropped = 0, malformed = 0;
  double handler_latency_ms = 0;
  std::vector<Metric> metrics;
};

struct BoardOptions {
  double stale_after_s = 3.0;  // three health periods
  size_t max_rows = 256;
  int steady_reports = 5;  // an input with messages in this many reports in a row is steady
  int quiet_reports = 2;   // a steady input without messages in this many is quiet
};

struct Row {
  std::string instance, host, process;
  int32_t pid = 0;
  int restarts = 0;  // pids seen after the first
  double uptime_s = 0;
  int level = 0;
  std::string message;
  double silent_s = 0;  // since the last message
  bool stale = false;
  double cpu_percent = -1;  // -1: one message only so far
  double rx_per_s = -1, tx_per_s = -1;
  int64_t rss_bytes = 0, dropped = 0, malformed = 0;
  double handler_latency_ms = 0;
  std::vector<std::string> quiet_inputs;  // channels that stopped
  std::vector<Metric> key_figures;        // the program's own, in its order
};

class StatusBoard {
 public:
  explicit StatusBoard(BoardOptions options = {}) : options_(options) {}

  void add(const HealthSample& sample);
  // Rows sorted by host, then instance, as of `now_s`.
  std::vector<Row> rows(double now_s) const;
  bool anyStale(double now_s) const;
  size_t size() const { return entries_.size(); }

  // The figures shown for a program (its `process` name), e.g. vslam-backend:
  // effective_sample_size, kidnapped, landmarks, pre-filter rejection.
  static std::vector<Metric> keyFigures(const HealthSample& sample);

 private:
  struct Entry {
    HealthSample last, previous;  // previous: an earlier message of the same pid
    bool has_previous = false;
    int restarts = 0;
    struct Input {
      int busy_run = 0, idle_run = 0;  // reports in a row with and without messages
      bool steady = false;
    };
    std::map<std::string, Input> inputs;  // by channel
  };
  BoardOptions options_;
  std::map<std::pair<std::string, std::string>, Entry> entries_;  // (host, instance)
};

// The board as a text table `width` columns wide (long fields cut), then
// one line per row that is not OK: its level message, stale or quiet inputs.
std::string renderBoard(const std::vector<Row>& rows, int width);

}  // namespace vslam::status
