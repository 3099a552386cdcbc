#pragma once
// vslam-status's command line: listens to HEALTH on the bus and shows the
// status board (status_board.hpp) every second, or once (--once) with an
// exit status for scripts.

#include <string>
#include <vector>
#include <vslam/health_t.hpp>

#include "status/status_board.hpp"

namespace vslam::status {

// A decoded HEALTH message as the board takes it, arrived at `received_s`.
HealthSample healthSampleOf(const vslam::health_t& h, double received_s);

// Exit statuses: 0; 1 with --once when a process is stale, none was heard or
// one reports ERROR; 2 for a bad command line or config.
int runStatusCli(const std::vector<std::string>& args);

}  // namespace vslam::status
