// The message-loss model: rates, duplicates, reordering, seeds, channel
// selection and bad options; then the Bus delivering through it over memq://.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>
#include <vslam/odometry_t.hpp>

#include "bus/bus.hpp"
#include "bus/loss_injector.hpp"

using namespace vslam;
using namespace vslam::bus;

namespace {

LossOptions lossy(double drop, double duplicate, double reorder, uint64_t seed = 7) {
  LossOptions o;
  o.drop = drop;
  o.duplicate = duplicate;
  o.reorder = reorder;
  o.seed = seed;
  return o;
}

// Offers messages 0, 1, ..., n-1 (each a 4-byte int) and returns the ones
// delivered, in delivery order.
std::vector<int> deliverSequence(LossStream& stream, int n) {
  std::vector<int> got;
  const LossStream::Deliver deliver = [&got](const void* data, size_t size) {
    EXPECT_EQ(size, sizeof(int));
    int v;
    std::memcpy(&v, data, sizeof v);
    got.push_back(v);
  };
  for (int i = 0; i < n; ++i) stream.offer(&i, sizeof i, deliver);
  stream.release(deliver);
  return got;
}

// Binomial tolerance: 5 standard deviations of a count of n trials at p.
double tolerance(int n, double p) { return 5.0 * std::sqrt(n * p * (1 - p)) + 1; }

}  // namespace

TEST(LossStream, ObservedRatesMatchTheProbabilities) {
  constexpr int n = 20000;
  for (const double drop : {0.1, 0.3, 0.5}) {
    LossInjector injector(lossy(drop, 0.05, 0.05));
    LossStream& s = *injector.stream("backend", "ODOMETRY");
    const std::vector<int> got = deliverSequence(s, n);
    const LossCounts& c = s.counts();
    EXPECT_EQ(c.offered, n);
    EXPECT_NEAR(c.dropped, drop * n, tolerance(n, drop)) << "drop " << drop;
    const double delivered = n - c.dropped;
    // Duplicates: of the delivered messages.
    EXPECT_NEAR(c.duplicated, 0.05 * delivered, tolerance(static_cast<int>(delivered), 0.05));
    // Held back: the message after a held one is never held, so r / (1 + r).
    const double held = 0.05 / 1.05;
    EXPECT_NEAR(c.reordered, held * delivered, tolerance(static_cast<int>(delivered), held));
    // Every delivered message arrives once, or twice if duplicated; none invented.
    EXPECT_EQ(static_cast<int64_t>(got.size()), n - c.dropped + c.duplicated);
  }
}

TEST(LossStream, DuplicatesAreDeliveredTwiceInARow) {
  LossInjector injector(lossy(0, 0.3, 0));
  LossStream& s = *injector.stream("db", "LANDMARK_PROPOSAL");
  const std::vector<int> got = deliverSequence(s, 1000);
  int repeats = 0;
  for (size_t i = 1; i < got.size(); ++i) {
    ASSERT_GE(got[i], got[i - 1]) << "no reordering asked for";
    repeats += got[i] == got[i - 1];
  }
  EXPECT_EQ(repeats, s.counts().duplicated);
  EXPECT_GT(repeats, 200);
  EXPECT_EQ(static_cast<int64_t>(got.size()), 1000 + repeats);
}

TEST(LossStream, AHeldMessageComesRightAfterTheNextOne) {
  LossInjector injector(lossy(0, 0, 0.2));
  LossStream& s = *injector.stream("frontend_forward", "LANDMARK_UPDATE");
  const std::vector<int> got = deliverSequence(s, 1000);
  ASSERT_EQ(got.size(), 1000u);  // nothing lost: the last held one is released at the end
  int swapped = 0;
  for (size_t i = 0; i + 1 < got.size();) {
    if (got[i] == static_cast<int>(i)) {
      ++i;
      continue;
    }
    // Message i was held: i + 1 comes first, then i.
    ASSERT_EQ(got[i], static_cast<int>(i + 1)) << "at " << i;
    ASSERT_EQ(got[i + 1], static_cast<int>(i)) << "at " << i;
    ++swapped;
    i += 2;
  }
  // The last message may have been held and released at the end, in order.
  EXPECT_EQ(swapped + (s.counts().reordered > swapped ? 1 : 0), s.counts().reordered);
  EXPECT_GT(swapped, 100);
}

