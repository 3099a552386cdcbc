// The real vslam-odometry-bridge binary over a pseudo-terminal: the test
// writes lines into the pty's master, the bridge reads its slave as a serial
// port and publishes ODOMETRY over LCM multicast on loopback, inside a fresh
// private network namespace (skipped where namespaces are not permitted).
// Also: a device that cannot be opened is a configuration error (exit 2)
// naming the key.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
#include <vslam/health_t.hpp>
#include <vslam/odometry_t.hpp>

#include "process_harness.hpp"

namespace tt = vslam::transport_test;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class BridgeProcess : public tt::NetnsTest {};

// A stack config whose odometry_bridge block is `block` (indented under it).
std::string writeConfig(const tt::TempDir& dir, const std::string& block) {
  const std::string file = dir.path() + "/vslam.yaml";
  std::ofstream out(file);
  out << "robot: " << VSLAM_SOURCE_DIR << "/config/robot/sim_two_camera.yaml\n"
      << "processes:\n  odometry_bridge:\n    role: odometry_bridge\n"
      << block;
  return file;
}

std::string readFile(const std::string& file) {
  std::ifstream in(file);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

double metric(const vslam::health_t& h, const std::string& name) {
  for (const auto& m : h.metrics) {
    if (m.name == name) return m.value;
  }
  return -1;
}

TEST_F(BridgeProcess, PoseLinesOverAPtyArriveAsOdometry) {
  VSLAM_IN_FRESH_NETNS();
  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0) << "posix_openpt: " << std::strerror(errno);
  ASSERT_EQ(grantpt(master), 0);
  ASSERT_EQ(unlockpt(master), 0);
  const std::string slave = ptsname(master);

  tt::TempDir dir;
  const std::string config =
      writeConfig(dir, "    source: serial\n    serial_device: " + slave +
                           "\n    baud: 115200\n    format: pose\n    timestamps: absolute\n");

  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << kUrl;
  std::vector<vslam::odometry_t> odometry;
  std::vector<vslam::health_t> health;
  bus.subscribe("ODOMETRY", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::odometry_t m;
    ASSERT_EQ(m.decode(data, 0, static_cast<int>(size)), static_cast<int>(size));
    odometry.push_back(m);
  });
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::health_t m;
    ASSERT_EQ(m.decode(data, 0, static_cast<int>(size)), static_cast<int>(size));
    health.push_back(m);
  });

  const std::string log = dir.path() + "/bridge.log";
  tt::Child bridge = tt::Child::spawn({std::string(VSLAM_BIN_DIR) + "/vslam-odometry-bridge",
                                       "--config", config, "--lcm-url", kUrl},
                                      {}, log);
  ASSERT_TRUE(bridge.valid());
  // Its first health message: the device is open and in raw mode.
  auto fromBridge = [&](auto pred) {
    for (const auto& h : health) {
      if (h.pid == bridge.pid() && pred(h)) return true;
    }
    return false;
  };
  ASSERT_TRUE(bus.spinUntil(
      [&] { return fromBridge([](const auto&) { return true; }) || !bridge.running(); }, 10.0))
      << "no HEALTH from vslam-odometry-bridge within 10 s; its output:\n"
      << readFile(log);
  ASSERT_TRUE(bridge.running()) << tt::describeStatus(*bridge.status()) << "\n" << readFile(log);

  // 50 readings of a 0.5 m drive at 50 Hz in absolute time, with three bad
  // lines among them.
  constexpr int kReadings = 50;
  constexpr double kT0 = 1700000000.0;
  std::string input = "# pose lines: t x y theta\n";
  for (int i = 0; i < kReadings; ++i) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%.3f %.4f 0 0\n", kT0 + 0.02 * i, 0.01 * i);
    input += buf;
    if (i == 10) input += "not a reading\n";
    if (i == 20) input += "1700000000.1 nan 0 0\n";
    if (i == 30) input += "1700000000.0 0 0 0\n";  // time going backwards
  }
  ASSERT_EQ(write(master, input.data(), input.size()), static_cast<ssize_t>(input.size()));

  ASSERT_TRUE(bus.spinUntil([&] { return odometry.size() >= kReadings; }, 10.0))
      << odometry.size() << " of " << kReadings << " ODOMETRY messages; bridge output:\n"
      << readFile(log);
  bus.spinFor(0.3);
  ASSERT_EQ(odometry.size(), static_cast<size_t>(kReadings)) << "bad lines were published";
  for (int i = 0; i < kReadings; ++i) {
    SCOPED_TRACE("reading " + std::to_string(i));
    EXPECT_EQ(odometry[i].seq, i);
    EXPECT_EQ(odometry[i].utime, static_cast<int64_t>(std::llround((kT0 + 0.02 * i) * 1e6)));
    EXPECT_NEAR(odometry[i].x, 0.01 * i, 1e-9);
    EXPECT_EQ(odometry[i].y, 0.0);
    EXPECT_EQ(odometry[i].theta, 0.0);
  }
  EXPECT_NEAR(odometry.back().distance, 0.49, 1e-9);
  EXPECT_NEAR(odometry.back().v, 0.5, 1e-6);

  // Health counts the lines, the rejections by reason, and warns about them.
  ASSERT_TRUE(bus.spinUntil(
      [&] { return fromBridge([](const auto& h) { return metric(h, "lines_rejected") == 3; }); },
      5.0))
      << "no HEALTH counting 3 rejected lines";
  const vslam::health_t* h = nullptr;
  for (const auto& m : health) {
    if (m.pid == bridge.pid() && metric(m, "lines_rejected") == 3) h = &m;
  }
  ASSERT_NE(h, nullptr);
  EXPECT_EQ(h->process, "vslam-odometry-bridge");
  EXPECT_EQ(metric(*h, "lines_read"), kReadings + 4);  // and the comment
  EXPECT_EQ(metric(*h, "lines_accepted"), kReadings);
  EXPECT_EQ(metric(*h, "rejected_field_count"), 1);
  EXPECT_EQ(metric(*h, "rejected_non_finite"), 1);
  EXPECT_EQ(metric(*h, "rejected_time_backwards"), 1);
  EXPECT_EQ(metric(*h, "source_open"), 1);

  bridge.sendSignal(SIGTERM);
  const auto status = bridge.waitFor(5.0);
  ASSERT_TRUE(status.has_value()) << "vslam-odometry-bridge still running 5 s after SIGTERM";
  EXPECT_TRUE(tt::exitedWith(status, 0)) << tt::describeStatus(*status);
  close(master);
  // The warnings named the lines and the reasons.
  const std::string out = readFile(log);
  EXPECT_NE(out.find("'not a reading' rejected: wrong number of fields"), std::string::npos) << out;
  EXPECT_NE(out.find("rejected: NaN or infinity"), std::string::npos) << out;
  EXPECT_NE(out.find("rejected: time not after the last accepted line"), std::string::npos) << out;
}

