#pragma once
// Runs stages on one lcm::LCM: live until SIGINT/SIGTERM, or driven event by
// event by the lock-step replay. Publishes one health message per stage per
// health period.

#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <vector>

#include "bus/stage.hpp"

namespace vslam::bus {

struct RunnerOptions {
  std::string process_name;  // e.g. "vslam-backend" or "vslam-replay"
  std::string health_channel;
  double health_period_s = 1.0;
  double timer_period_s = 0.1;  // Stage::onTimer cadence
};

class StageRunner {
 public:
  StageRunner(lcm::LCM& lcm, const Clock& clock, ExecutionMode mode, RunnerOptions options);
  ~StageRunner();

  // Message loss for every stage's subscriptions (Bus::setLossInjector);
  // before add().
  void setLossInjector(std::shared_ptr<LossInjector> injector) { loss_ = std::move(injector); }
  // Takes ownership; the stage's Bus is created here so counters are per stage.
  void add(std::string instance, std::unique_ptr<Stage> stage);
  void startAll();
  // Timers and health due at `now`.
  void tick(Utime now);
  void drainAll();
  // Lock-step replay: offers every started stage an input message ahead of its delivery.
  void prefetch(const std::string& channel, const void* data, size_t size);
  // Stops stages in reverse order (flushing their state) and publishes a last health.
  void stopAll();
  // No more messages come: the loss injector holds none back from now on, and
  // delivers those it held (their handlers may publish: dispatch after).
  void releaseHeldMessages();
  // Live loop: handle messages until stopRequested(); returns the exit code.
  int runLive();

  std::vector<std::string> outputChannels() const;
  size_t size() const { return entries_.size(); }

 private:
  struct Entry;
  void publishHealth(Entry& e, Utime now);

  lcm::LCM& lcm_;
  const Clock& clock_;
  ExecutionMode mode_;
  RunnerOptions options_;
  std::vector<std::unique_ptr<Entry>> entries_;
  std::shared_ptr<LossInjector> loss_;
  Utime next_timer_ = 0;
  Utime next_health_ = 0;
  Utime started_monotonic_ = 0;
  bool started_ = false;
  bool stopped_ = false;
};

}  // namespace vslam::bus
