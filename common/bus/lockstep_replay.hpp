#pragma once
// Lock-step replay: feeds an LCM log to stages over memq://, one event at a
// time, and lets every stage finish its work on the event (including the
// messages its handlers publish, and those published in answer to them)
// before the next event. No wall clock, no threads, no network: the output
// depends only on the input log and the configuration, so two runs are
// byte-identical, and the run is as fast as the CPU allows.
//
// Stage time comes from the log (each event's timestamp). Health messages
// carry wall-clock timing and are left out of the output unless asked for.

#include <cstddef>
#include <filesystem>
#include <map>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "bus/log_writer.hpp"
#include "bus/loss_injector.hpp"
#include "bus/runner.hpp"

namespace vslam::bus {

struct ReplayOptions {
  std::filesystem::path input;
  std::filesystem::path output;  // empty: write nothing
  std::string health_channel = "HEALTH";
  double health_period_s = 1.0;
  bool keep_health = false;           // also record the stages' health messages
  bool keep_inputs = true;            // record the input events fed to the stages
  std::string input_channels = ".*";  // regex: only feed matching input channels
  // Input events offered to the stages ahead of delivery (Stage::prefetch),
  // so that pure per-message work (SIFT) overlaps with the events before it.
  std::size_t prefetch_events = 48;
  // Messages lost, repeated or swapped on their way to each stage, inputs and
  // what stages publish alike; the output log records what was sent. None by
  // default (then the run is exactly the run without it).
  LossOptions loss;
  // A progress line on stderr when it is a terminal (util/progress.hpp).
  bool show_progress = false;
};

struct ReplayStats {
  int64_t events_read = 0;
  int64_t events_fed = 0;
  int64_t events_dropped = 0;  // on a channel a stage publishes, or not matching input_channels
  int64_t events_written = 0;
  int64_t messages_published = 0;  // by stages
  double log_seconds = 0;          // span of the input log's timestamps
  double wall_seconds = 0;
  int64_t events_missing = 0;    // gaps in the input's event numbers (damaged events skipped)
  int64_t bytes_skipped = 0;     // damaged bytes skipped to resynchronise
  bool input_truncated = false;  // the log ended inside an event (corrupt or cut tail)
  int64_t input_bytes_unread = 0;
  LossCounts loss;  // summed over the stages' subscriptions
  std::map<std::string, LossCounts> loss_per_channel;
};

class LockstepReplay {
 public:
  // Throws std::invalid_argument for bad loss options (validateLossOptions).
  explicit LockstepReplay(ReplayOptions options);
  ~LockstepReplay();

  lcm::LCM& lcm() { return *lcm_; }
  const Clock& clock() const { return clock_; }
  void addStage(std::string instance, std::unique_ptr<Stage> stage);
  // Runs the whole log, once. Throws std::runtime_error if a file cannot be opened.
  ReplayStats run();

 private:
  void onAnyMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void dispatchUntilQuiet();

  ReplayOptions options_;
  ManualClock clock_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::unique_ptr<StageRunner> runner_;
  std::shared_ptr<LossInjector> loss_;  // null: no loss
  std::unique_ptr<LogWriter> out_;
  bool next_is_input_ = false;
  bool ran_ = false;
  ReplayStats stats_;
};

}  // namespace vslam::bus
