// vslam-odometry-bridge's core without LCM: differential-drive integration
// against closed forms, encoder counter wrap-around, every rejection of a
// bad line (and that the bridge carries on after it), source restarts, and
// the line sources (a pseudo-terminal, UDP on localhost).
#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "odometry_bridge/line_bridge.hpp"
#include "odometry_bridge/line_source.hpp"
#include "odometry_bridge/wheel_odometry.hpp"

namespace ob = vslam::odometry_bridge;
using vslam::Pose2;
using vslam::Utime;

namespace {

constexpr Utime kHost0 = 1'700'000'000'000'000;  // host clock at the first line

ob::BridgeParams tickParams(int counter_bits = 32) {
  ob::BridgeParams p;
  p.format = ob::LineFormat::kTicks;
  p.drive.ticks_per_rev = 1000;
  p.drive.wheel_radius_m = 0.05;
  p.drive.track_width_m = 0.3;
  p.drive.counter_bits = counter_bits;
  return p;
}

double metresPerTick(const ob::BridgeParams& p) {
  return 2 * M_PI * p.drive.wheel_radius_m / p.drive.ticks_per_rev;
}

std::string line(double t, double a, double b, double c) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), "%.6f %.9f %.9f %.9f", t, a, b, c);
  return buf;
}

std::string ticks(double t, int64_t left, int64_t right) {
  return std::to_string(t) + " " + std::to_string(left) + " " + std::to_string(right);
}

// Feeds a line, expecting an output.
ob::OdometryOutput accept(ob::LineBridge& bridge, const std::string& text, Utime host = kHost0) {
  const ob::LineResult r = bridge.addLine(text, host);
  EXPECT_EQ(r.kind, ob::LineResult::Kind::kOutput)
      << "'" << text << "': " << ob::describe(r.reason) << ": " << r.detail;
  return r.output;
}

// Feeds a line, expecting a rejection for `reason`.
void expectRejected(ob::LineBridge& bridge, const std::string& text, ob::Rejection reason) {
  const ob::LineResult r = bridge.addLine(text, kHost0);
  ASSERT_EQ(r.kind, ob::LineResult::Kind::kRejected) << "'" << text << "' was not rejected";
  EXPECT_EQ(r.reason, reason) << "'" << text << "': " << ob::describe(r.reason) << ": " << r.detail;
  EXPECT_FALSE(r.detail.empty());
}

TEST(WheelOdometry, CounterDifferencesWrapAtTheCounterWidth) {
  EXPECT_EQ(ob::tickDifference(100, 250, 16), 150);
  EXPECT_EQ(ob::tickDifference(250, 100, 16), -150);
  EXPECT_EQ(ob::tickDifference(65530, 5, 16), 11);      // forward through the wrap
  EXPECT_EQ(ob::tickDifference(5, 65530, 16), -11);     // backward through it
  EXPECT_EQ(ob::tickDifference(32767, -32768, 16), 1);  // a signed 16-bit counter
  EXPECT_EQ(ob::tickDifference(4294967295LL, 0, 32), 1);
  EXPECT_EQ(ob::tickDifference(0, 4294967295LL, 32), -1);
  EXPECT_EQ(ob::tickDifference(-5, 5, 63), 10);
  EXPECT_TRUE(ob::tickInRange(65535, 16));
  EXPECT_TRUE(ob::tickInRange(-32768, 16));
  EXPECT_FALSE(ob::tickInRange(65536, 16));
  EXPECT_FALSE(ob::tickInRange(-32769, 16));
}

