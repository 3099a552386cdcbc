// The appearance stage end to end on rendered pixels: the paper's experiment
// (config/scenarios/loop.yaml: a cyclic path of 1 m moves and 90 degree
// turns with 3 % action error, driven twice), run through the `appearance`
// instance of config/vslam.yaml in lock-step and judged against the
// simulator's ground truth with vslam-eval's --appearance evaluation. To
// keep the test short the robot drives at 1 m/s and turns at 90 deg/s, and
// frames are rendered without motion blur; the path and its errors are the
// scenario's.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/health_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/lockstep_replay.hpp"
#include "bus/log_writer.hpp"
#include "eval/appearance_eval.hpp"
#include "odometry/pose2.hpp"
#include "sim/simulator.hpp"
#include "stages/builtin_stages.hpp"
#include "support/test_logs.hpp"
#include "util/log.hpp"

namespace fs = std::filesystem;
using namespace vslam;

namespace {

const fs::path kSource(VSLAM_SOURCE_DIR);

// Runs the `appearance` instance of `stack` over `input` into `output`.
void replayAppearance(const config::StackConfig& stack, const fs::path& input,
                      const fs::path& output, bool keep_health = false) {
  bus::ReplayOptions options;
  options.input = input;
  options.output = output;
  options.keep_health = keep_health;
  options.input_channels = "ODOMETRY|GROUND_TRUTH|CAM_.*_IMAGE|CAM_.*_CALIBRATION";
  bus::LockstepReplay replay(options);
  replay.addStage("appearance", stages::builtinStages().create(stack, "appearance"));
  replay.run();
}

// config/vslam.yaml with the appearance map in memory, as vslam-replay runs
// it: the shipped map file is the user's (in $XDG_DATA_HOME), not a test's.
config::StackConfig shippedConfigInMemory() {
  const auto stack = config::StackConfig::loadFile(kSource / "config/vslam.yaml");
  stack.process("appearance").set("map_file", "");
  return stack;
}

// config/vslam.yaml with the appearance map kept in `map`.
config::StackConfig configWithMap(const fs::path& dir, const fs::path& map) {
  std::ifstream in(kSource / "config/vslam.yaml");
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = yaml.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) yaml.replace(at, from.size(), to);
  };
  replace("robot: robot/", "robot: " + (kSource / "config/robot").string() + "/");
  replace("map_file: $XDG_DATA_HOME/vslam/appearance.vslam-appearance",
          "map_file: " + map.string());
  std::ofstream(dir / "vslam.yaml") << yaml;
  return config::StackConfig::loadFile(dir / "vslam.yaml");
}

// Map persistence through the stage (run by the loop test, which has the
// rendered log): a first run saves its map at shutdown;
// a second run over the same drive loads it and is in a known map from its
// first snapshot on (global localisation among the map's states), adding
// almost no states.
void secondRunStartsInTheSavedMap(const fs::path& scratch) {
  const fs::path dir = scratch / "map";
  fs::create_directories(dir);
  const auto stack = configWithMap(dir, dir / "appearance.map");
  // The periodic saves are logged at debug level.
  const vslam::log::Level level = vslam::log::minLevel();
  vslam::log::setMinLevel(vslam::log::Level::kDebug);
  testing::internal::CaptureStderr();
  replayAppearance(stack, scratch / "sim.lcmlog", dir / "first.lcmlog");
  const std::string said = testing::internal::GetCapturedStderr();
  vslam::log::setMinLevel(level);
  ASSERT_TRUE(fs::exists(dir / "appearance.map"));
  // Saved every map_save_period_s of robot time (the shipped 10 s), not only
  // at shutdown: a process killed on the way loses at most that much.
  int saves = 0;
  for (size_t at = said.find("saved appearance map"); at != std::string::npos;
       at = said.find("saved appearance map", at + 1)) {
    ++saves;
  }
  EXPECT_GE(saves, 8) << said;
  const auto first = eval::evaluateAppearanceLog(dir / "first.lcmlog", {});

  replayAppearance(stack, scratch / "sim.lcmlog", dir / "second.lcmlog");
  const auto second = eval::evaluateAppearanceLog(dir / "second.lcmlog", {});
  ASSERT_FALSE(second.steps.empty());
  EXPECT_TRUE(second.steps.front().best_is_revisit) << "the first snapshot was not recognised";
  ASSERT_FALSE(second.relocalizations.empty());
  EXPECT_EQ(second.relocalizations.front().step, 0);
  // The first run's states have no ground truth in the second run's log
  // (their snapshots were taken in the first), so judge by the map: most
  // steps are in it, and few states are added.
  int64_t best_revisit = 0;
  for (const auto& row : second.steps) best_revisit += row.best_is_revisit;
  EXPECT_GT(best_revisit, static_cast<int64_t>(second.steps.size()) * 3 / 4);
  ASSERT_GT(first.map_states, 0);
  EXPECT_LE(second.map_states, first.map_states + 6) << "the second run re-mapped the loop";
}

