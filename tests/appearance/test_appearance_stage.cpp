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
#include <vslam/appearance_map_t.hpp>

#include "bus/lockstep_replay.hpp"
#include "eval/appearance_eval.hpp"
#include "sim/simulator.hpp"
#include "stages/builtin_stages.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;

TEST(AppearanceStage, RelocalizesOnTheSecondLapOfTheLoop) {
  const fs::path dir = vslam::test::scratchDir("appearance_stage");
  const fs::path source(VSLAM_SOURCE_DIR);
  const auto stack = config::StackConfig::loadFile(source / "config/vslam.yaml");
  sim::Scenario scenario = sim::Scenario::loadByName("loop", source / "config/scenarios");
  scenario.motion.speed_mps = 1.0;
  scenario.motion.turn_rate_rps = M_PI / 2;
  scenario.cameras.motion_blur = false;
  {
    sim::Simulator simulator(scenario, stack.robot, 1767225600LL * kMicrosPerSecond);
    sim::LogFileSink sink((dir / "sim.lcmlog").string());
    while (simulator.step(sink)) {
    }
  }
  bus::ReplayOptions options;
  options.input = dir / "sim.lcmlog";
  options.output = dir / "run.lcmlog";
  options.input_channels = "ODOMETRY|GROUND_TRUTH|CAM_.*_IMAGE";
  bus::LockstepReplay replay(options);
  replay.addStage("appearance", stages::builtinStages().create(stack, "appearance"));
  replay.run();

  const eval::AppearanceReport r = eval::evaluateAppearanceLog(dir / "run.lcmlog", {});
  // 64 actions a lap, two laps, plus the first snapshot.
  EXPECT_EQ(r.steps.size(), 129u);
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
  fs::remove_all(dir);
}
