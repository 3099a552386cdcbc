#include "sim/sim_cli.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>
#include <vslam/health_t.hpp>

#include "bus/health_barrier.hpp"
#include "bus/messages.hpp"
#include "bus/process_main.hpp"
#include "config/param_table.hpp"
#include "config/stack_config.hpp"
#include "sim/simulator.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"
#include "util/process.hpp"
#include "util/progress.hpp"

namespace vslam::sim {
namespace {

// 2026-01-01T00:00:00Z: logs written with --out start here unless told
// otherwise, so the same scenario gives the same log.
constexpr Utime kDefaultLogStart = 1767225600LL * kMicrosPerSecond;

// What the command line says; 0 (-1 for the start time) is "not given".
struct SimOptions {
  std::string scenario, out, config_file, instance = "sim", lcm_url;
  double speed = 0, duration = 0, start_time = -1, wait_timeout = 60;
  std::vector<std::string> wait_for;
};

// What the run needs once set up: the stack config, the scenario, the bus
// (live only) and the simulator.
struct SimRun {
  std::unique_ptr<config::StackConfig> stack;
  Scenario scenario;
  std::unique_ptr<lcm::LCM> live_lcm;
  std::string live_url;
  std::unique_ptr<Simulator> simulator;
};

// Publishes on the bus, sleeping so that sim time runs at `speed` x real time.
class LiveSink final : public EventSink {
 public:
  LiveSink(lcm::LCM& lcm, double speed) : lcm_(lcm), speed_(speed) {}
  void write(Utime t, const std::string& channel, const void* data, size_t size) override {
    if (first_ < 0) {
      first_ = t;
      wall_start_ = monotonicUtime();
    }
    const Utime due = wall_start_ + static_cast<Utime>(static_cast<double>(t - first_) / speed_);
    const Utime now = monotonicUtime();
    if (due > now) {
      std::this_thread::sleep_for(std::chrono::microseconds(due - now));
    } else {
      lag_us_ = now - due;
    }
    lcm_.publish(channel, data, static_cast<unsigned int>(size));
    ++published_;
  }
  int64_t published() const { return published_; }
  double lagMs() const { return 1e-3 * static_cast<double>(lag_us_); }

 private:
  lcm::LCM& lcm_;
  double speed_;
  Utime first_ = -1;
  Utime wall_start_ = 0;
  Utime lag_us_ = 0;
  int64_t published_ = 0;
};

// A number >= 0 as strtod reads it (CLI11's own conversion goes through long
// double, which may round a decimal differently).
CLI::Option* addNumberOption(CLI::App& app, const std::string& name, double* value,
                             const std::string& help) {
  return app
      .add_option_function<std::string>(
          name, [value](const std::string& text) { *value = std::strtod(text.c_str(), nullptr); },
          help)
      ->check([](const std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        return !text.empty() && *end == '\0' && v >= 0
                   ? ""
                   : "expects a number >= 0, got '" + text + "'";
      })
      ->type_name("X");
}

// Parses the command line into `options`; an exit code when the program is
// done (help printed, or a usage error).
std::optional<int> parseSimCommandLine(const std::vector<std::string>& args, SimOptions* options) {
  CLI::App app{
      "vslam-sim: the simulated robot. Publishes live on the bus, paced to real time,\n"
      "or writes an LCM log as fast as it can (--out).",
      "vslam-sim"};
  app.option_defaults()->take_last();  // a repeated option: the last one counts
  app.add_option("--scenario", options->scenario,
                 "config/scenarios/NAME.yaml or a scenario file (default: the instance's "
                 "`scenario` in the stack config)")
      ->type_name("NAME|FILE");
  app.add_option("--out", options->out,
                 "write an LCM log as fast as possible instead of publishing")
      ->type_name("LOG");
  addNumberOption(app, "--speed", &options->speed,
                  "live: publish at X times real time (default: config, else 1)");
  addNumberOption(app, "--duration", &options->duration,
                  "stop after X simulated seconds (default: config, else the scenario's own "
                  "length)");
  addNumberOption(app, "--start-time", &options->start_time,
                  "time stamp of the first message, Unix seconds (default: now live, 2026-01-01 "
                  "with --out)");
  app.add_option("--config", options->config_file,
                 "stack configuration: robot cameras and channels (default $VSLAM_CONFIG, else "
                 "config/vslam.yaml)")
      ->type_name("FILE");
  app.add_option("--instance", options->instance, "block under processes:")
      ->capture_default_str()
      ->type_name("NAME");
  app.add_option("--lcm-url", options->lcm_url, "live: LCM provider")->type_name("URL");
  app.add_option("--wait-for", options->wait_for,
                 "live: publish nothing until these process instances have published health "
                 "(they are subscribed), e.g. when started together with them by scripts/launch")
      ->delimiter(',')
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
      ->type_name("A,B,...");
  addNumberOption(app, "--wait-timeout", &options->wait_timeout,
                  "live: give up waiting after X seconds (default 60; exit 1)");
  if (const auto code = vslam::parseCommandLine(app, "vslam-sim", args, std::cout, std::cerr)) {
    return code;
  }
  // "--wait-for a,,b" names two instances.
  auto& names = options->wait_for;
  names.erase(std::remove(names.begin(), names.end(), std::string()), names.end());
  options->config_file = config::resolveStackConfig(options->config_file);
  return std::nullopt;
}

// The keys of a `role: sim` block; the command line overrides each.
struct SimBlock {
  std::string scenario;  // none: --scenario is needed
  double speed = 1.0;
  double duration = 0;

