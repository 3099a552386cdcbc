#pragma once
// A Stage is one unit of the pipeline (front-end, landmark DB, back-end,
// appearance SLAM, ...) bound to LCM through a Bus. The same Stage runs
//   - live, alone in its process over UDP multicast (processes/<role>/main.cpp),
//   - in lock-step with other stages over memq:// (vslam-replay), and
//   - under unit tests over memq://.
// Stages keep their algorithms in libraries that know nothing of LCM; the
// stage converts messages to domain types and back.

#include <memory>
#include <string>
#include <vector>

#include "bus/bus.hpp"
#include "config/stack_config.hpp"
#include "util/time.hpp"

namespace vslam::bus {

enum class ExecutionMode {
  kLive,      // worker threads allowed; newest data wins over completeness
  kLockstep,  // everything runs inline on the caller's thread, deterministic
};

struct HealthMetric {
  std::string name;
  double value = 0;
  std::string unit;
};

// What a stage reports about itself once per health period.
struct HealthReport {
  int level = 0;        // vslam::health_t::LEVEL_*
  std::string message;  // why level is not OK
  std::vector<HealthMetric> metrics;
  void add(std::string name, double value, std::string unit = "") {
    metrics.push_back({std::move(name), value, std::move(unit)});
  }
  void warn(const std::string& why);  // raises level to WARN and appends why
  void fail(const std::string& why);  // raises level to ERROR and appends why
};

struct StageContext {
  Bus& bus;
  const Clock& clock;  // wall clock live, log time in replay
  ExecutionMode mode;
  std::string instance;  // config instance name, e.g. "frontend_forward"
};

class Stage {
 public:
  virtual ~Stage() = default;
  // Subscribes to the stage's inputs. Called once, before any message.
  virtual void start(StageContext& ctx) = 0;
  // Called by the runner about every timer period (live: wall clock; replay:
  // log time, before the first event at or after `now`).
  virtual void onTimer(Utime now) { (void)now; }
  // Returns once all work handed to background workers is done (lock-step
  // barrier; a no-op for stages that work inline).
  virtual void drain() {}
  // Lock-step replay only: an input message on `channel` that will be
  // delivered a few events from now. A stage may start work on it that
  // depends on nothing but the message (feature extraction), to run on
  // another core while the events before it are handled; delivering the
  // message later must then give exactly what it would have without the
  // prefetch. Default: nothing.
  virtual void prefetch(const std::string& channel, const void* data, size_t size) {
    (void)channel, (void)data, (void)size;
  }
  // Fills the stage-specific part of the health message (period statistics).
  virtual void collectHealth(HealthReport& report) { (void)report; }
  // Flushes state (files, databases) and joins workers. Called once.
  virtual void stop() {}
  // Channels this stage publishes (for replay, which drops these channels
  // from its input so that re-running a stage replaces its old output).
  virtual std::vector<std::string> outputChannels() const = 0;
};

}  // namespace vslam::bus
