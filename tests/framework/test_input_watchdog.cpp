// The watchdog of a stage's input: WARN while it is quiet (and says since
// when), clear when it is back; times going back or jumping ahead counted
// and reported until a health period passes without one.
#include <gtest/gtest.h>

#include <string>
#include <vslam/health_t.hpp>

#include "bus/input_watchdog.hpp"

namespace vslam::bus {
namespace {

constexpr Utime kSecond = kMicrosPerSecond;

struct Reported {
  int level = 0;
  std::string message;
  double age_s = -1;
};

Reported reportAt(InputWatchdog& w, Utime now) {
  HealthReport r;
  w.report(now, r);
  Reported out{r.level, r.message};
  for (const auto& m : r.metrics) {
    if (m.name == "odometry_age_s") out.age_s = m.value;
  }
  return out;
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(InputWatchdog, QuietLongerThanTheTimeoutWarnsUntilTheInputIsBack) {
  InputWatchdog w("odometry on ODOMETRY", "odometry_age_s", 2.0, ": the pose does not move");
  w.begin(100 * kSecond);
  Reported r = reportAt(w, 101 * kSecond);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_OK) << "1 s after the start is within the timeout";
  EXPECT_DOUBLE_EQ(r.age_s, 1.0);
  r = reportAt(w, 103 * kSecond);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_WARN);
  EXPECT_PRED2(has, r.message, "no odometry on ODOMETRY yet, for 3.0 s: the pose does not move");

  for (Utime t = 104; t <= 110; ++t) w.arrived(t * kSecond, t * kSecond);
  r = reportAt(w, 110 * kSecond + kSecond / 2);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_OK) << r.message;
  EXPECT_DOUBLE_EQ(r.age_s, 0.5);

  r = reportAt(w, 115 * kSecond);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_WARN);
  EXPECT_PRED2(has, r.message, "no odometry on ODOMETRY for 5.0 s");
  EXPECT_FALSE(has(r.message, "yet")) << r.message;
}

TEST(InputWatchdog, TimeGoingBackIsReportedUntilAPeriodPassesWithoutAJump) {
  InputWatchdog w("odometry on ODOMETRY", "odometry_age_s", 2.0);
  w.begin(0);
  for (Utime t = 1; t <= 10; ++t) w.arrived(t * kSecond, (1000 + t) * kSecond);
  EXPECT_EQ(reportAt(w, 10 * kSecond).level, vslam::health_t::LEVEL_OK);
  EXPECT_EQ(w.timeJumps(), 0);

  // A restarted source: its times start again from its own zero.
  w.arrived(11 * kSecond, 5 * kSecond);
  w.arrived(12 * kSecond, 6 * kSecond);
  Reported r = reportAt(w, 12 * kSecond);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_WARN);
  EXPECT_PRED2(has, r.message, "time went back 1005.0 s on odometry on ODOMETRY");
  EXPECT_EQ(w.timeJumps(), 1) << "the stamps after the jump step forward normally";

  w.arrived(13 * kSecond, 7 * kSecond);
  EXPECT_EQ(reportAt(w, 13 * kSecond).level, vslam::health_t::LEVEL_OK);
}

TEST(InputWatchdog, AForwardJumpCountsOnlyBeyondTheTimeThatPassedPlusTheTimeout) {
  InputWatchdog w("images on CAM", "odometry_age_s", 2.0);
  w.begin(0);
  w.arrived(1 * kSecond, 1 * kSecond);
  // 1.5 s quiet, stamps 1.5 s apart: no jump, whatever the gap.
  w.arrived(2 * kSecond + kSecond / 2, 2 * kSecond + kSecond / 2);
  // Stamps 2.9 s apart in 1 s: within the 2 s timeout of slack.
  w.arrived(3 * kSecond + kSecond / 2, 5 * kSecond + 4 * kSecond / 10);
  EXPECT_EQ(w.timeJumps(), 0);
  // Stamps an hour ahead in 1 s: a jump.
  w.arrived(4 * kSecond + kSecond / 2, 3605 * kSecond);
  EXPECT_EQ(w.timeJumps(), 1);
  const Reported r = reportAt(w, 5 * kSecond);
  EXPECT_EQ(r.level, vslam::health_t::LEVEL_WARN);
  EXPECT_PRED2(has, r.message, "time jumped 3599.6 s ahead in 1.0 s on images on CAM");
}

}  // namespace
}  // namespace vslam::bus
