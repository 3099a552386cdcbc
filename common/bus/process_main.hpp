#pragma once
// The whole of a process's main(): arguments, logging, configuration, LCM,
// signals, the live loop. processes/<role>/main.cpp is one call to this.
//
//   vslam-<role> [--config FILE] [--instance NAME] [--lcm-url URL] [--print-config] [--help]
//
// Exit codes: 0 clean stop (SIGINT/SIGTERM), 1 runtime failure (e.g. LCM
// cannot start), 2 bad command line or configuration.

#include <string>

#include "bus/stage_registry.hpp"
#include "util/command_line.hpp"

namespace vslam::bus {

int runStageProcess(int argc, char** argv, const std::string& role, const StageRegistry& registry);

}  // namespace vslam::bus
