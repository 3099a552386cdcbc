// Alternating image acquisition (util/alternation.hpp): which capture times
// each slot takes, the slot boundaries, times before the epoch and at robot
// times, the gate's one frame per turn, bad parameters, and the `alternate:`
// block of a robot file (config/robot_config.hpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "config/robot_config.hpp"
#include "util/alternation.hpp"

namespace {

using namespace vslam;
namespace fs = std::filesystem;

const fs::path kSource(VSLAM_SOURCE_DIR);

// The message of what `f` throws as E ("" if nothing is thrown).
template <class E, class F>
std::string thrown(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

TEST(Alternation, PeriodIsSlotsOverTheRate) {
  EXPECT_EQ(alternationPeriodUs(10, 2), 200000);
  EXPECT_EQ(alternationPeriodUs(30, 3), 100000);
  EXPECT_EQ(alternationPeriodUs(7, 1), 142857);  // rounded
  EXPECT_EQ(alternationPeriodUs(3, 2), 666667);
}

TEST(Alternation, TwoSlotsSplitThePeriodAtItsMiddle) {
  const Utime period = alternationPeriodUs(10, 2);
  struct Case {
    Utime t;
    int64_t period;
    int slot;
  };
  for (const Case& c : std::vector<Case>{{0, 0, 0},
                                         {1, 0, 0},
                                         {99999, 0, 0},
                                         {100000, 0, 1},  // a boundary belongs to the later slot
                                         {199999, 0, 1},
                                         {200000, 1, 0},
                                         {300000, 1, 1},
                                         {-1, -1, 1},  // before the epoch: floor, not truncation
                                         {-100000, -1, 1},
                                         {-100001, -1, 0},
                                         {-200000, -1, 0},
                                         {-200001, -2, 1}}) {
    const AlternationTurn turn = alternationTurn(c.t, period, 2);
    EXPECT_EQ(turn.period, c.period) << "t " << c.t;
    EXPECT_EQ(turn.slot, c.slot) << "t " << c.t;
  }
}

TEST(Alternation, SlotsOfAPeriodNotDivisibleBySlots) {
  // 100 us in 3 slots: boundaries at 33.3 and 66.7 us, so [0, 33], [34, 66], [67, 99].
  std::vector<int> slot_of(100);
  for (Utime t = 0; t < 100; ++t) slot_of[t] = alternationTurn(t, 100, 3).slot;
  EXPECT_EQ(slot_of[33], 0);
  EXPECT_EQ(slot_of[34], 1);
  EXPECT_EQ(slot_of[66], 1);
  EXPECT_EQ(slot_of[67], 2);
  EXPECT_EQ(slot_of[99], 2);
  EXPECT_EQ(std::count(slot_of.begin(), slot_of.end(), 0), 34);
  EXPECT_EQ(std::count(slot_of.begin(), slot_of.end(), 1), 33);
  EXPECT_EQ(std::count(slot_of.begin(), slot_of.end(), 2), 33);
  EXPECT_EQ(alternationTurn(100, 100, 3).slot, 0);
  EXPECT_EQ(alternationTurn(100, 100, 3).period, 1);
}

TEST(Alternation, RobotTimesOnTheUnixEpochClock) {
  const Utime midnight = 1767225600LL * 1000000;  // 2026-01-01, a multiple of 0.2 s
  const Utime period = alternationPeriodUs(10, 2);
  EXPECT_EQ(alternationTurn(midnight, period, 2).slot, 0);
  EXPECT_EQ(alternationTurn(midnight, period, 2).period, midnight / 200000);
  EXPECT_EQ(alternationTurn(midnight + 150000, period, 2).slot, 1);
  EXPECT_EQ(alternationTurn(midnight + 250000, period, 2).slot, 0);
}

// The times a gate takes from `times`.
std::vector<Utime> taken(AlternationGate gate, const std::vector<Utime>& times) {
  std::vector<Utime> out;
  for (Utime t : times) {
    if (gate.take(t)) out.push_back(t);
  }
  return out;
}

std::vector<Utime> ticks(Utime from, Utime to, Utime step) {
  std::vector<Utime> out;
  for (Utime t = from; t < to; t += step) out.push_back(t);
  return out;
}

TEST(AlternationGate, TwoCamerasTakeTurnsOnceEachPerPeriod) {
  // The simulator's 50 Hz clock, two cameras sharing 10 Hz.
  const auto clock = ticks(0, 1000000, 20000);
  EXPECT_EQ(taken(AlternationGate({0, 2}, 10), clock),
            (std::vector<Utime>{0, 200000, 400000, 600000, 800000}));
  EXPECT_EQ(taken(AlternationGate({1, 2}, 10), clock),
            (std::vector<Utime>{100000, 300000, 500000, 700000, 900000}));
  // A 30 Hz device: the first frame in the slot, wherever the frames fall.
  const auto device = ticks(5000, 1000000, 33333);
  EXPECT_EQ(taken(AlternationGate({0, 2}, 10), device),
            (std::vector<Utime>{5000, 204998, 404996, 604994, 804992}));
  EXPECT_EQ(taken(AlternationGate({1, 2}, 10), device),
            (std::vector<Utime>{104999, 304997, 504995, 704993, 904991}));
  // Without alternation (one slot) a gate is a rate limit on the period grid.
  EXPECT_EQ(taken(AlternationGate({0, 1}, 10), ticks(0, 500000, 50000)),
            (std::vector<Utime>{0, 100000, 200000, 300000, 400000}));
}

TEST(AlternationGate, AStreamThatNeverHitsTheSlotGivesNothingAndTimeDoesNotGoBack) {
  // Frames exactly every 200 ms, all in slot 0: slot 1 never gets one.
  EXPECT_TRUE(taken(AlternationGate({1, 2}, 10), ticks(0, 2000000, 200000)).empty());
  AlternationGate gate({0, 2}, 10);
  EXPECT_TRUE(gate.take(400000));
  EXPECT_FALSE(gate.take(0));  // an earlier period is never taken again
  EXPECT_FALSE(gate.take(450000));
  EXPECT_TRUE(gate.take(600000));
}

TEST(Alternation, BadParametersAreNamed) {
  for (double rate : {0.0, -10.0, std::nan(""), HUGE_VAL}) {
    EXPECT_NE(thrown<std::invalid_argument>([&] { alternationPeriodUs(rate, 2); }).find("rate_hz"),
              std::string::npos)
        << rate;
  }
  EXPECT_NE(thrown<std::invalid_argument>([] { alternationPeriodUs(1e-12, 2); }).find("rate_hz"),
            std::string::npos);
  for (int slots : {0, -1, 1001}) {
    EXPECT_NE(thrown<std::invalid_argument>([&] { alternationPeriodUs(10, slots); }).find("slots"),
              std::string::npos)
        << slots;
  }
  // 10 slots of a 5 us period would be shorter than a microsecond.
  EXPECT_NE(thrown<std::invalid_argument>([] { alternationPeriodUs(2e6, 10); }).find("microsecond"),
            std::string::npos);
  EXPECT_NE(thrown<std::invalid_argument>([] { alternationTurn(0, 1, 2); }), "");
  EXPECT_NE(thrown<std::invalid_argument>([] { alternationTurn(0, 100, 0); }), "");
  for (int slot : {-1, 2, 3}) {
    const std::string what = thrown<std::invalid_argument>([&] { AlternationGate({slot, 2}, 10); });
    EXPECT_NE(what.find("slot must be in 0..1"), std::string::npos) << slot << ": " << what;
  }
  EXPECT_NE(thrown<std::invalid_argument>([] { AlternationGate({0, 2}, 0); }), "");
}

// A two-camera robot file whose cameras have the given `alternate:` lines ("" for none).
config::RobotConfig loadRobot(const std::string& forward, const std::string& backward,
                              const std::string& backward_rate = "10") {
  const std::string calibration = (kSource / "config/calib/sim_320x240.yml").string();
  std::string yaml = "name: test\ncameras:\n";
  int index = 0;
  for (const auto& [name, alternate, rate] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"FORWARD", forward, "10"}, {"BACKWARD", backward, backward_rate}}) {
    yaml +=
        "  - name: " + name + "\n    calibration: " + calibration + "\n    frame_rate_hz: " + rate +
        "\n    position_m: [0, 0, 0.3]\n    orientation_deg: {yaw: " + std::to_string(180 * index) +
        ", pitch: 0, roll: 0}\n    image_channel: IMG_" + name + "\n    calibration_channel: CAL_" +
        name + "\n";
    if (!alternate.empty()) yaml += "    alternate: " + alternate + "\n";
    ++index;
  }
  yaml += "channels:\n";
  for (const auto& f : config::ChannelNames::fields()) {
    std::string channel = f.key;
    for (char& c : channel) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    yaml += std::string("  ") + f.key + ": CH_" + channel + "\n";
  }
  return config::RobotConfig::load(config::ConfigNode::loadString(yaml, "robot.yaml"));
}

