#include "bus/health_barrier.hpp"

#include <vslam/health_t.hpp>

#include "bus/checked_decode.hpp"

namespace vslam::bus {

HealthBarrier::HealthBarrier(lcm::LCM& lcm, const std::string& health_channel,
                             const std::vector<std::string>& instances)
    : lcm_(lcm), pending_(instances.begin(), instances.end()) {
  // subscribeFunction, as the replay does: LCM 1.3.1's member-function
  // subscribe trips UBSan's vptr check.
  subscription_ = lcm_.subscribeFunction(
      health_channel,
      +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, HealthBarrier* self) {
        self->onMessage(rbuf, channel);
      },
      this);
}

HealthBarrier::~HealthBarrier() {
  if (subscription_) lcm_.unsubscribe(subscription_);
}

void HealthBarrier::onMessage(const lcm::ReceiveBuffer* rbuf, const std::string&) {
  vslam::health_t health;
  if (!checkedDecode(health, rbuf->data, rbuf->data_size, nullptr)) {
    ++malformed_;
    return;
  }
  pending_.erase(health.instance);
}

}  // namespace vslam::bus
