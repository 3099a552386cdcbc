#pragma once
// The pre-filter's acceptance region (vSLAM paper section 5) is one for the
// whole stack: the back-end rejects measurements outside it, and each
// front-end asks it whether a place is already covered by a landmark. So it
// is a top-level block of the stack file, read here by both stages:
//
//   prefilter:
//     max_proj_err_rms_px: 3.0
//     min_num_points: 10
//     max_slope: 0.1
//
// Absent keys (or the whole block) take the defaults of
// backend::PrefilterParams.

#include "backend/prefilter.hpp"
#include "config/param_table.hpp"
#include "config/stack_config.hpp"

namespace vslam::stages {

// The block's keys, declared once (config/param_table.hpp).
const config::ParamTable<backend::PrefilterParams>& prefilterParamTable();

// ConfigError for a bad or unknown key of the block.
backend::PrefilterParams loadPrefilter(const config::StackConfig& stack);

// For a stage block that still has its own `prefilter:` (before it moved to
// the top level): a ConfigError saying where it belongs now.
void rejectInstancePrefilter(const config::ConfigNode& instance);

}  // namespace vslam::stages
