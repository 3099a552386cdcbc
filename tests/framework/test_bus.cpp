// The Bus and the runner over memq://: decode checks, error containment,
// latest-wins workers, health.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vslam/health_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/bus.hpp"
#include "bus/health_barrier.hpp"
#include "bus/latest_worker.hpp"
#include "bus/runner.hpp"

using namespace vslam;
using namespace vslam::bus;

namespace {

void pump(lcm::LCM& lcm) {
  while (lcm.handleTimeout(0) > 0) {
  }
}

vslam::odometry_t odometry(int64_t seq) {
  vslam::odometry_t m{};
  m.utime = 1000 + seq;
  m.seq = seq;
  m.x = 0.1 * static_cast<double>(seq);
  return m;
}

}  // namespace

TEST(Bus, DeliversDecodedMessagesAndCounts) {
  lcm::LCM lcm("memq://");
  ManualClock clock;
  clock.set(5000);
  Bus bus(lcm, clock, "t");
  std::vector<int64_t> seen;
  bus.subscribe<vslam::odometry_t>("ODO",
                                   [&](const vslam::odometry_t& m) { seen.push_back(m.seq); });
  for (int i = 0; i < 3; ++i) bus.publish("ODO", odometry(i));
  pump(lcm);
  EXPECT_EQ(seen, (std::vector<int64_t>{0, 1, 2}));
  EXPECT_EQ(bus.counters().received.load(), 3);
  EXPECT_EQ(bus.counters().published.load(), 3);
  EXPECT_EQ(bus.counters().malformed.load(), 0);
  // Latency is from a message's arrival to the end of its handling, on the
  // wall clock: not against the message's utime or the stage's clock (5000
  // here), which need not be the wall clock.
  const double latency_ms = bus.takeMeanLatencyMs();
  EXPECT_GE(latency_ms, 0.0);
  EXPECT_LT(latency_ms, 1000.0);
  EXPECT_EQ(bus.takeMeanLatencyMs(), 0.0);  // window restarts
  EXPECT_EQ(bus.receivedPerChannel().at("ODO"), 3);
}

TEST(Bus, MalformedMessagesAreCountedNotDelivered) {
  lcm::LCM lcm("memq://");
  WallClock clock;
  Bus bus(lcm, clock, "t");
  int delivered = 0;
  bus.subscribe<vslam::odometry_t>("ODO", [&](const vslam::odometry_t&) { ++delivered; });
  // Wrong fingerprint.
  const char garbage[] = "not an odometry message at all, just bytes";
  lcm.publish("ODO", garbage, sizeof(garbage));
  // Valid message followed by trailing bytes.
  const auto m = odometry(1);
  std::vector<uint8_t> buf(static_cast<size_t>(m.getEncodedSize()) + 4, 0);
  m.encode(buf.data(), 0, m.getEncodedSize());
  lcm.publish("ODO", buf.data(), static_cast<unsigned>(buf.size()));
  // Truncated message.
  lcm.publish("ODO", buf.data(), static_cast<unsigned>(m.getEncodedSize() - 3));
  // And a good one still gets through.
  bus.publish("ODO", odometry(2));
  pump(lcm);
  EXPECT_EQ(delivered, 1);
  EXPECT_EQ(bus.counters().malformed.load(), 3);
  EXPECT_EQ(bus.counters().received.load(), 4);
}

TEST(Bus, HandlerExceptionIsContained) {
  lcm::LCM lcm("memq://");
  WallClock clock;
  Bus bus(lcm, clock, "t");
  int handled = 0;
  bus.subscribe<vslam::odometry_t>("ODO", [&](const vslam::odometry_t& m) {
    if (m.seq == 0) throw std::runtime_error("boom");
    ++handled;
  });
  bus.publish("ODO", odometry(0));
  bus.publish("ODO", odometry(1));
  pump(lcm);
  EXPECT_EQ(handled, 1);
  EXPECT_EQ(bus.counters().handler_errors.load(), 1);
}

TEST(LatestWinsWorker, LiveModeDropsStaleItemsAndEndsOnTheNewest) {
  std::atomic<int> processed{0};
  std::atomic<int> last{-1};
  LatestWinsWorker<int> worker(ExecutionMode::kLive, [&](int& v) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    last = v;
    ++processed;
  });
  int accepted = 0;
  for (int i = 0; i < 200; ++i) accepted += worker.post(i) ? 1 : 0;
  worker.drain();
  EXPECT_EQ(last.load(), 199);                  // the newest always wins
  EXPECT_LT(processed.load(), 200);             // a slow worker skipped stale items
  EXPECT_EQ(worker.dropped(), 200 - accepted);  // every replaced item is counted
  EXPECT_EQ(processed.load() + worker.dropped(), 200);
  worker.stop();
}

