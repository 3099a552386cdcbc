#include "bus/loss_injector.hpp"

#include <sstream>
#include <stdexcept>

namespace vslam::bus {
namespace {

void checkProbability(const char* name, double p) {
  if (!(p >= 0.0 && p <= 1.0)) {  // also catches NaN
    std::ostringstream why;
    why << "message loss: " << name << " probability " << p << " is not in [0, 1]";
    throw std::invalid_argument(why.str());
  }
}

std::regex compilePattern(const std::string& pattern) {
  try {
    return std::regex(pattern);
  } catch (const std::regex_error& e) {
    throw std::invalid_argument("message loss: channel pattern '" + pattern +
                                "' is not a regular expression: " + e.what());
  }
}

// FNV-1a: a stable hash of the stream's names (std::hash may differ between
// library versions, and the seed must give the same run everywhere).
uint64_t stableHash(const std::string& receiver, const std::string& channel) {
  uint64_t h = 0xcbf29ce484222325ULL;
  auto mix = [&h](unsigned char c) {
    h ^= c;
    h *= 0x100000001b3ULL;
  };
  for (unsigned char c : receiver) mix(c);
  mix(0);  // ("ab", "c") and ("a", "bc") are different streams
  for (unsigned char c : channel) mix(c);
  return h;
}

std::seed_seq seedSequence(uint64_t a, uint64_t b) {
  return std::seed_seq{static_cast<uint32_t>(a), static_cast<uint32_t>(a >> 32),
                       static_cast<uint32_t>(b), static_cast<uint32_t>(b >> 32)};
}

}  // namespace

void validateLossOptions(const LossOptions& options) {
  checkProbability("drop", options.drop);
  checkProbability("duplicate", options.duplicate);
  checkProbability("reorder", options.reorder);
  compilePattern(options.channels);
}

LossCounts& LossCounts::operator+=(const LossCounts& o) {
  offered += o.offered;
  dropped += o.dropped;
  duplicated += o.duplicated;
  reordered += o.reordered;
  return *this;
}

LossStream::LossStream(const LossOptions& options, uint64_t stream_seed)
    : drop_(options.drop), duplicate_(options.duplicate), reorder_(options.reorder) {
  std::seed_seq seq = seedSequence(options.seed, stream_seed);
  rng_.seed(seq);
}

double LossStream::uniform() {
  // The top 53 bits as a double: std::uniform_real_distribution's algorithm
  // is left to the library, this is not.
  return static_cast<double>(rng_() >> 11) * 0x1.0p-53;
}

LossDecision LossStream::decide() {
  // Always three draws, so one option's value does not shift the others' decisions.
  const double u_drop = uniform(), u_duplicate = uniform(), u_hold = uniform();
  return {u_drop < drop_, u_duplicate < duplicate_, u_hold < reorder_};
}

void LossStream::offer(const void* data, size_t size, const Deliver& deliver) {
  const LossDecision d = decide();
  ++counts_.offered;
  if (d.drop) {
    ++counts_.dropped;
    return;  // a message held back waits for the next delivered one
  }
  if (d.duplicate) ++counts_.duplicated;
  if (d.hold && holding_ && !held_.has_value) {
    const auto* bytes = static_cast<const uint8_t*>(data);
    held_.bytes.assign(bytes, bytes + size);
    held_.twice = d.duplicate;
    held_.has_value = true;
    ++counts_.reordered;
    return;
  }
  deliver(data, size);
  if (d.duplicate) deliver(data, size);
  release(deliver);
}

void LossStream::release(const Deliver& deliver) {
  if (!held_.has_value) return;
  // Moved out first: delivering may lead to another offer on this stream
  // (live, a handler that republishes on its own channel).
  Held held = std::move(held_);
  held_ = Held{};
  deliver(held.bytes.data(), held.bytes.size());
  if (held.twice) deliver(held.bytes.data(), held.bytes.size());
}

LossInjector::LossInjector(LossOptions options) : options_(std::move(options)) {
  validateLossOptions(options_);
  pattern_ = compilePattern(options_.channels);
}

bool LossInjector::applies(const std::string& channel) const {
  return std::regex_match(channel, pattern_);
}

LossStream* LossInjector::stream(const std::string& receiver, const std::string& channel) {
  if (!applies(channel)) return nullptr;
  std::lock_guard<std::mutex> lock(mutex_);
  auto& s = streams_[{receiver, channel}];
  if (!s) {
    s = std::make_unique<LossStream>(options_, stableHash(receiver, channel));
    if (!holding_) s->stopHolding();
  }
  return s.get();
}

void LossInjector::stopHolding() {
  std::lock_guard<std::mutex> lock(mutex_);
  holding_ = false;
  for (auto& [key, s] : streams_) s->stopHolding();
}

LossCounts LossInjector::total() const {
  LossCounts sum;
  for (const auto& [channel, c] : perChannel()) sum += c;
  return sum;
}

std::map<std::string, LossCounts> LossInjector::perChannel() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::map<std::string, LossCounts> out;
  for (const auto& [key, s] : streams_) out[key.second] += s->counts();
  return out;
}

std::string describeLoss(const LossCounts& c) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(1);
  s << "dropped " << c.dropped << " of " << c.offered << " ("
    << (c.offered > 0 ? 100.0 * static_cast<double>(c.dropped) / static_cast<double>(c.offered)
                      : 0.0)
    << "%), duplicated " << c.duplicated << ", reordered " << c.reordered;
  return s.str();
}

}  // namespace vslam::bus
