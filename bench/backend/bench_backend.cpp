// The back-end's particle filter (paper section 6): one update (motion step,
// one landmark measurement with the mixture proposal, resampling when the
// effective sample size is low) for 200 / 1,000 / 10,000 particles, 50 / 500
// / 5,000 landmarks, 1 and 2 threads; and systematic resampling alone
// against the number of landmarks (copy-on-write maps: it should not grow).
//
//   bench_backend --benchmark_min_time=1
//
// The landmarks are loaded into a shared map (ParticleFilter::loadMap); the
// robot drives 2 cm per update and measures a landmark in turn, with
// measurements consistent with the truth plus noise, so the particles spread,
// get weighted and resample as in a run (about one update in 3-5 resamples).

#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "backend/measurement_model.hpp"
#include "backend/particle_filter.hpp"
#include "backend/rng.hpp"

namespace {

using namespace vslam;
using namespace vslam::backend;

struct Setup {
  std::unique_ptr<ParticleFilter> pf;
  std::vector<Pose2> landmarks;
  Pose2 truth;
  RandomStream rng{12345};
  size_t next = 0;
  int64_t resamplings = 0;
  int64_t updates = 0;

  Setup(int particles, int num_landmarks, int threads) {
    FilterParams p;
    p.num_particles = particles;
    p.num_threads = threads;
    p.motion = {0.05, 0.05};
    pf = std::make_unique<ParticleFilter>(p);
    std::vector<ParticleFilter::KnownLandmark> known;
    for (int k = 0; k < num_landmarks; ++k) {
      // Landmarks scattered over a 20 m x 20 m area, random headings.
      const Pose2 phi{20 * rng.uniform() - 10, 20 * rng.uniform() - 10,
                      M_PI * (2 * rng.uniform() - 1)};
      landmarks.push_back(phi);
      LandmarkEstimate e;
      e.mean = phi.vector();
      e.covariance = Eigen::Vector3d(0.0025, 0.0025, 0.0004).asDiagonal();
      e.num_observations = 5;
      known.push_back({1000000000LL + k, e});
    }
    pf->loadMap(known);
  }

  // Motion step + one measurement (+ resampling when due).
  void step() {
    const Pose2 u{0.02, 0, 0.01};
    truth = truth.compose(u);
    pf->predict(u);
    const size_t k = next++ % landmarks.size();
    Pose2 y = predictMeasurement(truth, landmarks[k]);
    y.x += 0.03 * rng.normal();
    y.y += 0.03 * rng.normal();
    y.theta += 0.01 * rng.normal();
    const UpdateReport r =
        pf->update({1000000000LL + static_cast<int64_t>(k), y, Eigen::Matrix3d::Zero()});
    resamplings += r.resampled;
    ++updates;
  }
};

void BM_Update(benchmark::State& state) {
  Setup s(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
          static_cast<int>(state.range(2)));
  for (int i = 0; i < 20; ++i) s.step();  // spread the particles, diversify the maps
  s.resamplings = s.updates = 0;
  for (auto _ : state) s.step();
  state.counters["resampled_fraction"] =
      static_cast<double>(s.resamplings) / static_cast<double>(std::max<int64_t>(1, s.updates));
}
BENCHMARK(BM_Update)
    ->ArgNames({"particles", "landmarks", "threads"})
    ->ArgsProduct({{200, 1000, 10000}, {50, 500, 5000}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_Resample(benchmark::State& state) {
  Setup s(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)), 1);
  for (int i = 0; i < 20; ++i) s.step();
  for (auto _ : state) {
    state.PauseTiming();
    s.step();  // each particle changes one landmark: its own path in the map
    state.ResumeTiming();
    s.pf->resample();
  }
}
BENCHMARK(BM_Resample)
    ->ArgNames({"particles", "landmarks"})
    ->ArgsProduct({{1000, 10000}, {50, 500, 5000, 50000}})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace
