// The back-end over hours of robot time (issue 16, "a pose graph whose cost
// does not grow with the run"): the shipped back-end parameters
// (config/vslam.yaml, map correction on) driven by a robot lapping a
// 6 m x 4 m home with 36 landmarks, odometry at 20 Hz with the motion model's
// noise, a measurement of each landmark in view at 5 Hz. Every hour of robot
// time it prints the graph's size, the time per solve, the back-end's
// update time (p50 / p99 / max over that hour) and the process's RSS.
// The robot time runs ~100x faster than real time here, so an update that
// takes a background solve's result often waits for the worker, which a
// robot at 1x would not: the update times are given without those waits
// (the filter's path), and the waits are counted beside them. With
// solve_in_background false the solve is on the update and counts in it.
//
//   bench_long_run [--hours 8] [--config config/vslam.yaml] [--json FILE]
//
// Synthetic measurements (y = true relative pose + noise, as the unit tests
// use): this measures cost, not accuracy; the landmark error at the end is
// printed as a sanity check that the estimator was working.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "backend/backend.hpp"
#include "backend/measurement_model.hpp"
#include "backend/rng.hpp"
#include "config/stack_config.hpp"
#include "stages/backend_stage.hpp"
#include "stages/prefilter_config.hpp"
#include "util/command_line.hpp"
#include "util/process.hpp"

namespace {

using namespace vslam;
using namespace vslam::backend;

constexpr double kOdometryHz = 20;
constexpr double kMeasurementHz = 5;
constexpr double kSpeedMps = 0.3;
constexpr double kWidthM = 6, kHeightM = 4;
constexpr double kLandmarkSpacingM = 0.55;  // 36 landmarks on the 20 m lap
constexpr double kRangeM = 1.2, kMaxHeadingRad = 40 * M_PI / 180;
constexpr double kCreationDelayS = 2.0;  // the front-end announces after its third view

// The true path by arc length: straight sides, 90 degree turns over 0.3 m.
class Lap {
 public:
  Pose2 step(double s, double ds) const {
    const double sides[4] = {kWidthM, kHeightM, kWidthM, kHeightM};
    const double lap = std::fmod(s, 2 * (kWidthM + kHeightM));
    double acc = 0;
    for (double side : sides) {
      acc += side;
      if (lap < acc) return {ds, 0, lap + ds > acc - 0.3 ? (M_PI / 2) * ds / 0.3 : 0.0};
    }
    return {ds, 0, 0};
  }
};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const auto k = static_cast<size_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

}  // namespace

