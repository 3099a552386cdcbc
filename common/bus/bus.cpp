#include "bus/bus.hpp"

#include <exception>

#include "bus/loss_injector.hpp"
#include "util/log.hpp"

namespace vslam::bus {

Bus::Bus(lcm::LCM& lcm, const Clock& clock, std::string owner)
    : lcm_(lcm), clock_(clock), owner_(std::move(owner)) {}

Bus::~Bus() {
  for (auto& s : subscriptions_) {
    if (s->lcm_subscription) lcm_.unsubscribe(s->lcm_subscription);
  }
}

void Bus::add(std::unique_ptr<Subscription> sub, int queue_capacity) {
  sub->bus = this;
  // subscribeFunction, not the member-function subscribe: with GCC 12 and
  // -fsanitize=undefined, LCM 1.3.1's member-function trampoline calls the
  // handler on a null object.
  sub->lcm_subscription = lcm_.subscribeFunction(
      sub->channel,
      +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, Subscription* self) {
        self->onRaw(rbuf, channel);
      },
      sub.get());
  if (sub->lcm_subscription && queue_capacity > 0) {
    sub->lcm_subscription->setQueueCapacity(queue_capacity);
  }
  subscriptions_.push_back(std::move(sub));
}

void Bus::Subscription::onRaw(const lcm::ReceiveBuffer* rbuf, const std::string& on_channel) {
  LossStream* stream = bus->loss_ ? lossStream(on_channel) : nullptr;
  if (!stream) {
    handle(rbuf);
    return;
  }
  const int64_t recv_utime = rbuf->recv_utime;
  stream->offer(rbuf->data, rbuf->data_size, [this, recv_utime](const void* data, size_t size) {
    const lcm::ReceiveBuffer copy{const_cast<void*>(data), static_cast<uint32_t>(size), recv_utime};
    handle(&copy);
  });
}

LossStream* Bus::Subscription::lossStream(const std::string& on_channel) {
  // A subscription's channel may be a pattern: one stream per channel it matches.
  auto it = loss_streams.find(on_channel);
  if (it == loss_streams.end()) {
    LossStream* stream = bus->loss_->stream(bus->owner_ + "/" + channel, on_channel);
    it = loss_streams.emplace(on_channel, stream).first;
  }
  return it->second;
}

void Bus::releaseHeld() {
  for (auto& s : subscriptions_) {
    Subscription* sub = s.get();
    for (auto& [channel, stream] : sub->loss_streams) {
      if (!stream) continue;
      stream->release([sub](const void* data, size_t size) {
        const lcm::ReceiveBuffer copy{const_cast<void*>(data), static_cast<uint32_t>(size), 0};
        sub->handle(&copy);
      });
    }
  }
}

void Bus::Subscription::handle(const lcm::ReceiveBuffer* rbuf) {
  ++received;
  ++bus->counters_.received;
  try {
    if (!decodeAndHandle(rbuf)) return;
  } catch (const std::exception& e) {
    ++bus->counters_.handler_errors;
    log::error("handler for ", channel, " (", type_name, ") failed: ", e.what());
    return;
  }
  // On one clock, the wall clock LCM stamps arrivals with: the time a message
  // waited in the queue plus its handling. (Against the message's own utime
  // it mixed clocks: a simulator at 2x made it -100 s.)
  if (rbuf->recv_utime > 0) {
    bus->counters_.latency_sum_us += wallUtime() - rbuf->recv_utime;
    ++bus->counters_.latency_count;
  }
}

void Bus::publishRaw(const std::string& channel, const void* data, size_t size) {
  if (lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0) {
    ++counters_.published;
  } else {
    log::warn("publish on ", channel, " (", size, " bytes) failed");
  }
}

void Bus::reportMalformed(const std::string& channel, const std::string& why) {
  ++counters_.malformed;
  // At most one line per second: a flood of bad messages must not flood the log.
  std::lock_guard<std::mutex> lock(malformed_log_mutex_);
  const Utime now = monotonicUtime();
  if (now - last_malformed_log_ >= kMicrosPerSecond) {
    last_malformed_log_ = now;
    log::warn("malformed message on ", channel, ": ", why, " (", counters_.malformed.load(),
              " so far); ignored");
  }
}

double Bus::takeMeanLatencyMs() {
  // Not atomic as a pair; a message counted between the two reads only skews
  // one period's mean.
  const int64_t n = counters_.latency_count.exchange(0);
  const int64_t sum = counters_.latency_sum_us.exchange(0);
  return n > 0 ? 1e-3 * static_cast<double>(sum) / static_cast<double>(n) : 0.0;
}

std::map<std::string, int64_t> Bus::receivedPerChannel() const {
  std::map<std::string, int64_t> out;
  for (const auto& s : subscriptions_) out[s->channel] += s->received.load();
  return out;
}

}  // namespace vslam::bus