// The bridge with `block` as its config exits 2 and its log names `key` and
// every string of `also`.
void expectRefused(const std::string& block, const std::string& key,
                   const std::vector<std::string>& also = {}) {
  tt::TempDir dir;
  const std::string config = writeConfig(dir, block);
  const std::string log = dir.path() + "/bridge.log";
  tt::Child bridge = tt::Child::spawn({std::string(VSLAM_BIN_DIR) + "/vslam-odometry-bridge",
                                       "--config", config, "--lcm-url", "memq://"},
                                      {}, log);
  const auto status = bridge.waitFor(10.0);
  ASSERT_TRUE(status.has_value());
  const std::string out = readFile(log);
  EXPECT_TRUE(tt::exitedWith(status, 2)) << tt::describeStatus(*status) << "\n" << out;
  EXPECT_NE(out.find("processes.odometry_bridge." + key), std::string::npos) << out;
  for (const auto& s : also) EXPECT_NE(out.find(s), std::string::npos) << out;
}

TEST(BridgeConfig, ADeviceThatCannotBeOpenedExitsTwoNamingTheKey) {
  expectRefused(
      "    source: serial\n    serial_device: /dev/does-not-exist-ttyUSB9\n    format: pose\n",
      "serial_device", {"/dev/does-not-exist-ttyUSB9"});
}

TEST(BridgeConfig, TicksWithoutTheWheelGeometryExitTwoNamingTheKey) {
  expectRefused(
      "    source: stdin\n    format: ticks\n    ticks_per_rev: 1024\n    wheel_radius_m: 0.035\n",
      "track_width_m");
}

}  // namespace
