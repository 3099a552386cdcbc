#pragma once
#include "bus/stage_registry.hpp"

namespace vslam::stages {

// Every stage role this build knows, for process mains and vslam-replay.
// Each issue that adds a stage registers it in builtin_stages.cpp.
const bus::StageRegistry& builtinStages();

}  // namespace vslam::stages
