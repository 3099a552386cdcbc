#pragma once
// The one place that touches lcm::LCM for a stage: typed subscribe/publish
// with decode checks and counters for the health message.
//
// LCM 1.3.1's typed subscribe prints "error decoding" to stderr and drops the
// message silently; here every message is decoded by us through
// checkedDecode (its counts are checked against its bytes before the
// generated decoder allocates anything), a message that fails the check or
// leaves trailing bytes is counted as malformed and logged (rate-limited) with
// its channel and the field at fault, and an exception thrown by a handler is
// logged and counted without ending the process.

#include <atomic>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#include "bus/checked_decode.hpp"
#include "util/time.hpp"

namespace vslam::bus {

class LossInjector;  // bus/loss_injector.hpp
class LossStream;

struct BusCounters {
  std::atomic<int64_t> received{0};
  std::atomic<int64_t> published{0};
  std::atomic<int64_t> dropped{0};
  std::atomic<int64_t> malformed{0};
  std::atomic<int64_t> handler_errors{0};
  // Sum and count of (handling end - message utime) since the last health period.
  std::atomic<int64_t> latency_sum_us{0};
  std::atomic<int64_t> latency_count{0};
};

class Bus {
 public:
  Bus(lcm::LCM& lcm, const Clock& clock, std::string owner);
  ~Bus();
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;

  // Subscribes `handler` to a channel of type Msg. queue_capacity bounds the
  // messages LCM keeps for this subscription between handle() calls (LCM
  // drops the newest beyond it); images use a small capacity so stale frames
  // are dropped rather than queued.
  template <class Msg>
  void subscribe(const std::string& channel, std::function<void(const Msg&)> handler,
                 int queue_capacity = 30);

  template <class Msg>
  void publish(const std::string& channel, const Msg& msg);
  void publishRaw(const std::string& channel, const void* data, size_t size);

  // Counts a message the stage discarded itself (stale, invalid content).
  void countDropped(int64_t n = 1) { counters_.dropped += n; }
  // Counts a message whose content failed validation, with a rate-limited log line.
  void reportMalformed(const std::string& channel, const std::string& why);

  const BusCounters& counters() const { return counters_; }
  // Mean (end of handling - arrival), both on the wall clock, in ms since the
  // last call; 0 if none.
  double takeMeanLatencyMs();
  // Messages received per channel since start.
  std::map<std::string, int64_t> receivedPerChannel() const;
  const Clock& clock() const { return clock_; }
  lcm::LCM& lcm() { return lcm_; }
  const std::string& owner() const { return owner_; }

  // Testing over an unreliable bus: the messages of the injector's channels
  // reach this bus's handlers dropped, duplicated or reordered, each
  // subscription with its own random stream. Set before messages flow.
  void setLossInjector(std::shared_ptr<LossInjector> injector) { loss_ = std::move(injector); }
  // Delivers the messages the injector holds back for this bus's handlers.
  void releaseHeld();

 private:
  struct Subscription {
    virtual ~Subscription() = default;
    void onRaw(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
    void handle(const lcm::ReceiveBuffer* rbuf);
    LossStream* lossStream(const std::string& on_channel);
    virtual bool decodeAndHandle(const lcm::ReceiveBuffer* rbuf) = 0;
    Bus* bus = nullptr;
    std::string channel;
    std::string type_name;
    std::atomic<int64_t> received{0};
    lcm::Subscription* lcm_subscription = nullptr;
    std::map<std::string, LossStream*> loss_streams;  // by channel; nullptr: not lossy
  };
  template <class Msg>
  struct TypedSubscription final : Subscription {
    std::function<void(const Msg&)> handler;
    Msg msg;  // reused: keeps buffers (images) allocated between messages
    bool decodeAndHandle(const lcm::ReceiveBuffer* rbuf) override;
  };
  void add(std::unique_ptr<Subscription> sub, int queue_capacity);

  lcm::LCM& lcm_;
  const Clock& clock_;
  std::string owner_;
  BusCounters counters_;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  std::mutex malformed_log_mutex_;
  Utime last_malformed_log_ = 0;
  std::shared_ptr<LossInjector> loss_;
};

template <class Msg>
bool Bus::TypedSubscription<Msg>::decodeAndHandle(const lcm::ReceiveBuffer* rbuf) {
  std::string why;
  if (!checkedDecode(msg, rbuf->data, rbuf->data_size, &why)) {
    bus->reportMalformed(channel, why);
    return false;
  }
  handler(msg);
  return true;
}

template <class Msg>
void Bus::subscribe(const std::string& channel, std::function<void(const Msg&)> handler,
                    int queue_capacity) {
  auto sub = std::make_unique<TypedSubscription<Msg>>();
  sub->channel = channel;
  sub->type_name = Msg::getTypeName();
  sub->handler = std::move(handler);
  add(std::move(sub), queue_capacity);
}

template <class Msg>
void Bus::publish(const std::string& channel, const Msg& msg) {
  // Reused per thread: an image-sized buffer is not re-faulted every frame.
  thread_local std::vector<uint8_t> buffer;
  const int size = msg.getEncodedSize();
  buffer.resize(static_cast<size_t>(size));
  msg.encode(buffer.data(), 0, size);
  publishRaw(channel, buffer.data(), static_cast<size_t>(size));
}

}  // namespace vslam::bus