TEST(LatestWinsWorker, LockstepModeRunsEveryItemInline) {
  std::vector<int> order;
  const auto caller = std::this_thread::get_id();
  bool inline_thread = true;
  LatestWinsWorker<int> worker(ExecutionMode::kLockstep, [&](int& v) {
    order.push_back(v);
    inline_thread = inline_thread && std::this_thread::get_id() == caller;
  });
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(worker.post(i));
  EXPECT_EQ(order.size(), 50u);
  EXPECT_TRUE(inline_thread);
  EXPECT_EQ(worker.dropped(), 0);
}

namespace {
class CountingStage final : public Stage {
 public:
  void start(StageContext& ctx) override {
    ctx.bus.subscribe<vslam::odometry_t>("ODO", [this](const vslam::odometry_t&) { ++count_; });
  }
  void collectHealth(HealthReport& r) override {
    r.add("odometry_messages", count_, "count");
    if (count_ == 0) r.warn("no odometry");
  }
  void stop() override { stopped_ = true; }
  std::vector<std::string> outputChannels() const override { return {}; }
  int count_ = 0;
  bool stopped_ = false;
};
}  // namespace

TEST(StageRunner, PublishesHealthPerStageOnSchedule) {
  lcm::LCM lcm("memq://");
  ManualClock clock;
  clock.set(1'000'000);
  StageRunner runner(lcm, clock, ExecutionMode::kLockstep, {"vslam-test", "HEALTH", 1.0, 0.1});
  auto stage = std::make_unique<CountingStage>();
  CountingStage* raw = stage.get();
  runner.add("counter", std::move(stage));
  std::vector<vslam::health_t> health;
  Bus listener(lcm, clock, "listener");
  listener.subscribe<vslam::health_t>("HEALTH",
                                      [&](const vslam::health_t& h) { health.push_back(h); });
  runner.startAll();

  runner.tick(1'500'000);
  pump(lcm);
  EXPECT_TRUE(health.empty());  // not due yet
  runner.tick(2'000'000);
  pump(lcm);
  ASSERT_EQ(health.size(), 1u);
  EXPECT_EQ(health[0].instance, "counter");
  EXPECT_EQ(health[0].process, "vslam-test");
  EXPECT_EQ(health[0].level, vslam::health_t::LEVEL_WARN);
  EXPECT_EQ(health[0].message, "no odometry");

  for (int i = 0; i < 4; ++i) listener.publish("ODO", odometry(i));
  pump(lcm);
  runner.tick(3'000'000);
  pump(lcm);
  ASSERT_EQ(health.size(), 2u);
  EXPECT_EQ(health[1].level, vslam::health_t::LEVEL_OK);
  EXPECT_EQ(health[1].messages_received, 4);
  bool found_rate = false;
  for (const auto& m : health[1].metrics) {
    if (m.name == "rx_hz_ODO") {
      EXPECT_NEAR(m.value, 4.0, 1e-9);  // 4 messages in a 1 s period
      found_rate = true;
    }
  }
  EXPECT_TRUE(found_rate);
  EXPECT_EQ(health[1].num_metrics, static_cast<int32_t>(health[1].metrics.size()));

  runner.stopAll();
  pump(lcm);
  EXPECT_TRUE(raw->stopped_);
  EXPECT_EQ(health.size(), 3u);  // a last health on stop
}

namespace {

void publishHealth(lcm::LCM& lcm, const std::string& instance) {
  vslam::health_t h{};
  h.process = "vslam-test";
  h.instance = instance;
  lcm.publish("HEALTH", &h);
}

}  // namespace

TEST(HealthBarrier, OpensWhenEveryInstanceHasPublishedHealth) {
  lcm::LCM lcm("memq://");
  HealthBarrier barrier(lcm, "HEALTH", {"backend", "frontend_forward"});
  publishHealth(lcm, "backend");
  publishHealth(lcm, "appearance");  // not waited for: changes nothing
  const uint8_t garbage[3] = {1, 2, 3};
  lcm.publish("HEALTH", garbage, sizeof(garbage));
  EXPECT_FALSE(barrier.wait(0.2, [] { return false; }));
  EXPECT_EQ(barrier.pending(), std::set<std::string>{"frontend_forward"});
  EXPECT_EQ(barrier.malformed(), 1);

  publishHealth(lcm, "frontend_forward");
  EXPECT_TRUE(barrier.wait(5.0, [] { return false; }));
  EXPECT_TRUE(barrier.pending().empty());
}

TEST(HealthBarrier, AStopRequestEndsTheWaitAtOnce) {
  lcm::LCM lcm("memq://");
  HealthBarrier barrier(lcm, "HEALTH", {"backend"});
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(barrier.wait(30.0, [] { return true; }));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(10));
  EXPECT_EQ(barrier.pending().size(), 1u);
}
