#include "bus/process_main.hpp"

#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "bus/runner.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

namespace vslam::bus {
namespace {

struct ProcessArgs {
  std::string config_file;
  std::string instance;
  std::string lcm_url;
  bool print_config = false;
};

void printUsage(const std::string& program) {
  std::cout << "usage: " << program
            << " [--config FILE] [--instance NAME] [--lcm-url URL] [--print-config]\n"
               "  --config FILE   stack configuration (default: $VSLAM_CONFIG, else "
               "config/vslam.yaml)\n"
               "  --instance NAME block under processes: to run (default: the role name)\n"
               "  --lcm-url URL   LCM provider (default: $LCM_DEFAULT_URL, else the config's "
               "lcm.url,\n"
               "                  else udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608)\n"
               "  --print-config  print the validated configuration and exit\n";
}

// Returns false (after printing why) on a bad command line.
bool parseArgs(int argc, char** argv, ProcessArgs* args, bool* help) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const std::string& name, std::string* out) {
      if (a == name) {
        if (i + 1 >= argc) {
          std::cerr << argv[0] << ": " << name << " needs a value\n";
          return false;
        }
        *out = argv[++i];
        return true;
      }
      if (a.rfind(name + "=", 0) == 0) {
        *out = a.substr(name.size() + 1);
        return true;
      }
      return false;
    };
    if (a == "--help" || a == "-h") {
      *help = true;
    } else if (a == "--print-config") {
      args->print_config = true;
    } else if (value("--config", &args->config_file) || value("--instance", &args->instance) ||
               value("--lcm-url", &args->lcm_url)) {
      continue;
    } else {
      std::cerr << argv[0] << ": unknown argument '" << a << "' (see --help)\n";
      return false;
    }
  }
  return true;
}

}  // namespace

int runStageProcess(int argc, char** argv, const std::string& role, const StageRegistry& registry) {
  const std::string program = "vslam-" + role;
  ProcessArgs args;
  bool help = false;
  if (!parseArgs(argc, argv, &args, &help)) return kExitUsage;
  if (help) {
    printUsage(program);
    return kExitOk;
  }
  if (args.instance.empty()) args.instance = role;
  if (args.config_file.empty()) {
    const char* env = std::getenv("VSLAM_CONFIG");
    args.config_file = env && *env ? env : "config/vslam.yaml";
  }
  log::setProcessName(args.instance);
  tuneAllocatorForSteadyState();

  std::unique_ptr<config::StackConfig> stack;
  std::unique_ptr<Stage> stage;
  try {
    stack = std::make_unique<config::StackConfig>(config::StackConfig::loadFile(args.config_file));
    stage = registry.create(*stack, args.instance, role);
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return kExitUsage;
  } catch (const std::exception& e) {
    log::error("cannot start: ", e.what());
    return kExitFailure;
  }
  // The parameters as the stage read them, defaults marked: its block and
  // the stack-level blocks it reads (the pre-filter).
  auto params = stack->root.resolvedValues("processes." + args.instance + ".");
  for (auto& shared : stack->root.resolvedValues("prefilter.")) params.push_back(std::move(shared));
  if (args.print_config) {
    stack->robot.print(std::cout);
    std::cout << "instance " << args.instance << " (role " << role << ") from " << args.config_file
              << ":\n";
    for (const auto& p : params) {
      std::cout << "  " << p.key << " = " << p.value << (p.is_default ? "  (default)" : "") << "\n";
    }
    return kExitOk;
  }
  for (const auto& p : params) {
    log::info("parameter ", p.key, " = ", p.value, p.is_default ? " (default)" : "");
  }

  const std::string url = config::resolveLcmUrl(args.lcm_url, stack->lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    log::error("cannot open LCM at '", url,
               "' (for udpm on a machine without a multicast route: ip route add 224.0.0.0/4 "
               "dev lo)");
    return kExitFailure;
  }
  log::info(program, " started: instance ", args.instance, ", config ", args.config_file, ", LCM ",
            url);

  installStopSignalHandlers();
  WallClock clock;
  StageRunner runner(lcm, clock, ExecutionMode::kLive,
                     RunnerOptions{program, stack->robot.channels.health, stack->health_period_s});
  runner.add(args.instance, std::move(stage));
  const int code = runner.runLive();
  log::info(program, " stopped");
  return code;
}

}  // namespace vslam::bus