TEST(RobotFileAlternation, ReadAndChecked) {
  const config::RobotConfig plain = loadRobot("", "");
  EXPECT_FALSE(plain.cameras[0].alternate.active());
  const config::RobotConfig turns = loadRobot("{slot: 0, slots: 2}", "{slot: 1, slots: 2}");
  EXPECT_EQ(turns.cameras[0].alternate.slot, 0);
  EXPECT_EQ(turns.cameras[1].alternate.slot, 1);
  EXPECT_EQ(turns.cameras[1].alternate.slots, 2);

  const auto error = [](const std::string& f, const std::string& b, const std::string& rate) {
    return thrown<config::ConfigError>([&] { loadRobot(f, b, rate); });
  };
  EXPECT_NE(error("{slot: 2, slots: 2}", "", "10").find("alternate.slot: slot 2 of 2 slots"),
            std::string::npos)
      << error("{slot: 2, slots: 2}", "", "10");
  EXPECT_NE(error("{slot: 0, slots: 0}", "", "10").find("alternate.slots"), std::string::npos);
  EXPECT_NE(error("{slot: -1, slots: 2}", "", "10").find("alternate.slot"), std::string::npos);
  EXPECT_NE(error("{slots: 2}", "", "10").find("alternate.slot"), std::string::npos);
  EXPECT_NE(error("{slot: 0, slots: 2, phase: 1}", "", "10").find("alternate.phase"),
            std::string::npos);
  EXPECT_NE(error("{slot: 1, slots: 2}", "{slot: 1, slots: 2}", "10")
                .find("camera 'BACKWARD' alternates in slot 1, which another camera has"),
            std::string::npos);
  EXPECT_NE(error("{slot: 0, slots: 2}", "{slot: 1, slots: 3}", "10").find("different slots"),
            std::string::npos);
  EXPECT_NE(error("{slot: 0, slots: 2}", "{slot: 1, slots: 2}", "15").find("frame_rate_hz"),
            std::string::npos);
}

}  // namespace
