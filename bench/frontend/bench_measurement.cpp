// One visual measurement (paper 4.2): RANSAC PnP, Ceres refinement with
// inlier re-selection, ProjErrRMS/NPoints/Slope and the planar sigmas, on
// 30, 50 and 100 correspondences with 20% outliers and 0.5 px noise, the
// 320x240 simulated camera. Figures in docs/frontend.md ("Measurement").
//
//   bench_measurement --benchmark_min_time=1

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/pose_measurement.hpp"

namespace {

using vslam::frontend::MeasurementCamera;
using vslam::frontend::PnpSolver;
using vslam::frontend::PoseMeasurementParams;

constexpr double kF = 277.13;
constexpr double kHalfW = 160.0 / kF, kHalfH = 120.0 / kF;
constexpr int kScenes = 16;  // cycled, so RANSAC's luck averages out

struct Scene {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> obs;
};

MeasurementCamera camera() {
  MeasurementCamera c;
  c.fx = c.fy = kF;
  c.robot_T_camera.linear() = vslam::config::robotRotationCamera(0, 0, 0);
  c.robot_T_camera.translation() = Eigen::Vector3d(0.10, 0, 0.30);
  return c;
}

// Points 1-5 m in front of the creating camera, seen after the robot moved
// (0.3, -0.2, 15 deg); 20% of the observations replaced by random ones.
Scene makeScene(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1), depth(1.0, 5.0);
  std::normal_distribution<double> noise(0, 0.5 / kF);
  const MeasurementCamera cam = camera();
  Eigen::Isometry3d creation_T_current = Eigen::Isometry3d::Identity();
  creation_T_current.linear() =
      Eigen::AngleAxisd(15 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  creation_T_current.translation() = Eigen::Vector3d(0.3, -0.2, 0);
  const Eigen::Isometry3d camera_T_creation =
      cam.robot_T_camera.inverse() * creation_T_current.inverse();
  Scene s;
  while (static_cast<int>(s.points.size()) < n) {
    const double d = depth(rng);
    const Eigen::Vector3d x =
        cam.robot_T_camera * Eigen::Vector3d(d * kHalfW * uni(rng), d * kHalfH * uni(rng), d);
    const Eigen::Vector3d p = camera_T_creation * x;
    if (p.z() < 0.2 || std::abs(p.x() / p.z()) > kHalfW || std::abs(p.y() / p.z()) > kHalfH)
      continue;
    s.points.push_back(x);
    s.obs.emplace_back(p.x() / p.z() + noise(rng), p.y() / p.z() + noise(rng));
  }
  for (int i = 0; i < n / 5; ++i) s.obs[i] = Eigen::Vector2d(kHalfW * uni(rng), kHalfH * uni(rng));
  return s;
}

void runMeasurement(benchmark::State& state, PnpSolver solver) {
  const int n = static_cast<int>(state.range(0));
  std::vector<Scene> scenes;
  for (int k = 0; k < kScenes; ++k) scenes.push_back(makeScene(n, 100 + k));
  const MeasurementCamera cam = camera();
  PoseMeasurementParams params;
  params.solver = solver;
  int k = 0, failures = 0;
  double ransac_ms = 0, refine_ms = 0, inliers = 0, iterations = 0;
  for (auto _ : state) {
    const Scene& s = scenes[k++ % kScenes];
    const auto r = vslam::frontend::measurePose(s.points, s.obs, cam, params);
    benchmark::DoNotOptimize(r.measurement.relative);
    failures += r.ok() ? 0 : 1;
    ransac_ms += r.measurement.ransac_ms;
    refine_ms += r.measurement.refine_ms;
    inliers += r.measurement.num_points;
    iterations += r.measurement.solver_iterations;
  }
  const double runs = static_cast<double>(state.iterations());
  state.counters["ransac_ms"] = ransac_ms / runs;
  state.counters["refine_ms"] = refine_ms / runs;
  state.counters["inliers"] = inliers / runs;
  state.counters["ceres_iters"] = iterations / runs;
  state.counters["failures"] = failures;
}

void BM_MeasurementAp3p(benchmark::State& state) { runMeasurement(state, PnpSolver::kAp3p); }
void BM_MeasurementP3p(benchmark::State& state) { runMeasurement(state, PnpSolver::kP3p); }
void BM_MeasurementEpnp(benchmark::State& state) { runMeasurement(state, PnpSolver::kEpnp); }
void BM_MeasurementSqpnp(benchmark::State& state) { runMeasurement(state, PnpSolver::kSqpnp); }
BENCHMARK(BM_MeasurementAp3p)->Arg(30)->Arg(50)->Arg(100)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MeasurementP3p)->Arg(30)->Arg(50)->Arg(100)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MeasurementEpnp)->Arg(30)->Arg(50)->Arg(100)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MeasurementSqpnp)->Arg(30)->Arg(50)->Arg(100)->Unit(benchmark::kMicrosecond);

}  // namespace
