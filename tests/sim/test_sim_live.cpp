// vslam-sim publishing live over UDP multicast, in a private network namespace:
// every channel arrives, paced to the requested speed, --wait-for holds the
// first message until the named instances publish health, and SIGTERM ends it
// cleanly.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <csignal>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <string>
#include <vslam/health_t.hpp>

#include "process_harness.hpp"

namespace tt = vslam::transport_test;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class SimLive : public tt::NetnsTest {};

std::vector<std::string> simCommand(double duration_s, double speed) {
  return {std::string(VSLAM_BIN_DIR) + "/vslam-sim",
          "--config",
          std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml",
          "--scenario",
          "living_room",
          "--duration",
          std::to_string(duration_s),
          "--speed",
          std::to_string(speed),
          "--lcm-url",
          kUrl};
}

}  // namespace

TEST_F(SimLive, PublishesEveryChannelPacedToTheRequestedSpeed) {
  VSLAM_IN_FRESH_NETNS();
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  std::map<std::string, int> count;
  bus.subscribe(".*",
                [&](const std::string& channel, const uint8_t*, size_t) { ++count[channel]; });
  const auto start = std::chrono::steady_clock::now();
  tt::Child sim = tt::Child::spawn(simCommand(3.0, 2.0));
  ASSERT_TRUE(bus.spinUntil([&] { return !sim.running(); }, 30.0)) << "vslam-sim did not finish";
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  bus.spinFor(0.3);
  EXPECT_TRUE(tt::exitedWith(sim.status(), 0)) << tt::describeStatus(*sim.status());
  // 3 s of simulated time at 50 Hz odometry and 10 Hz cameras.
  EXPECT_EQ(count["ODOMETRY"], 151);
  EXPECT_EQ(count["GROUND_TRUTH"], 151);
  EXPECT_EQ(count["CAM_FORWARD_IMAGE"], 31);
  EXPECT_EQ(count["CAM_BACKWARD_IMAGE"], 31);
  EXPECT_EQ(count["CAM_FORWARD_CALIBRATION"], 4);
  // Paced: 3 s of simulation at 2x real time cannot be over before 1.5 s.
  EXPECT_GE(wall, 1.5);
  EXPECT_GE(count["HEALTH"], 1);
}

TEST_F(SimLive, SigtermStopsItCleanly) {
  VSLAM_IN_FRESH_NETNS();
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  int odometry = 0;
  bus.subscribe("ODOMETRY", [&](const std::string&, const uint8_t*, size_t) { ++odometry; });
  tt::Child sim = tt::Child::spawn(simCommand(600.0, 1.0));
  ASSERT_TRUE(bus.spinUntil([&] { return odometry >= 20; }, 20.0)) << "no odometry from vslam-sim";
  sim.sendSignal(SIGTERM);
  const auto status = sim.waitFor(5.0);
  ASSERT_TRUE(status.has_value()) << "vslam-sim ignored SIGTERM";
  EXPECT_TRUE(tt::exitedWith(status, 0)) << tt::describeStatus(*status);
}

TEST_F(SimLive, WaitsForHealthFromTheNamedInstancesBeforePublishing) {
  VSLAM_IN_FRESH_NETNS();
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  int odometry = 0;
  bus.subscribe("ODOMETRY", [&](const std::string&, const uint8_t*, size_t) { ++odometry; });
  std::vector<std::string> command = simCommand(1.0, 2.0);
  command.insert(command.end(), {"--wait-for", "backend,frontend_forward"});
  tt::Child sim = tt::Child::spawn(command);
  auto health = [&](const std::string& instance) {
    vslam::health_t h{};
    h.process = "test";
    h.instance = instance;
    bus.publish("HEALTH", h);
  };
  // Stages publish health periodically; so does this test, for the ones it
  // plays. Only one of the two for 1.5 s: nothing may be published.
  auto spinPublishing = [&](const std::vector<std::string>& instances, double seconds,
                            const std::function<bool()>& done) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      for (const auto& name : instances) health(name);
      bus.spinFor(0.1);
      if (done && done()) return true;
    }
    return false;
  };
  spinPublishing({"backend"}, 1.5, nullptr);
  EXPECT_EQ(odometry, 0);
  ASSERT_TRUE(sim.running());
  ASSERT_TRUE(spinPublishing({"backend", "frontend_forward"}, 30.0, [&] { return !sim.running(); }))
      << "vslam-sim did not finish";
  bus.spinFor(0.3);
  EXPECT_TRUE(tt::exitedWith(sim.status(), 0)) << tt::describeStatus(*sim.status());
  EXPECT_EQ(odometry, 51);  // the whole second at 50 Hz: none lost to the wait
}

TEST_F(SimLive, GivesUpNamingTheSilentInstances) {
  VSLAM_IN_FRESH_NETNS();
  std::vector<std::string> command = simCommand(1.0, 2.0);
  command.insert(command.end(), {"--wait-for", "backend", "--wait-timeout", "0.5"});
  tt::TempDir dir;
  const std::string output_file = dir.path() + "/sim.out";
  tt::Child sim = tt::Child::spawn(command, {}, output_file);
  const auto status = sim.waitFor(20.0);
  ASSERT_TRUE(status.has_value()) << "vslam-sim kept waiting past --wait-timeout";
  EXPECT_TRUE(tt::exitedWith(status, 1)) << tt::describeStatus(*status);
  std::ifstream in(output_file);
  const std::string output((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(output.find("no health from backend within 0.5 s"), std::string::npos) << output;
}
