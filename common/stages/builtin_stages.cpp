#include "stages/builtin_stages.hpp"

#include "stages/appearance_stage.hpp"
#include "stages/backend_stage.hpp"
#include "stages/camera_stage.hpp"
#include "stages/deadreckon_stage.hpp"
#include "stages/frontend_stage.hpp"
#include "stages/landmark_db_stage.hpp"
#include "stages/odometry_bridge_stage.hpp"

namespace vslam::stages {

const bus::StageRegistry& builtinStages() {
  static const bus::StageRegistry registry = [] {
    bus::StageRegistry r;
    registerDeadReckon(r);
    registerFrontend(r);
    registerBackend(r);
    registerAppearance(r);
    registerLandmarkDb(r);
    return r;
  }();
  return registry;
}

const bus::StageRegistry& driverStages() {
  static const bus::StageRegistry registry = [] {
    bus::StageRegistry r;
    registerOdometryBridge(r);
    registerCamera(r);
    return r;
  }();
  return registry;
}

}  // namespace vslam::stages
