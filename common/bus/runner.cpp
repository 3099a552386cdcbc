#include "bus/runner.hpp"

#include <unistd.h>

#include <vslam/health_t.hpp>

#include "bus/loss_injector.hpp"
#include "bus/messages.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

namespace vslam::bus {

void HealthReport::warn(const std::string& why) {
  if (level < vslam::health_t::LEVEL_WARN) level = vslam::health_t::LEVEL_WARN;
  message += (message.empty() ? "" : "; ") + why;
}

void HealthReport::fail(const std::string& why) {
  level = vslam::health_t::LEVEL_ERROR;
  message += (message.empty() ? "" : "; ") + why;
}

struct StageRunner::Entry {
  std::string instance;
  std::unique_ptr<Bus> bus;
  std::unique_ptr<Stage> stage;
  std::unique_ptr<StageContext> context;
  int64_t last_received = 0;
  std::map<std::string, int64_t> last_per_channel;
  Utime last_health = 0;
};

StageRunner::StageRunner(lcm::LCM& lcm, const Clock& clock, ExecutionMode mode,
                         RunnerOptions options)
    : lcm_(lcm), clock_(clock), mode_(mode), options_(std::move(options)) {
  started_monotonic_ = monotonicUtime();
}

StageRunner::~StageRunner() { stopAll(); }

void StageRunner::add(std::string instance, std::unique_ptr<Stage> stage) {
  auto e = std::make_unique<Entry>();
  e->instance = std::move(instance);
  e->bus = std::make_unique<Bus>(lcm_, clock_, e->instance);
  if (loss_) e->bus->setLossInjector(loss_);
  e->stage = std::move(stage);
  e->context = std::make_unique<StageContext>(StageContext{*e->bus, clock_, mode_, e->instance});
  entries_.push_back(std::move(e));
}

void StageRunner::startAll() {
  for (auto& e : entries_) e->stage->start(*e->context);
  const Utime now = clock_.now();
  next_timer_ = now;
  next_health_ = now + fromSeconds(options_.health_period_s);
  for (auto& e : entries_) e->last_health = now;
  started_ = true;
}

void StageRunner::tick(Utime now) {
  if (!started_ || stopped_) return;
  // In replay, log time may jump: run at most one timer and one health per
  // tick, then realign, so a gap in a log does not trigger a burst.
  if (now >= next_timer_) {
    for (auto& e : entries_) e->stage->onTimer(now);
    next_timer_ = std::max(next_timer_ + fromSeconds(options_.timer_period_s), now);
  }
  if (now >= next_health_) {
    for (auto& e : entries_) publishHealth(*e, now);
    next_health_ = std::max(next_health_ + fromSeconds(options_.health_period_s), now);
  }
}

void StageRunner::prefetch(const std::string& channel, const void* data, size_t size) {
  if (!started_ || stopped_) return;
  for (auto& e : entries_) e->stage->prefetch(channel, data, size);
}

void StageRunner::drainAll() {
  for (auto& e : entries_) e->stage->drain();
}

void StageRunner::stopAll() {
  if (!started_ || stopped_) return;
  for (auto it = entries_.rbegin(); it != entries_.rend(); ++it) {
    (*it)->stage->drain();
    (*it)->stage->stop();
    publishHealth(**it, clock_.now());
  }
  stopped_ = true;
}

void StageRunner::releaseHeldMessages() {
  if (!loss_) return;
  loss_->stopHolding();
  for (auto& e : entries_) e->bus->releaseHeld();
}

std::vector<std::string> StageRunner::outputChannels() const {
  std::vector<std::string> out;
  for (const auto& e : entries_) {
    for (auto& c : e->stage->outputChannels()) out.push_back(c);
  }
  out.push_back(options_.health_channel);
  return out;
}

void StageRunner::publishHealth(Entry& e, Utime now) {
  HealthReport report;
  e.stage->collectHealth(report);

  const BusCounters& c = e.bus->counters();
  const double period_s = std::max(1e-6, toSeconds(now - e.last_health));
  const auto per_channel = e.bus->receivedPerChannel();
  for (const auto& [channel, count] : per_channel) {
    report.add("rx_hz_" + channel,
               static_cast<double>(count - e.last_per_channel[channel]) / period_s, "Hz");
  }
  e.last_per_channel = per_channel;
  e.last_health = now;

  vslam::health_t msg =
      healthMessage(options_.process_name, e.instance, now, started_monotonic_, report);
  msg.messages_received = c.received.load();
  msg.messages_published = c.published.load();
  msg.messages_dropped = c.dropped.load();
  msg.messages_malformed = c.malformed.load();
  msg.handler_latency_ms = e.bus->takeMeanLatencyMs();
  e.bus->publish(options_.health_channel, msg);
}

int StageRunner::runLive() {
  if (!started_) startAll();
  while (!stopRequested()) {
    // Blocks in select() for at most 100 ms, so a stop signal ends the loop promptly.
    const int status = lcm_.handleTimeout(static_cast<int>(options_.timer_period_s * 1000));
    if (status < 0 && !stopRequested()) {
      log::error("LCM handle failed; stopping");
      stopAll();
      return 1;
    }
    tick(clock_.now());
  }
  log::info("stop requested; flushing state");
  stopAll();
  return 0;
}

}  // namespace vslam::bus