// The robot of `input` carried: everything recorded from `from` to `to`
// (seconds of the log's span, as fractions) is cut out, and odometry after
// it continues from where it was at `from`, so the wheels never saw the
// move while the ground truth jumps (a carry, as vslam-eval finds it).
void writeCarriedLog(const fs::path& input, const fs::path& output, double from, double to) {
  const auto events = vslam::test::readLog(input);
  ASSERT_FALSE(events.empty());
  const int64_t span = events.back().timestamp - events.front().timestamp;
  const int64_t t1 = events.front().timestamp + static_cast<int64_t>(from * span);
  const int64_t t2 = events.front().timestamp + static_cast<int64_t>(to * span);
  const auto decode = [](const vslam::test::RecordedEvent& e) {
    vslam::odometry_t m;
    EXPECT_EQ(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
              static_cast<int>(e.data.size()));
    return m;
  };
  std::optional<vslam::odometry_t> before, after;  // the last reading before t1, the first from t2
  for (const auto& e : events) {
    if (e.channel != "ODOMETRY") continue;
    if (e.timestamp < t1) before = decode(e);
    if (e.timestamp >= t2 && !after) after = decode(e);
  }
  ASSERT_TRUE(before && after);
  const Pose2 o1{before->x, before->y, before->theta};
  const Pose2 o2{after->x, after->y, after->theta};
  vslam::bus::LogWriter log(output);
  for (const auto& e : events) {
    if (e.timestamp >= t1 && e.timestamp < t2) continue;
    std::vector<uint8_t> data = e.data;
    if (e.channel == "ODOMETRY" && e.timestamp >= t2) {
      vslam::odometry_t m = decode(e);
      const Pose2 p = o1.compose(o2.between(Pose2{m.x, m.y, m.theta}));
      m.x = p.x;
      m.y = p.y;
      m.theta = p.theta;
      m.distance -= after->distance - before->distance;
      m.rotation -= after->rotation - before->rotation;
      data.resize(static_cast<size_t>(m.getEncodedSize()));
      m.encode(data.data(), 0, static_cast<int>(data.size()));
    }
    log.write(e.timestamp, e.channel, data);
  }
}