TEST(LossStream, AHeldMessageWaitsForTheNextDeliveredOneAcrossDrops) {
  // Hold everything that can be held and drop half: a held message is
  // released by the next message that is delivered, never by a dropped one.
  LossInjector injector(lossy(0.5, 0, 1.0));
  LossStream& s = *injector.stream("backend", "VISUAL_MEASUREMENT");
  const std::vector<int> got = deliverSequence(s, 2000);
  EXPECT_EQ(static_cast<int64_t>(got.size()), 2000 - s.counts().dropped);
  // With reorder 1 the delivered messages pair up: (b, a), (d, c), ... with a < b.
  for (size_t i = 0; i + 1 < got.size(); i += 2) ASSERT_GT(got[i], got[i + 1]) << "at " << i;
}

TEST(LossStream, StoppingHoldingDeliversInOrder) {
  LossInjector injector(lossy(0, 0, 1.0));
  LossStream& s = *injector.stream("a", "C");
  std::vector<int> got;
  const LossStream::Deliver deliver = [&got](const void* data, size_t) {
    got.push_back(*static_cast<const int*>(data));
  };
  int zero = 0, one = 1, two = 2;
  s.offer(&zero, sizeof zero, deliver);
  EXPECT_TRUE(s.holds());
  EXPECT_TRUE(got.empty());
  injector.stopHolding();
  s.release(deliver);
  s.offer(&one, sizeof one, deliver);
  s.offer(&two, sizeof two, deliver);
  EXPECT_EQ(got, (std::vector<int>{0, 1, 2}));
  // A stream created after the stop does not hold either.
  LossStream& later = *injector.stream("b", "C");
  later.offer(&zero, sizeof zero, deliver);
  EXPECT_FALSE(later.holds());
}

TEST(LossStream, TheSameSeedGivesTheSameDecisions) {
  LossInjector a(lossy(0.3, 0.1, 0.1, 42)), b(lossy(0.3, 0.1, 0.1, 42)),
      c(lossy(0.3, 0.1, 0.1, 43));
  const auto run = [](LossInjector& inj, const std::string& receiver) {
    return deliverSequence(*inj.stream(receiver, "ODOMETRY"), 500);
  };
  const std::vector<int> first = run(a, "backend");
  EXPECT_EQ(first, run(b, "backend"));
  EXPECT_NE(first, run(c, "backend"));     // another seed
  EXPECT_NE(first, run(a, "deadreckon"));  // another receiver: its own losses
}

TEST(LossInjector, ChannelsOutsideThePatternAreUntouched) {
  LossOptions o = lossy(1.0, 1.0, 1.0);
  o.channels = "LANDMARK_.*|ODOMETRY";
  LossInjector injector(o);
  EXPECT_NE(injector.stream("db", "LANDMARK_PROPOSAL"), nullptr);
  EXPECT_NE(injector.stream("backend", "ODOMETRY"), nullptr);
  EXPECT_EQ(injector.stream("backend", "ODOMETRY_RAW"), nullptr);  // whole name only
  EXPECT_EQ(injector.stream("backend", "POSE_ESTIMATE"), nullptr);
  EXPECT_EQ(injector.stream("frontend", "CAM_FORWARD_IMAGE"), nullptr);
  EXPECT_EQ(injector.perChannel().count("POSE_ESTIMATE"), 0u);
}

TEST(LossInjector, CountsAreSummedPerChannelOverReceivers) {
  LossInjector injector(lossy(1.0, 0, 0));
  deliverSequence(*injector.stream("frontend_forward", "LANDMARK_UPDATE"), 10);
  deliverSequence(*injector.stream("frontend_backward", "LANDMARK_UPDATE"), 10);
  deliverSequence(*injector.stream("backend", "ODOMETRY"), 5);
  const auto per = injector.perChannel();
  EXPECT_EQ(per.at("LANDMARK_UPDATE").dropped, 20);
  EXPECT_EQ(per.at("ODOMETRY").offered, 5);
  EXPECT_EQ(injector.total().dropped, 25);
  EXPECT_EQ(describeLoss(injector.total()), "dropped 25 of 25 (100.0%), duplicated 0, reordered 0");
}