TEST(WheelOdometry, StraightLineAndTurnInPlaceAreExact) {
  const Pose2 straight = ob::diffDriveStep(0.2, 0.2, 0.3);
  EXPECT_DOUBLE_EQ(straight.x, 0.2);
  EXPECT_DOUBLE_EQ(straight.y, 0.0);
  EXPECT_DOUBLE_EQ(straight.theta, 0.0);
  const Pose2 turn = ob::diffDriveStep(-0.15, 0.15, 0.3);  // each wheel 0.15 m on a 0.15 m radius
  EXPECT_NEAR(turn.x, 0.0, 1e-15);
  EXPECT_NEAR(turn.y, 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(turn.theta, 1.0);
}

TEST(LineBridge, TicksIntegrateAStraightLine) {
  ob::LineBridge bridge(tickParams());
  const double m = metresPerTick(bridge.params());
  accept(bridge, ticks(0.0, 0, 0));
  ob::OdometryOutput o;
  for (int i = 1; i <= 100; ++i) o = accept(bridge, ticks(0.02 * i, 10 * i, 10 * i));
  EXPECT_NEAR(o.pose.x, 1000 * m, 1e-12);
  EXPECT_NEAR(o.pose.y, 0.0, 1e-12);
  EXPECT_NEAR(o.pose.theta, 0.0, 1e-12);
  EXPECT_NEAR(o.distance, 1000 * m, 1e-12);
  EXPECT_NEAR(o.v, 10 * m / 0.02, 1e-9);
  EXPECT_EQ(o.seq, 100);
  EXPECT_EQ(o.utime, kHost0 + 2'000'000);  // relative timestamps: t = 2 s after the first line
}

TEST(LineBridge, TicksIntegrateATurnInPlace) {
  const ob::BridgeParams p = tickParams();
  ob::LineBridge bridge(p);
  const double m = metresPerTick(p);
  // A quarter turn: each wheel travels (pi / 2) * track / 2.
  const double wheel_m = 0.5 * M_PI * p.drive.track_width_m / 2;
  const int steps = 50;
  const double per_step = wheel_m / m / steps;
  accept(bridge, ticks(0.0, 0, 0));
  ob::OdometryOutput o;
  for (int i = 1; i <= steps; ++i) {
    const auto n = static_cast<int64_t>(std::llround(per_step * i));
    o = accept(bridge, ticks(0.02 * i, -n, n));
  }
  const double expected = 2 * std::llround(per_step * steps) * m / p.drive.track_width_m;
  EXPECT_NEAR(o.pose.theta, expected, 1e-12);
  EXPECT_NEAR(o.pose.theta, M_PI / 2, 2 * m / p.drive.track_width_m);  // within a tick
  EXPECT_NEAR(o.pose.x, 0.0, 1e-12);
  EXPECT_NEAR(o.pose.y, 0.0, 1e-12);
  EXPECT_NEAR(o.rotation, expected, 1e-12);
  EXPECT_NEAR(o.distance, 0.0, 1e-12);
}

TEST(LineBridge, TicksFollowAnArcAsTheClosedFormSays) {
  // A quarter circle of radius 1 m: the wheels on radii 1 -+ track/2.
  ob::BridgeParams p = tickParams();
  p.drive.ticks_per_rev = 1e6;  // fine ticks: rounding stays far below the tolerance
  ob::LineBridge bridge(p);
  const double m = metresPerTick(p);
  const double radius = 1.0, b = p.drive.track_width_m;
  const int steps = 100;
  accept(bridge, ticks(0.0, 0, 0));
  ob::OdometryOutput o;
  for (int i = 1; i <= steps; ++i) {
    const double angle = 0.5 * M_PI * i / steps;
    const auto left = static_cast<int64_t>(std::llround(angle * (radius - b / 2) / m));
    const auto right = static_cast<int64_t>(std::llround(angle * (radius + b / 2) / m));
    o = accept(bridge, ticks(0.02 * i, left, right));
  }
  // Closed form: (R sin a, R (1 - cos a), a) at a = pi/2. Midpoint
  // integration shortens each chord by dtheta^2/12 of it (here 2e-5, 3e-5 m
  // over the arc): 1e-4 m is three times that.
  EXPECT_NEAR(o.pose.x, 1.0, 1e-4);
  EXPECT_NEAR(o.pose.y, 1.0, 1e-4);
  EXPECT_NEAR(o.pose.theta, M_PI / 2, 1e-5);
  // A single step over the whole arc is 16 cm off: the test can fail.
  ob::LineBridge coarse(p);
  accept(coarse, ticks(0.0, 0, 0));
  const auto left = static_cast<int64_t>(std::llround(0.5 * M_PI * (radius - b / 2) / m));
  const auto right = static_cast<int64_t>(std::llround(0.5 * M_PI * (radius + b / 2) / m));
  ob::BridgeParams loose = p;
  loose.max_step_m = 10;
  loose.max_step_deg = 180;
  ob::LineBridge one_step(loose);
  accept(one_step, ticks(0.0, 0, 0));
  const ob::OdometryOutput single = accept(one_step, ticks(1.0, left, right));
  EXPECT_GT(std::hypot(single.pose.x - 1.0, single.pose.y - 1.0), 0.05);
}

TEST(LineBridge, SixteenBitCountersWrapWithoutAJump) {
  ob::LineBridge bridge(tickParams(16));
  const double m = metresPerTick(bridge.params());
  int64_t count = 65000;
  accept(bridge, ticks(0.0, count, count));
  ob::OdometryOutput o;
  for (int i = 1; i <= 20; ++i) {  // 20 x 100 ticks: through 65535 -> 0
    count = (count + 100) % 65536;
    o = accept(bridge, ticks(0.02 * i, count, count));
  }
  EXPECT_LT(count, 65000);  // it did wrap
  EXPECT_NEAR(o.pose.x, 2000 * m, 1e-12);
  EXPECT_NEAR(o.pose.y, 0.0, 1e-12);
  EXPECT_EQ(bridge.counters().rejected, 0);
}

TEST(LineBridge, PoseLinesPassThroughWithTheirSpeeds) {
  ob::LineBridge bridge(ob::BridgeParams{});
  accept(bridge, line(10.0, 1.0, 2.0, 0.5));
  const ob::OdometryOutput o =
      accept(bridge, line(10.1, 1.0 + 0.1 * std::cos(0.5), 2.0 + 0.1 * std::sin(0.5), 0.55));
  EXPECT_NEAR(o.pose.x, 1.0 + 0.1 * std::cos(0.5), 1e-9);  // 9 decimals in the line
  EXPECT_DOUBLE_EQ(o.pose.theta, 0.55);
  EXPECT_NEAR(o.v, 1.0, 1e-6);
  EXPECT_NEAR(o.omega, 0.5, 1e-6);
  EXPECT_NEAR(o.distance, 0.1, 1e-9);
  EXPECT_NEAR(o.rotation, 0.05, 1e-9);
  EXPECT_EQ(o.utime, kHost0 + 100'000);
}

TEST(LineBridge, EveryBadLineIsRejectedByReasonAndTheBridgeCarriesOn) {
  ob::BridgeParams p;
  ob::LineBridge bridge(p);
  accept(bridge, line(1.0, 0, 0, 0));
  using R = ob::Rejection;
  expectRejected(bridge, "1.1 0 0", R::kFieldCount);
  expectRejected(bridge, "1.1 0 0 0 0", R::kFieldCount);
  expectRejected(bridge, "1.1 0 zero 0", R::kNotANumber);
  expectRejected(bridge, "1.1 0 0.5x 0", R::kNotANumber);
  expectRejected(bridge, "1.1 nan 0 0", R::kNonFinite);
  expectRejected(bridge, "1.1 0 0 inf", R::kNonFinite);
  expectRejected(bridge, "inf 0 0 0", R::kNonFinite);
  expectRejected(bridge, "1.1 1e999 0 0", R::kNonFinite);
  expectRejected(bridge, line(0.9, 0, 0, 0), R::kTimeNotIncreasing);
  expectRejected(bridge, line(1.0, 0, 0, 0), R::kTimeNotIncreasing);  // equal: a duplicate
  expectRejected(bridge, line(1.1, 5.0, 0, 0), R::kJump);             // 5 m in 0.1 s
  expectRejected(bridge, line(1.1, 0, 0, 1.5), R::kJump);             // 86 degrees
  expectRejected(bridge, std::string(300, '1'), R::kTooLong);
  // Skipped, not rejected: blank lines, comments, CR line ends are fine.
  EXPECT_EQ(bridge.addLine("", kHost0).kind, ob::LineResult::Kind::kSkipped);
  EXPECT_EQ(bridge.addLine("   # a comment", kHost0).kind, ob::LineResult::Kind::kSkipped);
  const ob::OdometryOutput o = accept(bridge, line(1.1, 0.05, 0, 0.1) + "\r");
  EXPECT_DOUBLE_EQ(o.pose.x, 0.05);
  EXPECT_EQ(o.seq, 1);  // rejected lines take no sequence number

  const ob::BridgeCounters& c = bridge.counters();
  EXPECT_EQ(c.lines, 17);
  EXPECT_EQ(c.accepted, 2);
  EXPECT_EQ(c.rejected, 13);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kFieldCount)], 2);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kNotANumber)], 2);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kNonFinite)], 4);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kTimeNotIncreasing)], 2);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kJump)], 2);
  EXPECT_EQ(c.rejected_by_reason[static_cast<size_t>(R::kTooLong)], 1);
  EXPECT_EQ(c.resyncs, 0);
}

