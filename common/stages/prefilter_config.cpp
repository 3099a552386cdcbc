#include "stages/prefilter_config.hpp"

namespace vslam::stages {

const config::ParamTable<backend::PrefilterParams>& prefilterParamTable() {
  using P = backend::PrefilterParams;
  using config::InRange;
  static const config::ParamTable<P> declared = [] {
    config::ParamTable<P> t;
    t.add("max_proj_err_rms_px", &P::max_proj_err_rms_px, InRange{1e-3, 1000}, "px",
          "reject if ProjErrRMS > this")
        .add("min_num_points", &P::min_num_points, InRange{0, 100000}, "",
             "reject if NPoints < this")
        .add("max_slope", &P::max_slope, InRange{0, 1e9}, "",
             "reject if Slope > this (tan of the robot's tilt)");
    return t;
  }();
  return declared;
}

backend::PrefilterParams loadPrefilter(const config::StackConfig& stack) {
  backend::PrefilterParams p;
  if (!stack.root.has("prefilter")) return p;
  const config::ConfigNode pf = stack.root.child("prefilter");
  prefilterParamTable().load(pf, p);
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