int main(int argc, char** argv) {
  double hours = 8;
  std::string config_file = config::kDefaultStackConfig, json_file;
  CLI::App app{"The back-end's cost over hours of robot time (docs/benchmarks.md)."};
  app.add_option("--hours", hours, "robot time to drive")->check(CLI::Range(0.01, 100.0));
  app.add_option("--config", config_file, "stack configuration (its backend process)");
  app.add_option("--json", json_file, "also write the table as JSON here");
  if (const auto status =
          parseCommandLine(app, "bench_long_run", argumentsOf(argc, argv), std::cout, std::cerr))
    return *status;
  tuneAllocatorForSteadyState();

  std::optional<stages::BackendStageParams> loaded;
  try {
    const config::StackConfig stack = config::StackConfig::loadFile(config_file);
    loaded = stages::BackendStageParams::load(stack.process("backend"), stack.robot,
                                              stages::loadPrefilter(stack));
  } catch (const std::exception& e) {
    std::cerr << "bench_long_run: " << e.what() << " (run from the source tree, or --config)\n";
    return kExitUsage;
  }
  const stages::BackendStageParams& params = *loaded;
  Backend backend(params.backend);

  const Lap lap;
  RandomStream rng(2026, 0, 0, 0);
  const MotionNoise noise = params.backend.filter.motion;
  const double dt = 1 / kOdometryHz, ds = kSpeedMps * dt;
  const auto ticks = static_cast<int64_t>(hours * 3600 * kOdometryHz);
  const auto measure_every = static_cast<int64_t>(kOdometryHz / kMeasurementHz);
  const auto ticks_per_hour = static_cast<int64_t>(3600 * kOdometryHz);
  const int64_t t0 = 1700000000000000LL;
  auto utimeOf = [&](int64_t tick) { return t0 + static_cast<int64_t>(tick * 1e6 / kOdometryHz); };

  struct TrueLandmark {
    int64_t id;
    Pose2 pose;
    int64_t announce_tick;
    bool announced = false;
  };
  std::vector<TrueLandmark> landmarks;
  Pose2 truth, odometry;
  double arc = 0, next_landmark = 0.2;
  const double lap_m = 2 * (kWidthM + kHeightM);

  std::vector<double> update_ms, solve_ms;
  int64_t solves_before = 0, waits_before = 0;
  nlohmann::json rows = nlohmann::json::array();
  std::printf("%6s %7s %9s %12s %12s %12s %12s %12s %9s %7s %7s\n", "hour", "nodes", "removed",
              "solve p50", "solve max", "update p50", "update p99", "update max", "RSS MB",
              "solves", "waits");
  backend.addOdometry({utimeOf(0), 0, odometry});
  for (int64_t tick = 1; tick <= ticks; ++tick) {
    const Pose2 motion = lap.step(arc, ds);
    arc += ds;
    truth = truth.compose(motion);
    odometry = odometry.compose(noise.perturb(motion, rng.normal(), rng.normal()));
    const int64_t utime = utimeOf(tick);
    backend.addOdometry({utime, static_cast<uint32_t>(tick), odometry});
    if (arc <= lap_m && arc >= next_landmark) {
      landmarks.push_back({1000000000LL + static_cast<int64_t>(landmarks.size()), truth,
                           tick + static_cast<int64_t>(kCreationDelayS * kOdometryHz)});
      next_landmark += kLandmarkSpacingM;
    }
    for (TrueLandmark& l : landmarks) {
      if (!l.announced && tick >= l.announce_tick) {
        backend.addLandmarkCreation(
            l.id, utimeOf(l.announce_tick) - static_cast<int64_t>(kCreationDelayS * 1e6));
        l.announced = true;
      }
    }
    if (tick % measure_every == 0) {
      for (const TrueLandmark& l : landmarks) {
        Pose2 rel = predictMeasurement(truth, l.pose);
        if (std::hypot(rel.x, rel.y) > kRangeM || std::abs(rel.theta) > kMaxHeadingRad) continue;
        rel.x += 0.02 * rng.normal();
        rel.y += 0.02 * rng.normal();
        rel.theta = wrapAngle(rel.theta + 0.005 * rng.normal());
        MeasurementInput m;
        m.utime = utime;
        m.landmark_id = l.id;
        m.relative = rel;
        m.proj_err_rms_px = 0.8;
        m.num_points = 40;
        const double waited_before = backend.counters().graph_solve_wait_ms;
        const auto start = std::chrono::steady_clock::now();
        backend.addMeasurement(m);
        const BackendCounters& c = backend.counters();
        update_ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count() -
            (c.graph_solve_wait_ms - waited_before));
        if (c.graph_solves != solves_before) {
          solves_before = c.graph_solves;
          solve_ms.push_back(c.graph_last_solve_ms);
        }
      }
    }
    if (tick % ticks_per_hour == 0 || tick == ticks) {
      const PoseGraph* graph = backend.poseGraph();
      const nlohmann::json row = {
          {"robot_hours", static_cast<double>(tick) / static_cast<double>(ticks_per_hour)},
          {"graph_nodes", graph ? graph->numNodes() : 0},
          {"graph_nodes_removed", graph ? graph->numNodesRemoved() : 0},
          {"solve_ms_p50", percentile(solve_ms, 0.5)},
          {"solve_ms_max",
           solve_ms.empty() ? 0 : *std::max_element(solve_ms.begin(), solve_ms.end())},
          {"update_ms_p50", percentile(update_ms, 0.5)},
          {"update_ms_p99", percentile(update_ms, 0.99)},
          {"update_ms_max",
           update_ms.empty() ? 0 : *std::max_element(update_ms.begin(), update_ms.end())},
          {"rss_mb", static_cast<double>(currentResourceUsage().rss_bytes) / 1e6},
          {"solves", solve_ms.size()},
          {"solve_waits", backend.counters().graph_solve_waits - waits_before},
      };
      std::printf("%6.2f %7d %9lld %9.2f ms %9.2f ms %9.3f ms %9.3f ms %9.2f ms %9.1f %7zu %7lld\n",
                  row["robot_hours"].get<double>(), row["graph_nodes"].get<int>(),
                  static_cast<long long>(row["graph_nodes_removed"].get<int64_t>()),
                  row["solve_ms_p50"].get<double>(), row["solve_ms_max"].get<double>(),
                  row["update_ms_p50"].get<double>(), row["update_ms_p99"].get<double>(),
                  row["update_ms_max"].get<double>(), row["rss_mb"].get<double>(), solve_ms.size(),
                  static_cast<long long>(row["solve_waits"].get<int64_t>()));
      std::fflush(stdout);
      rows.push_back(row);
      waits_before = backend.counters().graph_solve_waits;
      update_ms.clear();
      solve_ms.clear();
    }
  }
  // Sanity: the estimate is still where the robot is.
  const Pose2 est = backend.filter().estimate().mean;
  const double error = std::hypot(est.x - truth.x, est.y - truth.y);
  std::printf("final position error %.3f m (odometry alone %.3f m)\n", error,
              std::hypot(odometry.x - truth.x, odometry.y - truth.y));
  if (!json_file.empty()) {
    std::ofstream(json_file) << nlohmann::json{{"rows", rows}, {"final_error_m", error}}.dump(2)
                             << "\n";
  }
  return 0;
}