TEST(LineBridge, BadTickLinesAreRejected) {
  ob::LineBridge bridge(tickParams(16));
  accept(bridge, ticks(0.0, 0, 0));
  using R = ob::Rejection;
  expectRejected(bridge, "0.1 1.5 2", R::kNotANumber);                   // counts are integers
  expectRejected(bridge, "0.1 70000 0", R::kTickRange);                  // does not fit 16 bits
  expectRejected(bridge, "0.1 99999999999999999999 0", R::kNotANumber);  // overflows int64
  expectRejected(bridge, "0.1 20000 20000", R::kJump);                   // 6.3 m in one reading
  expectRejected(bridge, "0.1 3 4 5", R::kFieldCount);
  accept(bridge, ticks(0.1, 10, 10));
}

TEST(LineBridge, AbsoluteTimestampsMustBeUnixTime) {
  ob::BridgeParams p;
  p.timestamps = ob::TimestampMode::kAbsolute;
  ob::LineBridge bridge(p);
  expectRejected(bridge, line(12.5, 0, 0, 0), ob::Rejection::kTimeOutOfRange);  // since boot
  const ob::OdometryOutput o = accept(bridge, line(1700000000.25, 0, 0, 0));
  EXPECT_EQ(o.utime, 1'700'000'000'250'000);
}

TEST(LineBridge, HostTimestampsNeverGoBackwards) {
  ob::BridgeParams p;
  p.timestamps = ob::TimestampMode::kHost;
  ob::LineBridge bridge(p);
  EXPECT_EQ(accept(bridge, line(1, 0, 0, 0), kHost0).utime, kHost0);
  EXPECT_EQ(accept(bridge, line(2, 0, 0, 0), kHost0 + 500).utime, kHost0 + 500);
  EXPECT_EQ(accept(bridge, line(3, 0, 0, 0), kHost0 + 400).utime, kHost0 + 501);
}

TEST(LineBridge, ARestartedSourceIsFollowedFromTheLastPublishedPose) {
  ob::LineBridge bridge(ob::BridgeParams{});
  accept(bridge, line(100.0, 0, 0, 0), kHost0);
  const ob::OdometryOutput before = accept(bridge, line(100.1, 0.05, 0, 0), kHost0 + 100'000);
  // The base reboots: its clock and pose start again from zero.
  using R = ob::Rejection;
  expectRejected(bridge, line(0.0, 0.0, 0, 0), R::kTimeNotIncreasing);
  expectRejected(bridge, line(0.1, 0.01, 0, 0), R::kTimeNotIncreasing);
  const ob::LineResult r = bridge.addLine(line(0.2, 0.02, 0, 0), kHost0 + 5'000'000);
  ASSERT_EQ(r.kind, ob::LineResult::Kind::kOutput) << r.detail;
  EXPECT_TRUE(r.resynced);
  EXPECT_DOUBLE_EQ(r.output.pose.x, before.pose.x);  // no motion invented
  EXPECT_EQ(r.output.utime, kHost0 + 5'000'000);
  EXPECT_EQ(r.output.seq, before.seq + 1);
  // And it carries on from there.
  const ob::OdometryOutput after = accept(bridge, line(0.3, 0.03, 0, 0));
  EXPECT_NEAR(after.pose.x, before.pose.x + 0.01, 1e-12);
  EXPECT_EQ(after.utime, kHost0 + 5'100'000);
  EXPECT_EQ(bridge.counters().resyncs, 1);
  EXPECT_EQ(bridge.counters().rejected, 2);
}

TEST(LineBridge, AnIsolatedGlitchDoesNotResync) {
  ob::LineBridge bridge(ob::BridgeParams{});
  accept(bridge, line(1.0, 0, 0, 0));
  // Jumps that disagree with each other are glitches, each rejected.
  expectRejected(bridge, line(1.1, 9, 0, 0), ob::Rejection::kJump);
  expectRejected(bridge, line(1.2, -9, 0, 0), ob::Rejection::kJump);
  expectRejected(bridge, line(1.3, 9, 0, 0), ob::Rejection::kJump);
  accept(bridge, line(1.4, 0.1, 0, 0));
  EXPECT_EQ(bridge.counters().resyncs, 0);
}

TEST(LineBridge, InvalidParametersAreNamed) {
  ob::BridgeParams p = tickParams();
  p.drive.track_width_m = 0;
  try {
    ob::LineBridge bridge(p);
    FAIL() << "no error for a zero track width";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("track_width_m"), std::string::npos) << e.what();
  }
  p = tickParams(64);
  EXPECT_THROW(ob::LineBridge{p}, std::invalid_argument);
}

// ---- sources ---------------------------------------------------------------

TEST(LineSource, ReadsLinesFromAPseudoTerminalInRawMode) {
  const int master = posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0) << "posix_openpt: " << std::strerror(errno);
  ASSERT_EQ(grantpt(master), 0);
  ASSERT_EQ(unlockpt(master), 0);
  ob::SourceParams params;
  params.kind = ob::SourceKind::kSerial;
  params.serial_device = ptsname(master);
  params.baud = 115200;
  ob::LineSource source(params);
  // Raw mode: no echo back to the master, CR kept, no line editing (a
  // canonical tty would eat the ^? below).
  const std::string input = "1 2 3\r\n4 5\x7f 6\n" + std::string(400, 'x') + "\n7 8 9\npartial";
  ASSERT_EQ(write(master, input.data(), input.size()), static_cast<ssize_t>(input.size()));
  std::string got;
  std::vector<std::string> lines;
  for (int i = 0; i < 50 && lines.size() < 4; ++i) {
    if (source.next(&got, 100, 256) == ob::LineSource::Status::kLine) lines.push_back(got);
  }
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0], "1 2 3\r");
  EXPECT_EQ(lines[1], "4 5\x7f 6");
  EXPECT_EQ(lines[2].size(), 257u);  // cut: the caller rejects it as too long
  EXPECT_EQ(lines[3], "7 8 9");
  EXPECT_EQ(source.next(&got, 50, 256), ob::LineSource::Status::kTimeout);  // "partial" waits
  char echo[16];
  const int flags = fcntl(master, F_GETFL);
  fcntl(master, F_SETFL, flags | O_NONBLOCK);
  EXPECT_LT(read(master, echo, sizeof(echo)), 0) << "the slave echoed input back";
  close(master);  // the other end goes away: the partial line, then closed
  ob::LineSource::Status status = ob::LineSource::Status::kTimeout;
  for (int i = 0; i < 20 && status == ob::LineSource::Status::kTimeout; ++i) {
    status = source.next(&got, 100, 256);
  }
  ASSERT_EQ(status, ob::LineSource::Status::kLine);
  EXPECT_EQ(got, "partial");
  EXPECT_EQ(source.next(&got, 100, 256), ob::LineSource::Status::kClosed);
}