  static const config::ParamTable<SimBlock>& table() {
    static const config::ParamTable<SimBlock> declared = [] {
      config::ParamTable<SimBlock> t;
      t.add("scenario", &SimBlock::scenario, "config/scenarios/<name>.yaml, or a path")
          .add("speed", &SimBlock::speed, config::InRange{0.01, 1000}, "x",
               "live: multiple of real time")
          .add("duration", &SimBlock::duration, config::InRange{0, 1e7}, "s",
               "simulated seconds before it stops; 0: the scenario's own length");
      return t;
    }();
    return declared;
  }
};

// The instance's block in the stack config, if it has one (the simulator
// needs none: command-line options suffice), fills what the command line left.
void applyInstanceBlock(const config::StackConfig& stack, SimOptions& options) {
  const auto& instances = stack.instances();
  if (std::find(instances.begin(), instances.end(), options.instance) == instances.end()) return;
  const config::ConfigNode block = stack.process(options.instance);
  block.getEnum("role", {"sim"});
  SimBlock configured;
  SimBlock::table().load(block, configured);
  block.requireAllKeysUsed();
  if (options.scenario.empty()) options.scenario = configured.scenario;
  if (options.speed <= 0) options.speed = configured.speed;
  if (options.duration <= 0) options.duration = configured.duration;
}

// Opens the bus for a live run; false (logged) if LCM cannot be opened.
bool openLiveBus(const SimOptions& options, SimRun& run) {
  const std::string url = config::resolveLcmUrl(options.lcm_url, run.stack->lcm_url);
  run.live_lcm = std::make_unique<lcm::LCM>(url);
  if (!run.live_lcm->good()) {
    log::error("cannot open LCM at '", url, "'");
    return false;
  }
  run.live_url = url;
  return true;
}

// Waits for health from every --wait-for instance; an exit code if the run
// ends here (stopped by a signal, or some instance stayed silent).
std::optional<int> waitForProcesses(const SimOptions& options, SimRun& run) {
  const std::string& health_channel = run.stack->robot.channels.health;
  bus::HealthBarrier barrier(*run.live_lcm, health_channel, options.wait_for);
  log::info("waiting up to ", options.wait_timeout, " s for health from ", options.wait_for.size(),
            " process instances on ", health_channel);
  if (barrier.wait(options.wait_timeout, stopRequested)) return std::nullopt;
  if (stopRequested()) return kExitOk;
  std::string missing;
  for (const auto& name : barrier.pending()) missing += (missing.empty() ? "" : ", ") + name;
  log::error("no health from ", missing, " within ", options.wait_timeout,
             " s (--wait-for): are they running on this bus?");
  return kExitFailure;
}

// Loads the configuration and the scenario, opens the bus (live), waits for
// the processes named and creates the simulator; an exit code on failure.
std::optional<int> setUp(SimOptions& options, SimRun& run) {
  try {
    run.stack =
        std::make_unique<config::StackConfig>(config::StackConfig::loadFile(options.config_file));
    applyInstanceBlock(*run.stack, options);
    if (options.scenario.empty()) {
      std::cerr << "vslam-sim: no scenario: give --scenario NAME or set processes."
                << options.instance << ".scenario in " << options.config_file << "\n";
      return kExitUsage;
    }
    run.scenario = Scenario::loadByName(options.scenario, run.stack->root.baseDir() / "scenarios");
    if (options.duration > 0) run.scenario.duration_s = options.duration;
    if (options.out.empty() && !openLiveBus(options, run)) return kExitFailure;
    if (run.live_lcm && !options.wait_for.empty()) {
      if (const auto code = waitForProcesses(options, run)) return code;
    }
    // Live, the first message is stamped now: after the wait, not before it.
    const Utime start = options.start_time >= 0 ? fromSeconds(options.start_time)
                        : options.out.empty()   ? wallUtime()
                                                : kDefaultLogStart;
    run.simulator = std::make_unique<Simulator>(run.scenario, run.stack->robot, start);
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return kExitUsage;
  } catch (const std::exception& e) {
    log::error(e.what());
    return kExitUsage;
  }
  return std::nullopt;
}

// Writes the log as fast as the simulator goes, reporting every 10% (and on
// a terminal, rate and time left).
void writeLog(Simulator& simulator, const std::string& out) {
  LogFileSink sink(out);
  double next_report = 0.1;
  ProgressMeter meter("simulate", 0, ProgressMeter::kSeconds);
  while (!stopRequested() && simulator.step(sink)) {
    if (simulator.progress() > 0) meter.setTotal(simulator.simTime() / simulator.progress());
    meter.update(simulator.simTime());
    if (simulator.progress() >= next_report) {
      log::info(static_cast<int>(100 * simulator.progress()), "% (", simulator.simTime(),
                " s simulated)");
      next_report += 0.1;
    }
  }
}

double meanRenderMs(const SimulatorStats& s) {
  return s.frames ? s.render_ms_total / static_cast<double>(s.frames) : 0.0;
}

// The simulator's HEALTH message: frames rendered since the last one, render
// time, sim time and how far behind real time it runs.
void publishHealth(lcm::LCM& lcm, const std::string& channel, const std::string& instance,
                   Utime wall_start, const Simulator& simulator, const LiveSink& sink,
                   int64_t frames_at_last_health) {
  const auto& s = simulator.stats();
  bus::HealthReport report;
  if (sink.lagMs() > 100) report.warn("cannot keep up with real time");
  report.add("frames_per_second", static_cast<double>(s.frames - frames_at_last_health), "Hz");
  report.add("render_ms_mean", meanRenderMs(s), "ms");
  report.add("sim_time", simulator.simTime(), "s");
  report.add("lag", sink.lagMs(), "ms");
  vslam::health_t h = bus::healthMessage("vslam-sim", instance, wallUtime(), wall_start, report);
  h.messages_published = sink.published();
  std::vector<uint8_t> buf(static_cast<size_t>(h.getEncodedSize()));
  h.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm.publish(channel, buf.data(), static_cast<unsigned>(buf.size()));
}

// Publishes on the bus at `speed` x real time, with health once a second.
void publishLive(SimRun& run, const SimOptions& options, Utime wall_start) {
  log::info("publishing live on ", run.live_url, " at ", options.speed, "x real time");
  LiveSink sink(*run.live_lcm, options.speed);
  Simulator& simulator = *run.simulator;
  Utime next_health = monotonicUtime() + kMicrosPerSecond;
  int64_t frames_at_health = 0;
  while (!stopRequested() && simulator.step(sink)) {
    if (monotonicUtime() >= next_health) {
      publishHealth(*run.live_lcm, run.stack->robot.channels.health, options.instance, wall_start,
                    simulator, sink, frames_at_health);
      frames_at_health = simulator.stats().frames;
      next_health += kMicrosPerSecond;
    }
  }
}

void logSummary(const Simulator& simulator, const std::string& out, Utime wall_start) {
  const auto& s = simulator.stats();
  const double wall = toSeconds(monotonicUtime() - wall_start);
  log::info("simulated ", s.sim_seconds, " s (", s.distance_m, " m driven, ", s.kidnaps,
            " kidnaps): ", s.odometry_messages, " odometry messages, ", s.frames, " frames in ",
            wall, " s wall (", s.sim_seconds / std::max(wall, 1e-9), "x real time; render ",
            meanRenderMs(s), " ms/frame)", out.empty() ? "" : ", log " + out);
}

}  // namespace

int runSimCli(const std::vector<std::string>& args) {
  log::setProcessName("sim");
  tuneAllocatorForSteadyState();
  SimOptions options;
  if (const auto code = parseSimCommandLine(args, &options)) return *code;

  installStopSignalHandlers();
  SimRun run;
  if (const auto code = setUp(options, run)) return *code;
  if (options.speed <= 0) options.speed = 1.0;
  log::info("scenario ", run.scenario.name, " (", run.scenario.file.string(), "), world ",
            run.scenario.world_file.string(), ", ", run.stack->robot.cameras.size(), " cameras");

  const Utime wall_start = monotonicUtime();
  try {
    if (!options.out.empty()) {
      writeLog(*run.simulator, options.out);
    } else {
      publishLive(run, options, wall_start);
    }
  } catch (const std::exception& e) {
    log::error(e.what());
    return kExitFailure;
  }
  logSummary(*run.simulator, options.out, wall_start);
  return kExitOk;
}

}  // namespace vslam::sim
