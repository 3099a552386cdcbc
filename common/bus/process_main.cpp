#include "bus/process_main.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>

#include "bus/runner.hpp"
#include "config/stack_config.hpp"
#include "util/command_line.hpp"
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

// Parses the command line; returns an exit code if the process should stop
// here (help printed: 0; a bad command line, said why: kExitUsage).
std::optional<int> parseArgs(int argc, char** argv, const std::string& program, ProcessArgs* args) {
  CLI::App app{program + ": one process of the vslam stack (a stage over LCM)", program};
  app.add_option("--config", args->config_file,
                 "stack configuration (default: $VSLAM_CONFIG, else config/vslam.yaml)");
  app.add_option("--instance", args->instance,
                 "block under processes: to run (default: the role name)");
  app.add_option("--lcm-url", args->lcm_url,
                 std::string("LCM provider (default: $LCM_DEFAULT_URL, else the config's lcm.url, "
                             "else ") +
                     config::kDefaultLcmUrl + ")");
  app.add_flag("--print-config", args->print_config,
               "print the validated configuration (each value with its unit, default and "
               "meaning) and exit");
  return parseCommandLine(app, program, argumentsOf(argc, argv), std::cout, std::cerr);
}

// One --print-config line: the value, and what the declaration says of it.
std::string describedLine(const config::ResolvedValue& value,
                          const std::map<std::string, config::ParamDoc>& docs) {
  std::string line = value.key + " = " + value.value;
  auto it = docs.find(value.key);
  if (it == docs.end()) return line + (value.is_default ? "  (default)" : "");
  const config::ParamDoc& d = it->second;
  if (!d.unit.empty()) line += " " + d.unit;
  if (value.is_default) {
    line += "  (default)";
  } else if (d.default_value == "required") {
    line += "  (required)";
  } else if (d.default_value != value.value) {
    line += "  (default " + d.default_value + ")";
  }
  return line + "  -- " + d.meaning;
}

}  // namespace

int runStageProcess(int argc, char** argv, const std::string& role, const StageRegistry& registry) {
  // The executable's name: roles are snake_case, programs kebab-case.
  std::string program = "vslam-" + role;
  std::replace(program.begin(), program.end(), '_', '-');
  ProcessArgs args;
  if (const auto exit_code = parseArgs(argc, argv, program, &args)) return *exit_code;
  if (args.instance.empty()) args.instance = role;
  args.config_file = config::resolveStackConfig(args.config_file);
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
    std::map<std::string, config::ParamDoc> docs;
    for (auto& d : registry.describeParams(role)) {
      docs.emplace("processes." + args.instance + "." + d.key, std::move(d));
    }
    for (const auto& p : params) std::cout << "  " << describedLine(p, docs) << "\n";
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
