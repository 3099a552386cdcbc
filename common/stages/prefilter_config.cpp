#include "stages/prefilter_config.hpp"

namespace vslam::stages {

backend::PrefilterParams loadPrefilter(const config::StackConfig& stack) {
  backend::PrefilterParams p;
  if (!stack.root.has("prefilter")) return p;
  using config::InRange;
  const config::ConfigNode pf = stack.root.child("prefilter");
  p.max_proj_err_rms_px =
      pf.getDouble("max_proj_err_rms_px", p.max_proj_err_rms_px, InRange{1e-3, 1000});
  p.min_num_points =
      static_cast<int>(pf.getInt("min_num_points", p.min_num_points, InRange{0, 100000}));
  p.max_slope = pf.getDouble("max_slope", p.max_slope, InRange{0, 1e9});
  pf.requireAllKeysUsed();
  return p;
}

void rejectInstancePrefilter(const config::ConfigNode& instance) {
  if (instance.has("prefilter")) {
    throw instance.error("prefilter",
                         "the pre-filter is one for the stack now: move this block to the top "
                         "level of the file (it is shared by the front-ends and the back-end)");
  }
}

}  // namespace vslam::stages
