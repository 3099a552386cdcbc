#pragma once
#include "bus/stage_registry.hpp"

namespace vslam::stages {

// Every stage role this build knows, for process mains and vslam-replay.
// Each issue that adds a stage registers it in builtin_stages.cpp.
const bus::StageRegistry& builtinStages();

// Sensor drivers run as stages (their process mains use runStageProcess), but
// apart from builtinStages(): vslam-replay, where the log holds the sensor
// data, never starts them, even if their instances are in the config.
const bus::StageRegistry& driverStages();

}  // namespace vslam::stages
