// vslam-status over multicast, in a fresh network namespace: a real process
// (vslam-deadreckon) is listed with its host and pid, a process heard once
// and then silent is marked stale and fails --once, and a bus with nobody on
// it fails --once with a message saying so.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vslam/health_t.hpp>

#include "process_harness.hpp"

namespace tt = vslam::transport_test;
namespace fs = std::filesystem;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class StatusCli : public tt::NetnsTest {};

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST_F(StatusCli, ListsTheProcessesOnTheBusAndFailsOnceWhenOneIsStale) {
  VSLAM_IN_FRESH_NETNS();
  const fs::path dir = fs::temp_directory_path() / ("vslam_status_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string bin(VSLAM_BIN_DIR);
  const std::string config = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  int health_from_deadreckon = 0;
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* data, size_t size) {
    vslam::health_t h;
    if (h.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size) &&
        h.instance == "deadreckon") {
      ++health_from_deadreckon;
    }
  });
  tt::Child deadreckon =
      tt::Child::spawn({bin + "/vslam-deadreckon", "--config", config, "--lcm-url", kUrl});
  ASSERT_TRUE(bus.spinUntil([&] { return health_from_deadreckon > 0; }, 10.0))
      << "no HEALTH from vslam-deadreckon";

  // vslam-status --once listening for `wait` seconds, its output in `file`.
  const auto statusOnce = [&](const std::string& wait, const fs::path& file) {
    return tt::Child::spawn(
        {bin + "/vslam-status", "--once", "--wait", wait, "--config", config, "--lcm-url", kUrl},
        {}, file.string());
  };
  const auto exitStatus = [](tt::Child& child) {
    const auto code = child.waitFor(15.0);
    EXPECT_TRUE(code.has_value()) << "vslam-status --once did not exit";
    return code;
  };

  // A process heard once, then silent: stale after 3 s.
  const fs::path first = dir / "first.txt";
  tt::Child status = statusOnce("4.5", first);
  bus.spinFor(1.0);
  vslam::health_t ghost{};
  ghost.utime = 1;
  ghost.process = "vslam-backend";
  ghost.instance = "ghost";
  ghost.host = "elsewhere";
  ghost.pid = 4242;
  bus.publish("HEALTH", ghost);
  const auto code = exitStatus(status);
  const std::string board = readText(first);
  EXPECT_TRUE(tt::exitedWith(code, 1)) << board;
  char host[256] = {};
  gethostname(host, sizeof(host) - 1);
  EXPECT_NE(board.find("deadreckon"), std::string::npos) << board;
  EXPECT_NE(board.find(std::string(host).substr(0, 11)), std::string::npos) << board;
  EXPECT_NE(board.find(std::to_string(deadreckon.pid())), std::string::npos) << board;
  EXPECT_NE(board.find("ghost@elsewhere: STALE"), std::string::npos) << board;

  // Only live processes: exit 0.
  const fs::path second = dir / "second.txt";
  tt::Child again = statusOnce("2.5", second);
  EXPECT_TRUE(tt::exitedWith(exitStatus(again), 0)) << readText(second);
  EXPECT_EQ(readText(second).find("STALE"), std::string::npos) << readText(second);

  // Nobody on the bus.
  deadreckon.kill();
  const fs::path third = dir / "third.txt";
  tt::Child empty = statusOnce("1.5", third);
  EXPECT_TRUE(tt::exitedWith(exitStatus(empty), 1)) << readText(third);
  EXPECT_NE(readText(third).find("no process heard on HEALTH"), std::string::npos)
      << readText(third);
  fs::remove_all(dir);
}
