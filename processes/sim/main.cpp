// vslam-sim: the simulated robot (common/sim/simulator.hpp). Either publishes
// live on the bus, paced to real time (or --speed times it), or writes an LCM
// log as fast as it can (--out).
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <thread>
#include <vslam/health_t.hpp>

#include "bus/health_barrier.hpp"
#include "bus/messages.hpp"
#include "bus/process_main.hpp"
#include "config/stack_config.hpp"
#include "sim/simulator.hpp"
#include "util/log.hpp"
#include "util/process.hpp"

namespace {

using namespace vslam;

// 2026-01-01T00:00:00Z: logs written with --out start here unless told
// otherwise, so the same scenario gives the same log.
constexpr Utime kDefaultLogStart = 1767225600LL * kMicrosPerSecond;

void usage() {
  std::cout
      << "usage: vslam-sim [--scenario NAME|FILE] [--out LOG] [options]\n"
         "  --scenario NAME|FILE  config/scenarios/NAME.yaml or a scenario file (default: the\n"
         "                        instance's `scenario` in the stack config)\n"
         "  --out LOG             write an LCM log as fast as possible instead of publishing\n"
         "  --speed X             live: publish at X times real time (default: config, else 1)\n"
         "  --duration S          stop after S simulated seconds (default: config, else the\n"
         "                        scenario's own length)\n"
         "  --start-time UNIX_S   time stamp of the first message (default: now live, 2026-01-01 "
         "with --out)\n"
         "  --config FILE         stack configuration: robot cameras and channels (default "
         "$VSLAM_CONFIG, else config/vslam.yaml)\n"
         "  --instance NAME       block under processes: (default sim)\n"
         "  --lcm-url URL         live: LCM provider\n"
         "  --wait-for A,B,...    live: publish nothing until these process instances have\n"
         "                        published health (they are subscribed), e.g. when started\n"
         "                        together with them by scripts/launch\n"
         "  --wait-timeout S      live: give up waiting after S seconds (default 60; exit 1)\n";
}

// Publishes on the bus, sleeping so that sim time runs at `speed` x real time.
class LiveSink final : public sim::EventSink {
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

}  // namespace

int main(int argc, char** argv) {
  log::setProcessName("sim");
  tuneAllocatorForSteadyState();
  std::string scenario_arg, out, config_file, instance = "sim", lcm_url;
  double speed = 0, duration = 0, start_time = -1, wait_timeout = 60;
  std::vector<std::string> wait_for;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "vslam-sim: " << a << " needs a value\n";
        std::exit(bus::kExitUsage);
      }
      return argv[++i];
    };
    auto number = [&](const std::string& text) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || !(v >= 0)) {
        std::cerr << "vslam-sim: " << a << " expects a number >= 0, got '" << text << "'\n";
        std::exit(bus::kExitUsage);
      }
      return v;
    };
    if (a == "--help" || a == "-h") {
      usage();
      return bus::kExitOk;
    } else if (a == "--scenario") {
      scenario_arg = next();
    } else if (a == "--out") {
      out = next();
    } else if (a == "--speed") {
      speed = number(next());
    } else if (a == "--duration") {
      duration = number(next());
    } else if (a == "--start-time") {
      start_time = number(next());
    } else if (a == "--config") {
      config_file = next();
    } else if (a == "--instance") {
      instance = next();
    } else if (a == "--lcm-url") {
      lcm_url = next();
    } else if (a == "--wait-for") {
      std::stringstream list(next());
      for (std::string name; std::getline(list, name, ',');) {
        if (!name.empty()) wait_for.push_back(name);
      }
    } else if (a == "--wait-timeout") {
      wait_timeout = number(next());
    } else {
      std::cerr << "vslam-sim: unknown argument '" << a << "' (see --help)\n";
      return bus::kExitUsage;
    }
  }
  if (config_file.empty()) {
    const char* env = std::getenv("VSLAM_CONFIG");
    config_file = env && *env ? env : "config/vslam.yaml";
  }

  installStopSignalHandlers();
  std::unique_ptr<sim::Simulator> simulator;
  std::unique_ptr<lcm::LCM> live_lcm;
  std::string live_url;
  std::unique_ptr<config::StackConfig> stack_holder;
  sim::Scenario scenario;
  try {
    stack_holder =
        std::make_unique<config::StackConfig>(config::StackConfig::loadFile(config_file));
    // The instance block is optional for the simulator: command-line options suffice.
    const bool has_block = [&] {
      for (const auto& name : stack_holder->instances()) {
        if (name == instance) return true;
      }
      return false;
    }();
    if (has_block) {
      const config::ConfigNode block = stack_holder->process(instance);
      block.getEnum("role", {"sim"});
      const std::string configured = block.getString("scenario", "");
      const double configured_speed = block.getDouble("speed", 1.0, config::InRange{0.01, 1000});
      const double configured_duration = block.getDouble("duration", 0.0, config::InRange{0, 1e7});
      block.requireAllKeysUsed();
      if (scenario_arg.empty()) scenario_arg = configured;
      if (speed <= 0) speed = configured_speed;
      if (duration <= 0) duration = configured_duration;
    }
    if (scenario_arg.empty()) {
      std::cerr << "vslam-sim: no scenario: give --scenario NAME or set processes." << instance
                << ".scenario in " << config_file << "\n";
      return bus::kExitUsage;
    }
    scenario = sim::Scenario::loadByName(scenario_arg, stack_holder->root.baseDir() / "scenarios");
    if (duration > 0) scenario.duration_s = duration;
    if (out.empty()) {
      const std::string url = config::resolveLcmUrl(lcm_url, stack_holder->lcm_url);
      live_lcm = std::make_unique<lcm::LCM>(url);
      if (!live_lcm->good()) {
        log::error("cannot open LCM at '", url, "'");
        return bus::kExitFailure;
      }
      live_url = url;
    }
    if (live_lcm && !wait_for.empty()) {
      bus::HealthBarrier barrier(*live_lcm, stack_holder->robot.channels.health, wait_for);
      log::info("waiting up to ", wait_timeout, " s for health from ", wait_for.size(),
                " process instances on ", stack_holder->robot.channels.health);
      if (!barrier.wait(wait_timeout, stopRequested)) {
        if (stopRequested()) return bus::kExitOk;
        std::string missing;
        for (const auto& name : barrier.pending()) missing += (missing.empty() ? "" : ", ") + name;
        log::error("no health from ", missing, " within ", wait_timeout,
                   " s (--wait-for): are they running on this bus?");
        return bus::kExitFailure;
      }
    }
    // Live, the first message is stamped now: after the wait, not before it.
    const Utime start = start_time >= 0 ? fromSeconds(start_time)
                        : out.empty()   ? wallUtime()
                                        : kDefaultLogStart;
    simulator = std::make_unique<sim::Simulator>(scenario, stack_holder->robot, start);
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return bus::kExitUsage;
  } catch (const std::exception& e) {
    log::error(e.what());
    return bus::kExitUsage;
  }
  const config::StackConfig& stack = *stack_holder;
  if (speed <= 0) speed = 1.0;
  log::info("scenario ", scenario.name, " (", scenario.file.string(), "), world ",
            scenario.world_file.string(), ", ", stack.robot.cameras.size(), " cameras");

  const Utime wall_start = monotonicUtime();
  try {
    if (!out.empty()) {
      sim::LogFileSink sink(out);
      double next_report = 0.1;
      while (!stopRequested() && simulator->step(sink)) {
        if (simulator->progress() >= next_report) {
          log::info(static_cast<int>(100 * simulator->progress()), "% (", simulator->simTime(),
                    " s simulated)");
          next_report += 0.1;
        }
      }
    } else {
      lcm::LCM& lcm = *live_lcm;
      log::info("publishing live on ", live_url, " at ", speed, "x real time");
      LiveSink sink(lcm, speed);
      Utime next_health = monotonicUtime() + kMicrosPerSecond;
      int64_t frames_at_health = 0;
      while (!stopRequested() && simulator->step(sink)) {
        if (monotonicUtime() >= next_health) {
          const auto& s = simulator->stats();
          bus::HealthReport report;
          if (sink.lagMs() > 100) report.warn("cannot keep up with real time");
          report.add("frames_per_second", static_cast<double>(s.frames - frames_at_health), "Hz");
          report.add("render_ms_mean",
                     s.frames ? s.render_ms_total / static_cast<double>(s.frames) : 0, "ms");
          report.add("sim_time", simulator->simTime(), "s");
          report.add("lag", sink.lagMs(), "ms");
          vslam::health_t h =
              bus::healthMessage("vslam-sim", instance, wallUtime(), wall_start, report);
          h.messages_published = sink.published();
          std::vector<uint8_t> buf(static_cast<size_t>(h.getEncodedSize()));
          h.encode(buf.data(), 0, static_cast<int>(buf.size()));
          lcm.publish(stack.robot.channels.health, buf.data(), static_cast<unsigned>(buf.size()));
          frames_at_health = s.frames;
          next_health += kMicrosPerSecond;
        }
      }
    }
  } catch (const std::exception& e) {
    log::error(e.what());
    return bus::kExitFailure;
  }
  const auto& s = simulator->stats();
  const double wall = toSeconds(monotonicUtime() - wall_start);
  log::info("simulated ", s.sim_seconds, " s (", s.distance_m, " m driven, ", s.kidnaps,
            " kidnaps): ", s.odometry_messages, " odometry messages, ", s.frames, " frames in ",
            wall, " s wall (", s.sim_seconds / std::max(wall, 1e-9), "x real time; render ",
            s.frames ? s.render_ms_total / static_cast<double>(s.frames) : 0.0, " ms/frame)",
            out.empty() ? "" : ", log " + out);
  return bus::kExitOk;
}
