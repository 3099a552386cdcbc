// LCM over UDP multicast between processes, each test in its own fresh
// network namespace (loopback with a multicast route, nothing else):
//  - every vslam type published by a peer process arrives complete, in order;
//  - vslam-deadreckon, driven over multicast, integrates a straight 1 m drive,
//    reports health, and exits 0 on SIGTERM.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <map>
#include <string>
#include <vector>
#include <vslam/health_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "peer_protocol.hpp"
#include "process_harness.hpp"

namespace tt = vslam::transport_test;

namespace {

// The URL the stack uses by default (config/stack_config.hpp), spelled out
// here as the task for these tests specifies it.
constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class MulticastNetns : public tt::NetnsTest {};

// Decodes `bytes` as the type the mixed channel names; the bytes consumed, or -1.
int decodeAsChannelType(const std::string& channel, const std::vector<uint8_t>& bytes) {
  int used = -2;
  tt::forEachType(tt::AllTypes{}, [&](auto tag) {
    using T = typename decltype(tag)::type;
    if (channel == tt::mixedChannel(T::getTypeName())) {
      T msg;
      used = msg.decode(bytes.data(), 0, static_cast<int>(bytes.size()));
    }
  });
  return used;
}

TEST_F(MulticastNetns, EveryTypeArrivesFromAnotherProcess) {
  VSLAM_IN_FRESH_NETNS();
  constexpr int kRounds = 5;
  const std::vector<tt::Outgoing> expected = tt::mixedSequence(kRounds);
  ASSERT_EQ(expected.size(), 23u * kRounds);

  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << kUrl;
  bus.record("TEST_.*");
  tt::Child peer =
      tt::Child::spawn({VSLAM_TRANSPORT_PEER, "mixed", kUrl, std::to_string(kRounds), "200"});
  const auto status = tt::spinUntilPeerDone(bus, peer, 20.0);
  ASSERT_TRUE(tt::exitedWith(status, 0))
      << "peer " << (status ? tt::describeStatus(*status) : "did not finish in 20 s");
  EXPECT_GE(bus.helloCount(), 1);
  ASSERT_EQ(bus.doneCounts().size(), 1u);
  EXPECT_EQ(bus.doneCounts()[0], static_cast<int>(expected.size())) << "peer's own publish count";

  const auto& got = bus.received();
  EXPECT_EQ(got.size(), expected.size()) << "messages received vs published";
  for (size_t i = 0; i < std::min(got.size(), expected.size()); ++i) {
    SCOPED_TRACE("message " + std::to_string(i));
    EXPECT_EQ(got[i].channel, expected[i].channel);
    EXPECT_TRUE(got[i].bytes == expected[i].bytes) << "content differs on " << got[i].channel;
    EXPECT_EQ(decodeAsChannelType(got[i].channel, got[i].bytes),
              static_cast<int>(got[i].bytes.size()));
  }
  // Every type was actually seen.
  std::map<std::string, int> per_channel;
  for (const auto& m : got) ++per_channel[m.channel];
  EXPECT_EQ(per_channel.size(), 23u);
  for (const auto& [channel, n] : per_channel) EXPECT_EQ(n, kRounds) << channel;
}

TEST_F(MulticastNetns, DeadReckonIntegratesAStraightDriveAndStopsOnSigterm) {
  VSLAM_IN_FRESH_NETNS();
  constexpr int kReadings = 100;
  constexpr double kHz = 50.0;

  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << kUrl;
  std::vector<vslam::pose_estimate_t> poses;
  std::vector<vslam::health_t> health;
  int malformed = 0;
  bus.subscribe("POSE_ODOMETRY", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::pose_estimate_t m;
    if (m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) {
      poses.push_back(m);
    } else {
      ++malformed;
    }
  });
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::health_t m;
    if (m.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size)) {
      health.push_back(m);
    } else {
      ++malformed;
    }
  });

  const std::string bin = std::string(VSLAM_BIN_DIR) + "/vslam-deadreckon";
  const std::string config = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  tt::Child deadreckon = tt::Child::spawn({bin, "--config", config, "--lcm-url", kUrl});
  ASSERT_TRUE(deadreckon.valid());

  // Its first health message says it is up and subscribed (~1 s after start).
  auto healthFromIt = [&](int64_t min_received) {
    for (const auto& h : health) {
      if (h.pid == deadreckon.pid() && h.messages_received >= min_received) return true;
    }
    return false;
  };
  ASSERT_TRUE(bus.spinUntil([&] { return healthFromIt(0) || !deadreckon.running(); }, 10.0))
      << "no HEALTH from vslam-deadreckon within 10 s";
  ASSERT_TRUE(deadreckon.running())
      << "vslam-deadreckon " << tt::describeStatus(*deadreckon.status());
  const vslam::health_t& first = health.back();
  EXPECT_EQ(first.process, "vslam-deadreckon");
  EXPECT_EQ(first.instance, "deadreckon");
  EXPECT_EQ(first.messages_received, 0);

  // 100 readings of a straight 1 m drive, from another process.
  tt::Child driver = tt::Child::spawn(
      {VSLAM_TRANSPORT_PEER, "drive", kUrl, std::to_string(kReadings), std::to_string(kHz)});
  const auto driver_status = tt::spinUntilPeerDone(bus, driver, 20.0);
  ASSERT_TRUE(tt::exitedWith(driver_status, 0))
      << "driver " << (driver_status ? tt::describeStatus(*driver_status) : "did not finish");
  // One estimate per reading (the first one, which only sets the odometry
  // reference, gives the starting pose).
  bus.spinUntil([&] { return poses.size() >= kReadings; }, 3.0);
  ASSERT_EQ(poses.size(), static_cast<size_t>(kReadings));
  EXPECT_EQ(malformed, 0);
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(poses[i].seq, static_cast<int64_t>(i)) << "estimate " << i;
    const vslam::odometry_t odo = tt::straightDriveOdometry(static_cast<int>(i), kReadings, kHz);
    EXPECT_EQ(poses[i].utime, odo.utime) << "estimate " << i;
    EXPECT_NEAR(poses[i].x, odo.x, 1e-6) << "estimate " << i;
    EXPECT_EQ(poses[i].odom_x, odo.x) << "estimate " << i;
  }
  const vslam::pose_estimate_t& last = poses.back();
  EXPECT_NEAR(last.x, 1.0, 1e-6);
  EXPECT_NEAR(last.y, 0.0, 1e-6);
  EXPECT_NEAR(last.theta, 0.0, 1e-6);
  EXPECT_EQ(last.estimator, "deadreckon");
  EXPECT_EQ(last.num_particles, 0);
  EXPECT_FALSE(last.kidnapped);
  // Driving adds uncertainty along x.
  EXPECT_GT(last.covariance[0], 0.0);

  // A later health message counts the 100 readings and the 100 estimates.
  ASSERT_TRUE(bus.spinUntil([&] { return healthFromIt(kReadings); }, 3.0))
      << "no HEALTH counting " << kReadings << " received messages";
  const vslam::health_t& h = health.back();
  EXPECT_EQ(h.messages_received, kReadings);
  EXPECT_GE(h.messages_published, kReadings);  // estimates + health
  EXPECT_EQ(h.messages_malformed, 0);
  EXPECT_EQ(h.level, vslam::health_t::LEVEL_OK) << h.message;

  // SIGTERM: a clean exit, code 0, within a few seconds.
  deadreckon.sendSignal(SIGTERM);
  const auto status = deadreckon.waitFor(5.0);
  ASSERT_TRUE(status.has_value()) << "vslam-deadreckon still running 5 s after SIGTERM";
  EXPECT_TRUE(tt::exitedWith(status, 0)) << "vslam-deadreckon " << tt::describeStatus(*status);
}

}  // namespace