TEST(LineSource, ReadsDatagramsOnLocalhost) {
  ob::SourceParams params;
  params.kind = ob::SourceKind::kUdp;
  params.udp_port = 20000 + static_cast<int>(getpid() % 20000);
  std::unique_ptr<ob::LineSource> source;
  try {
    source = std::make_unique<ob::LineSource>(params);
  } catch (const std::runtime_error& e) {
    GTEST_SKIP() << "cannot bind a UDP port for the test: " << e.what();
  }
  const int sock = socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(sock, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(params.udp_port));
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  for (const std::string d : {"1 0 0 0", "2 0 0 0\n3 0 0 0\n"}) {
    ASSERT_EQ(
        sendto(sock, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to)),
        static_cast<ssize_t>(d.size()));
  }
  close(sock);
  std::vector<std::string> lines;
  std::string got;
  for (int i = 0; i < 50 && lines.size() < 3; ++i) {
    if (source->next(&got, 100, 256) == ob::LineSource::Status::kLine) lines.push_back(got);
  }
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0], "1 0 0 0");  // a datagram ends a line
  EXPECT_EQ(lines[1], "2 0 0 0");
  EXPECT_EQ(lines[2], "3 0 0 0");
}

TEST(LineSource, AMissingDeviceIsNamed) {
  ob::SourceParams params;
  params.kind = ob::SourceKind::kSerial;
  params.serial_device = "/dev/does-not-exist-ttyUSB9";
  try {
    ob::LineSource source(params);
    FAIL() << "opened a missing device";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/does-not-exist-ttyUSB9"), std::string::npos);
  }
}

}  // namespace