TEST(LossInjector, BadOptionsAreAClearError) {
  const auto message = [](const LossOptions& o) -> std::string {
    try {
      LossInjector injector(o);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_EQ(message(lossy(1.5, 0, 0)), "message loss: drop probability 1.5 is not in [0, 1]");
  EXPECT_EQ(message(lossy(0, -0.1, 0)),
            "message loss: duplicate probability -0.1 is not in [0, 1]");
  EXPECT_NE(message(lossy(0, 0, std::numeric_limits<double>::quiet_NaN()))
                .find("reorder probability nan is not in [0, 1]"),
            std::string::npos);
  LossOptions bad_regex;
  bad_regex.channels = "LANDMARK_(";
  EXPECT_NE(message(bad_regex).find("channel pattern 'LANDMARK_(' is not a regular expression"),
            std::string::npos)
      << message(bad_regex);
  EXPECT_EQ(message(lossy(0, 1, 1)), "accepted");
  EXPECT_FALSE(LossOptions{}.active());
  EXPECT_TRUE(lossy(0, 0, 0.01).active());
}

// The Bus delivers through the injector: its handler sees the losses of its
// own stream, other channels and an un-injected subscriber see everything.
TEST(BusWithLoss, HandlersSeeDropsDuplicatesAndReorders) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  ManualClock clock;
  LossOptions o = lossy(0.3, 0.1, 0.1, 3);
  o.channels = "ODOMETRY";
  auto injector = std::make_shared<LossInjector>(o);
  Bus lossy_bus(lcm, clock, "lossy");
  lossy_bus.setLossInjector(injector);
  Bus clean_bus(lcm, clock, "clean");
  std::vector<int64_t> lossy_seq, clean_seq, other_seq;
  lossy_bus.subscribe<vslam::odometry_t>(
      "ODOMETRY", [&](const vslam::odometry_t& m) { lossy_seq.push_back(m.seq); }, 0);
  lossy_bus.subscribe<vslam::odometry_t>(
      "ODOMETRY_B", [&](const vslam::odometry_t& m) { other_seq.push_back(m.seq); }, 0);
  clean_bus.subscribe<vslam::odometry_t>(
      "ODOMETRY", [&](const vslam::odometry_t& m) { clean_seq.push_back(m.seq); }, 0);
  constexpr int n = 2000;
  for (int i = 0; i < n; ++i) {
    vslam::odometry_t m{};
    m.utime = 1000 + i;
    m.seq = i;
    clean_bus.publish("ODOMETRY", m);
    clean_bus.publish("ODOMETRY_B", m);
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  lossy_bus.releaseHeld();
  EXPECT_EQ(clean_seq.size(), static_cast<size_t>(n));
  EXPECT_EQ(other_seq.size(), static_cast<size_t>(n));
  const LossCounts c = injector->total();
  EXPECT_EQ(c.offered, n);
  EXPECT_NEAR(c.dropped, 0.3 * n, tolerance(n, 0.3));
  EXPECT_EQ(static_cast<int64_t>(lossy_seq.size()), n - c.dropped + c.duplicated);
  int out_of_order = 0, repeats = 0;
  for (size_t i = 1; i < lossy_seq.size(); ++i) {
    out_of_order += lossy_seq[i] < lossy_seq[i - 1];
    repeats += lossy_seq[i] == lossy_seq[i - 1];
  }
  EXPECT_GT(out_of_order, 0);
  EXPECT_GT(repeats, 0);
  // Counted as received: what reached the handlers (the other channel's too).
  EXPECT_EQ(lossy_bus.counters().received, static_cast<int64_t>(lossy_seq.size() + n));
}
