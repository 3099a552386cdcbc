// Recording and replaying with LCM's own tools, in a fresh network namespace:
// lcm-logger records a short run published by another process (odometry,
// ground truth, 320x240 images at 30 Hz); the log read back with lcm::LogFile
// holds every message in order; lcm-logplayer --speed=1 then republishes the
// log and a subscriber receives every event with identical bytes.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <set>
#include <string>
#include <vector>

#include "peer_protocol.hpp"
#include "process_harness.hpp"

namespace tt = vslam::transport_test;
namespace fs = std::filesystem;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

struct LoggedEvent {
  int64_t eventnum = 0;
  int64_t timestamp = 0;
  std::string channel;
  std::vector<uint8_t> bytes;
};

std::vector<LoggedEvent> readLog(const std::string& path, bool* ok) {
  std::vector<LoggedEvent> events;
  lcm::LogFile log(path, "r");
  *ok = log.good();
  if (!*ok) return events;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    const auto* data = static_cast<const uint8_t*>(e->data);
    events.push_back(
        {e->eventnum, e->timestamp, e->channel, std::vector<uint8_t>(data, data + e->datalen)});
  }
  return events;
}

std::string fileText(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Shows the LCM tools' output when the test fails.
class RecordReplay : public tt::NetnsTest {
 protected:
  void TearDown() override {
    if (HasFailure()) {
      for (const std::string& f : tool_outputs_) {
        std::printf("---- %s ----\n%s\n", f.c_str(), fileText(f).c_str());
      }
    }
    tt::NetnsTest::TearDown();
  }
  std::vector<std::string> tool_outputs_;
};

TEST_F(RecordReplay, LcmLoggerRecordsAndLcmLogplayerReplaysEveryMessage) {
  VSLAM_IN_FRESH_NETNS();
  const std::string logger_bin = LCM_LOGGER_EXECUTABLE;
  const std::string player_bin = LCM_LOGPLAYER_EXECUTABLE;
  ASSERT_FALSE(logger_bin.empty() || player_bin.empty())
      << "lcm-logger / lcm-logplayer not found at configure time (Debian package liblcm-bin)";

  tt::TempDir dir;
  ASSERT_FALSE(dir.path().empty());
  const std::string log_path = dir.path() + "/rec.lcmlog";
  const std::vector<tt::Outgoing> run = tt::recordRunSequence();
  ASSERT_EQ(run.size(), 50u + 50u + 10u);

  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good()) << "cannot open LCM at " << kUrl;

  // ---- record ---------------------------------------------------------------
  // `-l URL` is broken in LCM 1.3.1's lcm-logger; --lcm-url=URL works.
  tool_outputs_ = {dir.path() + "/logger.out", dir.path() + "/player.out"};
  tt::Child logger = tt::Child::spawn(
      {logger_bin, "--lcm-url=" + std::string(kUrl), "--flush-interval=20", "--quiet", log_path},
      {}, dir.path() + "/logger.out");
  ASSERT_TRUE(logger.valid());
  // The logger is ready once a message we publish shows up in its file.
  std::vector<uint8_t> sync = {'s', 'y', 'n', 'c'};
  auto syncLogged = [&] {
    bool ok = false;
    if (!fs::exists(log_path)) return false;
    for (const auto& e : readLog(log_path, &ok)) {
      if (e.channel == tt::kSyncChannel) return true;
    }
    return false;
  };
  bool logger_ready = false;
  for (int i = 0; i < 100 && !logger_ready && logger.running(); ++i) {
    bus.publishRaw(tt::kSyncChannel, sync);
    bus.spinFor(0.05);
    logger_ready = syncLogged();
  }
  ASSERT_TRUE(logger_ready) << "lcm-logger wrote nothing to " << log_path << " within 5 s ("
                            << (logger.running() ? "running" : tt::describeStatus(*logger.status()))
                            << ")";

  tt::Child publisher = tt::Child::spawn({VSLAM_TRANSPORT_PEER, "run", kUrl});
  const auto pub_status = tt::spinUntilPeerDone(bus, publisher, 20.0);
  ASSERT_TRUE(tt::exitedWith(pub_status, 0))
      << "publisher " << (pub_status ? tt::describeStatus(*pub_status) : "did not finish");
  ASSERT_EQ(bus.doneCounts().size(), 1u);
  EXPECT_EQ(bus.doneCounts()[0], static_cast<int>(run.size()));
  // Let the logger write what it has (flush interval 20 ms), then stop it.
  bus.spinFor(0.3);
  logger.sendSignal(SIGINT);
  const auto logger_status = logger.waitFor(5.0);
  ASSERT_TRUE(logger_status.has_value()) << "lcm-logger still running 5 s after SIGINT";
  EXPECT_TRUE(tt::exitedWith(logger_status, 0))
      << "lcm-logger " << tt::describeStatus(*logger_status);

  // ---- the log, read back ---------------------------------------------------------
  bool ok = false;
  const std::vector<LoggedEvent> events = readLog(log_path, &ok);
  ASSERT_TRUE(ok) << "lcm::LogFile cannot open " << log_path;
  std::set<std::string> run_channels;
  for (const auto& m : run) run_channels.insert(m.channel);
  std::vector<const LoggedEvent*> run_events;
  for (size_t i = 0; i < events.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(events[i].eventnum, events[i - 1].eventnum) << "event " << i;
      EXPECT_GE(events[i].timestamp, events[i - 1].timestamp) << "event " << i;
    }
    if (run_channels.count(events[i].channel)) run_events.push_back(&events[i]);
  }
  ASSERT_EQ(run_events.size(), run.size())
      << "run messages in the log (of " << events.size() << " events in all)";
  for (size_t i = 0; i < run.size(); ++i) {
    SCOPED_TRACE("run message " + std::to_string(i));
    EXPECT_EQ(run_events[i]->channel, run[i].channel);
    EXPECT_TRUE(run_events[i]->bytes == run[i].bytes) << "logged bytes differ";
  }
  // Timestamps follow the 30 Hz publication: the run spans ~49/30 s.
  const double span_s = (run_events.back()->timestamp - run_events.front()->timestamp) * 1e-6;
  EXPECT_GT(span_s, 1.0) << "the log's receive timestamps do not reflect the 30 Hz publication";

  // ---- replay -------------------------------------------------------------------------
  // The log holds our HELLO/ACK handshake too; answering the replayed HELLO
  // would add messages that are not in the log.
  bus.setAutoAck(false);
  bus.record(".*");
  tt::Child player =
      tt::Child::spawn({player_bin, "--lcm-url=" + std::string(kUrl), "--speed=1", log_path}, {},
                       dir.path() + "/player.out");
  const double log_duration_s = (events.back().timestamp - events.front().timestamp) * 1e-6;
  bus.spinUntil([&] { return !player.running(); }, log_duration_s + 15.0);
  ASSERT_FALSE(player.running()) << "lcm-logplayer did not finish";
  EXPECT_TRUE(tt::exitedWith(player.status(), 0))
      << "lcm-logplayer " << tt::describeStatus(*player.status());
  bus.spinUntil([&] { return bus.received().size() >= events.size(); }, 2.0);
  bus.spinFor(0.2);  // nothing more may arrive

  const auto& got = bus.received();
  std::printf(
      "[ record/replay ] log: %zu events (%zu of the run, the rest handshake and sync); "
      "replay at --speed=1: %zu received\n",
      events.size(), run_events.size(), got.size());
  EXPECT_EQ(got.size(), events.size()) << "replayed messages received vs events in the log";
  for (size_t i = 0; i < std::min(got.size(), events.size()); ++i) {
    SCOPED_TRACE("replayed event " + std::to_string(i));
    EXPECT_EQ(got[i].channel, events[i].channel);
    EXPECT_TRUE(got[i].bytes == events[i].bytes) << "replayed bytes differ on " << got[i].channel;
  }
}

}  // namespace
