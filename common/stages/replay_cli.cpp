#include "stages/replay_cli.hpp"

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <regex>
#include <stdexcept>
#include <string>

#include "bus/lockstep_replay.hpp"
#include "bus/process_main.hpp"
#include "config/stack_config.hpp"
#include "stages/builtin_stages.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"

namespace vslam::stages {
namespace {

std::string stageRoles() {
  std::string s;
  for (const auto& r : builtinStages().roles()) s += (s.empty() ? "" : " ") + r;
  return s;
}

// The instances to run: those named, else every stage instance the robot can
// run (one whose camera the robot file lacks, a two-camera config over a
// one-camera robot, is left out with a note).
std::vector<std::string> chooseInstances(const config::StackConfig& stack,
                                         const std::vector<std::string>& named) {
  if (!named.empty()) return named;
  std::vector<std::string> instances;
  for (const auto& inst : stack.instances()) {
    if (!builtinStages().has(stack.roleOf(inst))) continue;
    const auto absent = stack.absentCameras(inst);
    if (!absent.empty()) {
      log::info("note: ", inst, " left out: its camera '", absent.front(),
                "' is not in the robot file ", stack.robot.file.string());
      continue;
    }
    instances.push_back(inst);
  }
  return instances;
}

// A replay starts from fresh maps, in memory, unless the user names a file:
// a map file named in the stack config is the live robot's, and loading it
// would make a replay depend on every run before it (and write into it).
// Named, a map file is continued if it exists, created if not, and kept; the
// back-end's `map_prior_file: landmark_db` reads the landmark map named here.
void chooseMaps(const config::StackConfig& stack, const std::string& landmark_map,
                const std::string& appearance_map) {
  const auto absolute = [](const std::string& f) {
    return f.empty() ? f : std::filesystem::absolute(f).lexically_normal().string();
  };
  for (const auto& inst : stack.instances()) {
    const config::ConfigNode block = stack.process(inst);
    const std::string role = stack.roleOf(inst);
    if (role == "landmark_db") {
      block.set("map_file", absolute(landmark_map));
      log::info("landmark map of ", inst, ": ",
                landmark_map.empty() ? "fresh, in memory (--map FILE to keep one)"
                                     : absolute(landmark_map));
    } else if (role == "appearance") {
      block.set("map_file", absolute(appearance_map));
      if (!appearance_map.empty()) {
        block.set("map_load", "true");
        block.set("map_save", "true");
      }
      log::info("appearance map of ", inst, ": ",
                appearance_map.empty() ? "fresh, in memory (--appearance-map FILE to keep one)"
                                       : absolute(appearance_map));
    }
  }
}

}  // namespace

int runReplayCli(const std::vector<std::string>& args) {
  bus::ReplayOptions options;
  std::string input, output, config_file;
  std::vector<std::string> stages;
  CLI::App app{
      "vslam-replay: runs the stack's stages in lock-step over a recorded LCM log\n"
      "(deterministic, as fast as the CPU)",
      "vslam-replay"};
  app.add_option("log", input, "the input LCM log")->required();
  app.add_option("--out", output, "the output LCM log")->required();
  app.add_option("--config", config_file,
                 "stack configuration (default $VSLAM_CONFIG, else config/vslam.yaml)");
  app.add_option("--stages", stages,
                 "process instances to run (default: every instance whose role is a stage, "
                 "but those whose camera the robot file lacks: " +
                     stageRoles() + ")")
      ->delimiter(',');
  app.add_option("--channels", options.input_channels,
                 "feed only input channels matching this regular expression")
      ->default_str(".*")
      ->check([](const std::string& re) -> std::string {
        try {
          std::regex check(re);
          return "";
        } catch (const std::regex_error& e) {
          return "not a regular expression: " + std::string(e.what());
        }
      });
  std::string landmark_map, appearance_map;
  app.add_option(
      "--map", landmark_map,
      "the landmark map file to continue (created if missing, kept); default: a fresh "
      "map in memory, whatever the config names, so that replays of a log are identical");
  app.add_option("--appearance-map", appearance_map,
                 "the appearance map file to continue (created if missing, kept); default: a fresh "
                 "map in memory");
  app.add_flag("!--no-inputs", options.keep_inputs, "write only what the stages publish");
  app.add_flag("--keep-health", options.keep_health,
               "also write health messages (wall-clock timing: not deterministic)");
  // Message loss (testing): checked by bus::validateLossOptions below, the one
  // place that knows the valid values.
  bus::LossOptions& loss = options.loss;
  app.add_option("--drop", loss.drop,
                 "drop this fraction of the messages each stage receives on the loss channels "
                 "(inputs and stage outputs alike; the output log keeps all)")
      ->capture_default_str();
  app.add_option("--duplicate", loss.duplicate,
                 "deliver this fraction of the delivered messages twice")
      ->capture_default_str();
  app.add_option("--reorder", loss.reorder,
                 "hold this fraction of the delivered messages back until the next one on their "
                 "channel")
      ->capture_default_str();
  app.add_option("--loss-seed", loss.seed, "seed of the loss decisions (same seed, same run)")
      ->capture_default_str();
  app.add_option("--loss-channels", loss.channels,
                 "regular expression: the channels that lose messages")
      ->capture_default_str();
  const auto code = parseCommandLine(app, "vslam-replay", args, std::cout, std::cerr, [&] {
    try {
      bus::validateLossOptions(options.loss);
    } catch (const std::invalid_argument& e) {
      throw CLI::ValidationError(e.what());
    }
  });
  if (code) return *code;
  options.input = input;
  options.output = output;
  options.show_progress = true;
  config_file = config::resolveStackConfig(config_file);

  try {
    const auto stack = config::StackConfig::loadFile(config_file);
    chooseMaps(stack, landmark_map, appearance_map);
    options.health_channel = stack.robot.channels.health;
    options.health_period_s = stack.health_period_s;
    bus::LockstepReplay replay(options);
    const std::vector<std::string> instances = chooseInstances(stack, stages);
    if (instances.empty()) {
      log::error("no stage to run: no instance in ", config_file, " has a stage role");
      return kExitUsage;
    }
    for (const auto& inst : instances) {
      replay.addStage(inst, builtinStages().create(stack, inst));
      log::info("stage ", inst, " (role ", stack.roleOf(inst), ")");
    }
    const bus::ReplayStats s = replay.run();
    log::info("replayed ", s.events_fed, " of ", s.events_read, " events (", s.events_dropped,
              " dropped: stage outputs or filtered), stages published ", s.messages_published,
              "; wrote ", s.events_written, " events to ", options.output.string(), "; ",
              s.log_seconds, " s of log in ", s.wall_seconds, " s (",
              s.wall_seconds > 0 ? s.log_seconds / s.wall_seconds : 0.0, "x real time)");
    if (options.loss.active()) {
      // Counted per receiving stage: a message two stages subscribe to is offered twice.
      log::info("message loss, all channels: ", bus::describeLoss(s.loss));
      for (const auto& [channel, counts] : s.loss_per_channel) {
        log::info("message loss on ", channel, ": ", bus::describeLoss(counts));
      }
    }
    return s.input_truncated || s.events_missing > 0 ? kExitFailure : kExitOk;
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return kExitUsage;
  } catch (const std::exception& e) {
    log::error(e.what());
    return kExitFailure;
  }
}

}  // namespace vslam::stages