class AppearanceStageTest : public ::testing::Test {
 protected:
  // The loop scenario, simulated once for the suite.
  static void SetUpTestSuite() {
    dir_ = new fs::path(vslam::test::scratchDir("appearance_stage"));
    const auto stack = config::StackConfig::loadFile(kSource / "config/vslam.yaml");
    sim::Scenario scenario = sim::Scenario::loadByName("loop", kSource / "config/scenarios");
    scenario.motion.speed_mps = 1.0;
    scenario.motion.turn_rate_rps = M_PI / 2;
    scenario.cameras.motion_blur = false;
    sim::Simulator simulator(scenario, stack.robot, 1767225600LL * kMicrosPerSecond);
    sim::LogFileSink sink((*dir_ / "sim.lcmlog").string());
    while (simulator.step(sink)) {
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static fs::path* dir_;
};
fs::path* AppearanceStageTest::dir_ = nullptr;

}  // namespace

TEST_F(AppearanceStageTest, RelocalizesOnTheSecondLapOfTheLoopAndReloadsItsMap) {
  const fs::path dir = *dir_;
  const auto stack = shippedConfigInMemory();
  replayAppearance(stack, dir / "sim.lcmlog", dir / "run.lcmlog");

  const eval::AppearanceReport r = eval::evaluateAppearanceLog(dir / "run.lcmlog", {});
  // 64 actions a lap, two laps, plus the first snapshot.
  EXPECT_EQ(r.steps.size(), 129u);
  // The simulated robot's forward and backward cameras (their calibration
  // messages in the log) face opposite ways: states count either way.
  EXPECT_TRUE(r.states_either_way);
  EXPECT_EQ(r.either_way_cameras, "forward/backward");
  const int64_t lap = 64;
  // Re-localised on the second lap, to the right place.
  ASSERT_FALSE(r.relocalizations.empty());
  EXPECT_GT(r.relocalizations.front().step, lap - 2) << "a false re-localisation on the first lap";
  EXPECT_LT(r.relocalizations.front().step, lap + 20) << "re-localised late";
  int correct = 0;
  for (const auto& rl : r.relocalizations) correct += rl.correct;
  EXPECT_GE(correct, (static_cast<int>(r.relocalizations.size()) + 1) / 2);
  EXPECT_TRUE(r.relocalizations.front().correct)
      << "first re-localisation " << r.relocalizations.front().position_error << " m off";
  // The done-when criterion: the surviving (revisit) hypotheses' mean position
  // error is below one action length.
  EXPECT_LT(r.mean_position_error, 1.0);
  // Most of the second lap is recognised as the first.
  EXPECT_GT(r.steps_best_revisit, lap / 2);
  EXPECT_LT(r.mean_best_position_error, 1.0);
  RecordProperty("mean_position_error_mm", static_cast<int>(1000 * r.mean_position_error));
  RecordProperty("relocalizations", static_cast<int>(r.relocalizations.size()));
  RecordProperty("steps_best_revisit", static_cast<int>(r.steps_best_revisit));

  // The last map message names the states of the best path, with links.
  vslam::appearance_map_t last_map;
  bool have_map = false;
  for (const auto& e : vslam::test::readLog(dir / "run.lcmlog")) {
    if (e.channel != "APPEARANCE_MAP") continue;
    ASSERT_EQ(last_map.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
              static_cast<int>(e.data.size()));
    have_map = true;
  }
  ASSERT_TRUE(have_map);
  EXPECT_GE(last_map.num_states, lap - 4);
  EXPECT_LE(last_map.num_states, lap + 20) << "the second lap made a second map";
  EXPECT_GE(last_map.num_links, last_map.num_states - 1);

  SCOPED_TRACE("second run in the saved map");
  secondRunStartsInTheSavedMap(dir);
}

// Global re-localization on rendered pixels: the loop with the robot
// carried, without its wheels noticing, from 70 % of the way round the
// first lap to 10 % into the second. The odometry then traces it on from
// the first lap's 70 %, where nothing matches; relocalization seeds put it
// back into the first lap's states once it drives past them, without a
// wrong re-localization. (With the paper's tree alone it never re-enters
// its map: the test fails with relocalization_candidates: 0.)
TEST_F(AppearanceStageTest, ACarriedRobotRelocalizesIntoTheFirstLap) {
  const fs::path dir = *dir_;
  writeCarriedLog(dir / "sim.lcmlog", dir / "carried.lcmlog", 0.35, 0.55);
  const auto stack = shippedConfigInMemory();
  replayAppearance(stack, dir / "carried.lcmlog", dir / "carried_run.lcmlog");
  const eval::AppearanceReport r = eval::evaluateAppearanceLog(dir / "carried_run.lcmlog", {});
  ASSERT_EQ(r.kidnaps.size(), 1u) << "the carry is one jump of the ground truth";
  const auto& carry = r.kidnaps.front();
  EXPECT_EQ(carry.kind, eval::AppearanceKidnap::Kind::kCarry);
  ASSERT_EQ(carry.status, eval::AppearanceKidnap::Status::kRelocalized)
      << "first mapped place at step " << carry.first_mapped_step;
  EXPECT_LE(carry.steps_to_relocalize, 5);
  EXPECT_EQ(r.relocalizations_wrong, 0);
  EXPECT_EQ(r.wrong_revisit_steps, 0);
  EXPECT_GT(r.revisit_steps_recognized, r.revisit_steps / 2);
  RecordProperty("steps_to_relocalize", static_cast<int>(carry.steps_to_relocalize));
}

// Bad input: images of the wrong size or encoding, truncated image data and
// non-finite odometry are counted as malformed (health) and skipped; the
// stage goes on taking snapshots.
TEST(AppearanceStage, SkipsBadInputAndKeepsRunning) {
  const fs::path dir = vslam::test::scratchDir("appearance_bad_input");
  const auto stack = shippedConfigInMemory();
  {
    vslam::bus::LogWriter log(dir / "bad.lcmlog");
    const auto write = [&](int64_t t, const std::string& channel, const auto& msg) {
      log.writeMessage(t, channel, msg);
    };
    cv::Mat texture(240, 320, CV_8UC1);
    cv::RNG rng(3);
    const int64_t t0 = 1767225600LL * kMicrosPerSecond;
    double x = 0;
    int64_t seq = 0;
    for (int i = 0; i < 50 * 20; ++i) {  // 20 s: drive 1 m in 3.3 s, stand 1.7 s
      const int64_t t = t0 + i * 20000;
      const double phase = std::fmod(0.02 * i, 5.0);
      if (phase < 10.0 / 3.0) x += 0.3 * 0.02;
      vslam::odometry_t o{};
      o.utime = t;
      o.seq = seq++;
      o.x = i == 500 ? NAN : x;  // one non-finite reading
      write(t, "ODOMETRY", o);
      if (i % 5 != 0) continue;
      for (const char* channel : {"CAM_FORWARD_IMAGE", "CAM_BACKWARD_IMAGE"}) {
        rng.fill(texture, cv::RNG::UNIFORM, 0, 255);
        vslam::image_t img{};
        img.utime = t;
        img.width = 320;
        img.height = 240;
        img.row_stride = 320;
        img.encoding = vslam::image_t::ENCODING_GRAY8;
        img.data.assign(texture.data, texture.data + texture.total());
        const int k = i / 5;
        if (k == 40) img.width = 160;       // wrong size
        if (k == 41) img.data.resize(100);  // truncated
        if (k == 42) img.encoding = 99;     // unknown encoding
        img.data_size = static_cast<int32_t>(img.data.size());
        write(t, channel, img);
      }
    }
  }
  replayAppearance(stack, dir / "bad.lcmlog", dir / "run.lcmlog", true);
  int64_t steps = 0, malformed = 0;
  for (const auto& e : vslam::test::readLog(dir / "run.lcmlog")) {
    if (e.channel == "APPEARANCE_HYPOTHESES") ++steps;
    if (e.channel == "HEALTH") {
      vslam::health_t h;
      ASSERT_GT(h.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
      if (h.instance == "appearance") malformed = std::max(malformed, h.messages_malformed);
    }
  }
  // 1 m moves every 5 s over 20 s: the first snapshot and 3 or 4 actions.
  EXPECT_GE(steps, 4);
  EXPECT_EQ(malformed, 1 + 3 * 2) << "NaN odometry, 3 bad frames of 2 cameras";
  fs::remove_all(dir);
}
