#include "eval/evaluate.hpp"

#include "eval/errors.hpp"

namespace vslam::eval {

std::string toString(EstimateKind kind) {
  return kind == EstimateKind::kEstimate ? "estimate" : "odometry";
}

EstimateEvaluation evaluateEstimate(const Trajectory& ref, const EstimateInput& est,
                                    const TrajectoryEvalOptions& options) {
  const Trajectory& traj = est.trajectory;
  if (traj.empty()) throw DataError("estimate " + traj.name + " has no poses");
  EstimateEvaluation e;
  e.name = traj.name;
  e.kind = est.kind;
  e.source = est.source;
  e.poses = traj.size();
  e.duration = traj.duration();
  e.path_length = traj.pathLength();
  e.ate = computeAte(ref, traj, options.offset, options.max_diff, options.align);
  e.aligned = e.ate.alignment.apply(traj);
  RpeOptions rpe = options.rpe;
  rpe.offset = options.offset;
  e.rpe = computeRpe(ref, e.aligned, rpe);
  e.error_times.reserve(e.ate.matches.size());
  for (const auto& m : e.ate.matches) e.error_times.push_back(ref.poses[m.ref].t);
  return e;
}

}  // namespace vslam::eval
