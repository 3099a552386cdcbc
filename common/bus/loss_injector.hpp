#pragma once
// Message loss for testing the stack over an unreliable bus: drops,
// duplicates and reorders the messages a receiver gets, each decision drawn
// from a random stream seeded by (seed, receiver, channel), so a seed gives
// the same decisions in every run, whatever else the stack does.
//
// The injector works on the receiving side, as loss on UDP multicast does:
// each subscriber of a channel loses its own messages, and a recorder that
// does not go through the injector still sees everything that was sent.
//
// Per message of a matching channel, three draws u1, u2, u3 in [0, 1):
//   - dropped if u1 < drop (never delivered);
//   - otherwise delivered twice if u2 < duplicate;
//   - and held back if u3 < reorder and nothing is held on that stream: it is
//     then delivered right after the next delivered message of the stream
//     (a message that releases a held one is not held itself, so about
//     reorder / (1 + reorder) of the delivered messages arrive late).
// Plain C++: knows nothing of LCM (the Bus calls it with raw bytes).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <regex>
#include <string>
#include <utility>
#include <vector>

namespace vslam::bus {

struct LossOptions {
  double drop = 0;       // probability that a message is not delivered
  double duplicate = 0;  // probability that a delivered message is delivered twice
  double reorder = 0;    // probability that a delivered message is held back (see above)
  uint64_t seed = 1;
  std::string channels = ".*";  // ECMAScript regex matched against the whole channel name

  // Whether any message can be affected; an inactive injector is not installed.
  bool active() const { return drop > 0 || duplicate > 0 || reorder > 0; }
};

// Throws std::invalid_argument naming the option: a probability outside
// [0, 1] (or NaN), or a channel pattern that is not a regular expression.
void validateLossOptions(const LossOptions& options);

struct LossCounts {
  int64_t offered = 0;     // messages that reached the stream
  int64_t dropped = 0;     // never delivered
  int64_t duplicated = 0;  // delivered twice
  int64_t reordered = 0;   // held back and delivered after the next one
  LossCounts& operator+=(const LossCounts& o);
};

struct LossDecision {
  bool drop = false;
  bool duplicate = false;
  bool hold = false;
};

// The decisions for one receiver's messages on one channel, and the message
// it holds back. Not thread-safe: one stream is used by one subscription,
// whose messages arrive one at a time.
class LossStream {
 public:
  using Deliver = std::function<void(const void* data, size_t size)>;

  LossStream(const LossOptions& options, uint64_t stream_seed);

  // The next decision (three draws), before the one-held-message rule.
  LossDecision decide();
  // Delivers `data` through `deliver` as the next decision says: not at all,
  // once, twice, or later; then the message held back before, if any.
  void offer(const void* data, size_t size, const Deliver& deliver);
  // Delivers the message held back, if any (nothing will come after it).
  void release(const Deliver& deliver);
  // From now on no message is held back.
  void stopHolding() { holding_ = false; }

  const LossCounts& counts() const { return counts_; }
  bool holds() const { return held_.has_value; }

 private:
  struct Held {
    bool has_value = false;
    bool twice = false;
    std::vector<uint8_t> bytes;
  };
  double uniform();  // in [0, 1), the same on every platform

  double drop_, duplicate_, reorder_;
  std::mt19937_64 rng_;  // its output sequence is fixed by the C++ standard
  bool holding_ = true;
  Held held_;
  LossCounts counts_;
};

// The streams of one run, by (receiver, channel), and their counts.
class LossInjector {
 public:
  // Throws std::invalid_argument for bad options (validateLossOptions).
  explicit LossInjector(LossOptions options);

  const LossOptions& options() const { return options_; }
  bool applies(const std::string& channel) const;
  // The stream of `receiver`'s messages on `channel` (the same one for the
  // same names), or nullptr if the channel does not match the pattern.
  // Owned by the injector.
  LossStream* stream(const std::string& receiver, const std::string& channel);
  // No stream holds a message back from now on (the end of a replay: no
  // message comes after). Held messages stay until released.
  void stopHolding();

  LossCounts total() const;
  std::map<std::string, LossCounts> perChannel() const;  // summed over receivers

 private:
  LossOptions options_;
  std::regex pattern_;
  mutable std::mutex mutex_;  // live: subscriptions of several LCM instances
  bool holding_ = true;
  std::map<std::pair<std::string, std::string>, std::unique_ptr<LossStream>> streams_;
};

// "dropped 12 of 100 (12.0%), duplicated 3, reordered 4"
std::string describeLoss(const LossCounts& counts);

}  // namespace vslam::bus
