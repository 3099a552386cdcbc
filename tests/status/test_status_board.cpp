// status::StatusBoard: rows, rates, staleness, restarts, quiet inputs and key
// figures from HEALTH samples alone; bounded against a flood of names.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "status/status_board.hpp"

using namespace vslam::status;

namespace {

HealthSample sample(const std::string& instance, double t, int pid = 100) {
  HealthSample s;
  s.received_s = t;
  s.process = "vslam-backend";
  s.instance = instance;
  s.host = "robot";
  s.pid = pid;
  s.uptime_s = t;
  return s;
}

const Row* find(const std::vector<Row>& rows, const std::string& instance) {
  for (const auto& r : rows) {
    if (r.instance == instance) return &r;
  }
  return nullptr;
}

}  // namespace

TEST(StatusBoard, RatesComeFromTwoMessagesOfOneProcess) {
  StatusBoard board;
  HealthSample a = sample("backend", 10);
  a.cpu_seconds = 2.0;
  a.received = 100;
  a.published = 40;
  board.add(a);
  auto rows = board.rows(10.5);
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_LT(rows[0].cpu_percent, 0) << "one message: no rate yet";
  HealthSample b = sample("backend", 12);
  b.cpu_seconds = 3.0;  // 1 s of CPU in 2 s
  b.received = 160;     // 30 per second
  b.published = 50;
  b.rss_bytes = 64 << 20;
  board.add(b);
  rows = board.rows(12.2);
  EXPECT_NEAR(rows[0].cpu_percent, 50.0, 1e-9);
  EXPECT_NEAR(rows[0].rx_per_s, 30.0, 1e-9);
  EXPECT_NEAR(rows[0].tx_per_s, 5.0, 1e-9);
  EXPECT_FALSE(rows[0].stale);
  EXPECT_EQ(rows[0].restarts, 0);
}

TEST(StatusBoard, ASilentProcessIsStaleAndARestartIsCounted) {
  StatusBoard board(BoardOptions{3.0, 256});
  board.add(sample("frontend", 1));
  board.add(sample("backend", 1));
  board.add(sample("backend", 4));
  EXPECT_TRUE(board.anyStale(4.5));
  auto rows = board.rows(4.5);
  EXPECT_TRUE(find(rows, "frontend")->stale);
  EXPECT_NEAR(find(rows, "frontend")->silent_s, 3.5, 1e-9);
  EXPECT_FALSE(find(rows, "backend")->stale);
  EXPECT_FALSE(board.anyStale(3.9));

  HealthSample respawned = sample("frontend", 5, 200);
  respawned.uptime_s = 0.5;
  respawned.cpu_seconds = 0.1;
  board.add(respawned);
  rows = board.rows(5);
  EXPECT_EQ(find(rows, "frontend")->restarts, 1);
  EXPECT_EQ(find(rows, "frontend")->pid, 200);
  EXPECT_LT(find(rows, "frontend")->cpu_percent, 0) << "no rate across two processes";
  EXPECT_FALSE(board.anyStale(5));
  // The same instance on another host is another row.
  HealthSample elsewhere = sample("frontend", 5);
  elsewhere.host = "laptop";
  board.add(elsewhere);
  EXPECT_EQ(board.size(), 3u);
}

// A back-end without odometry stays OK by its own level: the board marks the
// steady input that stopped, and not an input that comes in bursts.
TEST(StatusBoard, ASteadyInputThatStoppedIsMarkedQuiet) {
  StatusBoard board;  // steady after 5 reports with messages, quiet after 2 without
  const auto report = [&](double t, double odometry_hz, double proposals_hz) {
    HealthSample s = sample("backend", t);
    s.metrics = {{"rx_hz_ODOMETRY", odometry_hz, "Hz"},
                 {"rx_hz_LANDMARK_PROPOSAL", proposals_hz, "Hz"},
                 {"rx_hz_VISUAL_MEASUREMENT", 0, "Hz"}};
    board.add(s);
    return board.rows(t)[0].quiet_inputs;
  };
  for (int t = 1; t <= 5; ++t) EXPECT_TRUE(report(t, 50, t % 2).empty()) << t;
  EXPECT_TRUE(report(6, 0, 0).empty()) << "one second without is not yet quiet";
  const auto quiet = report(7, 0, 0);
  ASSERT_EQ(quiet.size(), 1u) << "bursts and never-heard inputs are not quiet";
  EXPECT_EQ(quiet[0], "ODOMETRY");
  EXPECT_NE(renderBoard(board.rows(7), 120).find("input gone quiet: ODOMETRY"), std::string::npos);
  EXPECT_TRUE(report(8, 50, 0).empty()) << "back again";
}

TEST(StatusBoard, KeyFiguresArePickedPerProgram) {
  HealthSample s = sample("backend", 1);
  s.metrics = {{"effective_sample_size", 312, "count"},
               {"kidnapped", 0, ""},
               {"landmarks", 41, "count"},
               {"measurements_accepted", 90, "count"},
               {"measurements_rejected_slope", 6, "count"},
               {"measurements_rejected_proj_err", 4, "count"},
               {"updates", 12, "count"}};
  const auto figures = StatusBoard::keyFigures(s);
  ASSERT_EQ(figures.size(), 4u);
  EXPECT_EQ(figures[0].name, "ESS");
  EXPECT_EQ(figures[0].value, 312);
  EXPECT_EQ(figures[2].name, "landmarks");
  EXPECT_EQ(figures[3].name, "rejected");
  EXPECT_NEAR(figures[3].value, 10.0, 1e-9);
  s.process = "vslam-landmark-db";
  s.metrics = {{"landmarks_in_memory", 30, ""}, {"landmarks_stored", 55, ""}, {"file_mb", 1.5, ""}};
  const auto db = StatusBoard::keyFigures(s);
  ASSERT_EQ(db.size(), 3u);
  EXPECT_EQ(db[1].name, "on disk");
  s.process = "some-other-program";
  EXPECT_TRUE(StatusBoard::keyFigures(s).empty());
}

// Everything here came over the network.
TEST(StatusBoard, HostileMessagesCannotGrowItOrBreakTheTable) {
  StatusBoard board(BoardOptions{3.0, 8});
  for (int i = 0; i < 1000; ++i) board.add(sample("flood" + std::to_string(i), i));
  EXPECT_EQ(board.size(), 8u);
  const auto rows = board.rows(1000);
  EXPECT_NE(find(rows, "flood999"), nullptr) << "the newest stay, the longest silent go";

  StatusBoard odd;
  HealthSample s = sample(std::string(5000, 'x') + "\n\x1b[2J", 1);
  s.cpu_seconds = std::numeric_limits<double>::quiet_NaN();
  s.uptime_s = std::numeric_limits<double>::infinity();
  s.message = "bad\x1b]0;title\x07";
  s.dropped =
      std::numeric_limits<int64_t>::max();  // found by fuzzing (UBSan): their sum overflowed
  s.malformed = 18;
  s.level = 2;
  s.metrics = {{"effective_sample_size", std::numeric_limits<double>::quiet_NaN(), ""}};
  odd.add(s);
  odd.add(s);
  const std::string text = renderBoard(odd.rows(1), 100);
  for (char c : text) {
    EXPECT_TRUE(c == '\n' || (c >= 0x20 && c < 0x7f)) << "control byte " << int(c) << " shown";
  }
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    EXPECT_LE(end - start, 100u);
    start = end + 1;
  }
  EXPECT_NE(text.find("ERROR"), std::string::npos) << text;
}
