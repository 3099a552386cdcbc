// vslam-replay: runs the stack's stages in lock-step over a recorded LCM log
// (see common/bus/lockstep_replay.hpp). Deterministic and as fast as the CPU.
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "bus/lockstep_replay.hpp"
#include "bus/process_main.hpp"
#include "stages/builtin_stages.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

namespace {

void usage() {
  std::cout
      << "usage: vslam-replay LOG --out OUT.lcmlog [options]\n"
         "  --config FILE        stack configuration (default $VSLAM_CONFIG, else "
         "config/vslam.yaml)\n"
         "  --stages A,B,...     process instances to run (default: every instance whose role\n"
         "                       is a stage, but those whose camera the robot file lacks: "
      <<
      [] {
        std::string s;
        for (const auto& r : vslam::stages::builtinStages().roles()) s += r + " ";
        return s;
      }()
      << ")\n"
         "  --channels REGEX     feed only input channels matching REGEX (default .*)\n"
         "  --no-inputs          write only what the stages publish\n"
         "  --keep-health        also write health messages (wall-clock timing: not "
         "deterministic)\n";
}

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace vslam;
  log::setProcessName("replay");
  tuneAllocatorForSteadyState();
  bus::ReplayOptions options;
  std::string config_file, stages_arg;
  bool stages_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&](std::string* out) {
      if (i + 1 >= argc) {
        std::cerr << "vslam-replay: " << a << " needs a value\n";
        std::exit(bus::kExitUsage);
      }
      *out = argv[++i];
    };
    std::string v;
    if (a == "--help" || a == "-h") {
      usage();
      return bus::kExitOk;
    } else if (a == "--out") {
      next(&v);
      options.output = v;
    } else if (a == "--config") {
      next(&config_file);
    } else if (a == "--stages") {
      next(&stages_arg);
      stages_given = true;
    } else if (a == "--channels") {
      next(&options.input_channels);
    } else if (a == "--no-inputs") {
      options.keep_inputs = false;
    } else if (a == "--keep-health") {
      options.keep_health = true;
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "vslam-replay: unknown option '" << a << "' (see --help)\n";
      return bus::kExitUsage;
    } else if (options.input.empty()) {
      options.input = a;
    } else {
      std::cerr << "vslam-replay: more than one input log given\n";
      return bus::kExitUsage;
    }
  }
  if (options.input.empty() || options.output.empty()) {
    usage();
    return bus::kExitUsage;
  }
  if (config_file.empty()) {
    const char* env = std::getenv("VSLAM_CONFIG");
    config_file = env && *env ? env : "config/vslam.yaml";
  }
  try {
    std::regex check(options.input_channels);
  } catch (const std::regex_error& e) {
    std::cerr << "vslam-replay: --channels '" << options.input_channels
              << "' is not a regular expression: " << e.what() << "\n";
    return bus::kExitUsage;
  }

  try {
    const auto stack = config::StackConfig::loadFile(config_file);
    const auto& registry = stages::builtinStages();
    options.health_channel = stack.robot.channels.health;
    options.health_period_s = stack.health_period_s;
    bus::LockstepReplay replay(options);
    std::vector<std::string> instances;
    if (stages_given) {
      instances = split(stages_arg);
    } else {
      // Every stage instance the robot can run: one whose camera the robot
      // file lacks (a two-camera config over a one-camera robot) is left out.
      for (const auto& inst : stack.instances()) {
        if (!registry.has(stack.roleOf(inst))) continue;
        const auto absent = stack.absentCameras(inst);
        if (!absent.empty()) {
          log::info("note: ", inst, " left out: its camera '", absent.front(),
                    "' is not in the robot file ", stack.robot.file.string());
          continue;
        }
        instances.push_back(inst);
      }
    }
    if (instances.empty()) {
      log::error("no stage to run: --stages is empty and no instance in ", config_file,
                 " has a stage role");
      return bus::kExitUsage;
    }
    for (const auto& inst : instances) {
      replay.addStage(inst, registry.create(stack, inst));
      log::info("stage ", inst, " (role ", stack.roleOf(inst), ")");
    }
    const bus::ReplayStats s = replay.run();
    log::info("replayed ", s.events_fed, " of ", s.events_read, " events (", s.events_dropped,
              " dropped: stage outputs or filtered), stages published ", s.messages_published,
              "; wrote ", s.events_written, " events to ", options.output.string(), "; ",
              s.log_seconds, " s of log in ", s.wall_seconds, " s (",
              s.wall_seconds > 0 ? s.log_seconds / s.wall_seconds : 0.0, "x real time)");
    return s.input_truncated || s.events_missing > 0 ? bus::kExitFailure : bus::kExitOk;
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return bus::kExitUsage;
  } catch (const std::exception& e) {
    log::error(e.what());
    return bus::kExitFailure;
  }
}
