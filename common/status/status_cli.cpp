#include "status/status_cli.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <filesystem>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <vslam/health_t.hpp>

#include "bus/bus.hpp"
#include "config/stack_config.hpp"
#include "status/status_board.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"
#include "util/process.hpp"
#include "util/time.hpp"

namespace vslam::status {
namespace {

struct StatusOptions {
  std::string lcm_url, config_file, channel;
  bool once = false;
  double wait_s = 4.0;
  double interval_s = 1.0;
  BoardOptions board;
};

}  // namespace

HealthSample healthSampleOf(const vslam::health_t& h, double received_s) {
  HealthSample s;
  s.received_s = received_s;
  s.process = h.process;
  s.instance = h.instance;
  s.host = h.host;
  s.pid = h.pid;
  s.uptime_s = h.uptime;
  s.level = h.level;
  s.message = h.message;
  s.cpu_seconds = h.cpu_seconds;
  s.rss_bytes = h.rss_bytes;
  s.received = h.messages_received;
  s.published = h.messages_published;
  s.dropped = h.messages_dropped;
  s.malformed = h.messages_malformed;
  s.handler_latency_ms = h.handler_latency_ms;
  s.metrics.reserve(h.metrics.size());
  for (const auto& m : h.metrics) s.metrics.push_back({m.name, m.value, m.unit});
  return s;
}

namespace {

int terminalWidth() {
  winsize ws{};
  if (isatty(STDOUT_FILENO) == 1 && ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) {
    return ws.ws_col;
  }
  return 200;
}

double nowSeconds() { return toSeconds(monotonicUtime()); }

}  // namespace

int runStatusCli(const std::vector<std::string>& args) {
  StatusOptions o;
  CLI::App app{
      "vslam-status: every process on the bus, from its HEALTH messages: level, rates, CPU,\n"
      "memory, drops, latency and its key figures; stale processes and inputs gone quiet\n"
      "marked. Refreshed every second; --once prints one board and exits (1 if a process\n"
      "is stale, reports ERROR, or none was heard).",
      "vslam-status"};
  app.add_option("--lcm-url", o.lcm_url,
                 "LCM URL (default: $LCM_DEFAULT_URL, the config's, "
                 "else the stack's default)");
  app.add_option("--config", o.config_file,
                 "stack configuration for the URL and the health channel (default $VSLAM_CONFIG, "
                 "else config/vslam.yaml if it exists)");
  app.add_option("--channel", o.channel, "health channel (default: the robot file's, else HEALTH)");
  app.add_flag("--once", o.once, "listen for --wait seconds, print the board, exit");
  app.add_option("--wait", o.wait_s, "with --once: seconds to listen")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  app.add_option("--interval", o.interval_s, "seconds between refreshes")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  app.add_option("--stale-after", o.board.stale_after_s,
                 "a process silent this long is stale (health comes every second)")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 3600.0));
  if (const auto code = parseCommandLine(app, "vslam-status", args, std::cout, std::cerr)) {
    return *code;
  }

  std::string config_url;
  try {
    const std::string file = config::resolveStackConfig(o.config_file);
    std::error_code ec;
    if (!o.config_file.empty() || std::filesystem::exists(file, ec)) {
      const auto stack = config::StackConfig::loadFile(file);
      config_url = stack.lcm_url;
      if (o.channel.empty()) o.channel = stack.robot.channels.health;
    }
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return kExitUsage;
  }
  if (o.channel.empty()) o.channel = "HEALTH";

  const std::string url = config::resolveLcmUrl(o.lcm_url, config_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    log::error("cannot open LCM on ", url);
    return kExitFailure;
  }
  installStopSignalHandlers();
  StatusBoard board(o.board);
  WallClock clock;
  bus::Bus bus(lcm, clock, "status");
  bus.subscribe<vslam::health_t>(
      o.channel, [&](const vslam::health_t& h) { board.add(healthSampleOf(h, nowSeconds())); },
      200);

  const bool terminal = isatty(STDOUT_FILENO) == 1;
  const double started = nowSeconds();
  double next_draw = started + (o.once ? o.wait_s : o.interval_s);
  while (!stopRequested()) {
    lcm.handleTimeout(100);
    const double now = nowSeconds();
    if (now < next_draw) continue;
    const std::string text = renderBoard(board.rows(now), terminalWidth());
    if (o.once) {
      std::cout << text;
      if (board.size() == 0) {
        std::cout << "no process heard on " << o.channel << " in " << o.wait_s << " s (" << url
                  << ")\n";
        return kExitFailure;
      }
      bool error = false;
      for (const Row& r : board.rows(now)) error = error || r.level >= 2;
      return board.anyStale(now) || error ? kExitFailure : kExitOk;
    }
    // A terminal shows one board in place; a pipe gets one board per refresh.
    std::cout << (terminal ? "\033[H\033[2J" : "\n") << "vslam-status: " << board.size()
              << " processes on " << o.channel << " (" << url << ")\n"
              << text << std::flush;
    next_draw = now + o.interval_s;
  }
  return kExitOk;
}

}  // namespace vslam::status
