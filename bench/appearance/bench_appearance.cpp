// One step of the path-hypothesis tree (prediction with tracing, observation,
// update, pruning) against the number of states in the map: 100, 1,000 and
// 10,000. The map is one lap of a rectangular loop of 1 m moves and 90
// degree turns (a state per action, two cameras, 36-bin histograms of their
// own); the robot then starts the second lap, re-localises and is timed on
// the steps after, with the hypothesis bound of config/vslam.yaml (20) and
// its error model. Every sixth place looks alike (70 % of each view is
// shared: perceptual aliasing) and each snapshot is its place's view with
// noise, so the tree stays at its bound.
#include <benchmark/benchmark.h>

#include <map>
#include <opencv2/imgproc.hpp>
#include <random>

#include "appearance/gradient_histogram.hpp"
#include "appearance/path_hypotheses.hpp"

using namespace vslam;
using namespace vslam::appearance;

namespace {

constexpr int kBins = 36;
constexpr int kCameras = 2;

std::vector<Histogram> randomView(std::mt19937& rng) {
  std::gamma_distribution<float> g(1.f, 1.f);
  std::vector<Histogram> v(kCameras, Histogram(kBins));
  for (auto& h : v) {
    float sum = 0;
    for (auto& x : h) sum += (x = g(rng));
    for (auto& x : h) x /= sum;
  }
  return v;
}

std::vector<Histogram> noisy(const std::vector<Histogram>& v, std::mt19937& rng) {
  std::normal_distribution<float> n(1.f, 0.1f);
  std::vector<Histogram> out = v;
  for (auto& h : out) {
    float sum = 0;
    for (auto& x : h) sum += (x = std::max(0.f, x * n(rng)));
    for (auto& x : h) x /= sum;
  }
  return out;
}

struct Setup {
  AppearanceSlam slam;
  std::vector<std::vector<Histogram>> views;  // per place of the lap
  std::string plan;                           // 'F' / 'L' per action of the lap
  int place = 0;                              // where the robot is
};

Pose2 actionOf(char c) { return c == 'F' ? Pose2{1, 0, 0} : Pose2{0, 0, M_PI / 2}; }

SlamParams defaultParams() {
  SlamParams p;  // config/vslam.yaml's appearance block
  p.beta = 1.0;
  p.new_state_ratio = 0.5;
  p.gate = 11.34;
  p.place_sigma_m = 0.25;
  p.place_sigma_rad = 10 * M_PI / 180;
  p.min_belief = 1e-3;
  p.max_hypotheses = 20;
  p.revisit_horizon = 10;
  return p;
}

// A lap of `states` actions: four equal sides, each ending in a left turn.
Setup& setupFor(int states) {
  static std::map<int, std::unique_ptr<Setup>> cache;
  auto& s = cache[states];
  if (s) return *s;
  s.reset(new Setup{AppearanceSlam(defaultParams(), kCameras, kBins), {}, {}, 0});
  ActionErrorModel model;
  model.odometry_translation = model.odometry_rotation = 0.03;
  s->slam.setActionModel(model);
  // A forward and a backward camera, as the simulated robot's: every state
  // is also tried turned around.
  s->slam.setTurnedCameras(
      turnedCameras({{Eigen::Vector3d::UnitX(), 1.0}, {-Eigen::Vector3d::UnitX(), 1.0}}));
  const int side = states / 4;
  for (int i = 0; i < states; ++i) s->plan += (i % side == side - 1) ? 'L' : 'F';
  std::mt19937 rng(7);
  std::vector<std::vector<Histogram>> looks;
  for (int i = 0; i < 6; ++i) looks.push_back(randomView(rng));
  for (int i = 0; i < states; ++i) {
    // 70 % the look shared with every sixth place, 30 % its own.
    std::vector<Histogram> v = randomView(rng);
    for (int c = 0; c < kCameras; ++c) {
      for (int k = 0; k < kBins; ++k) {
        v[c][k] = 0.7f * looks[static_cast<size_t>(i % 6)][c][k] + 0.3f * v[c][k];
      }
    }
    s->views.push_back(std::move(v));
  }
  Snapshot z;
  z.histograms = s->views[0];
  s->slam.initialize(z);
  for (int i = 0; i < states + 3; ++i) {  // the lap, then three steps into the second
    s->place = (i + 1) % states;
    z.histograms = noisy(s->views[static_cast<size_t>(s->place)], rng);
    s->slam.step(actionOf(s->plan[static_cast<size_t>(i % states)]), z);
  }
  return *s;
}

void BM_AppearanceStep(benchmark::State& state) {
  const int states = static_cast<int>(state.range(0));
  Setup& s = setupFor(states);
  std::mt19937 rng(11);
  const int next = (s.place + 1) % states;
  Snapshot z;
  z.histograms = noisy(s.views[static_cast<size_t>(next)], rng);
  const Pose2 action = actionOf(s.plan[static_cast<size_t>(s.place)]);
  double hypotheses = 0, children = 0, candidates = 0;
  for (auto _ : state) {
    state.PauseTiming();
    AppearanceSlam slam = s.slam;  // the same step every iteration
    state.ResumeTiming();
    const StepResult r = slam.step(action, z);
    benchmark::DoNotOptimize(r.hypotheses.data());
    hypotheses = static_cast<double>(r.hypotheses.size());
    children = r.children;
    candidates = r.revisit_candidates;
  }
  state.counters["states"] = static_cast<double>(s.slam.best().node->num_states);
  state.counters["hypotheses_in"] = static_cast<double>(s.slam.hypotheses().size());
  state.counters["hypotheses_out"] = hypotheses;
  state.counters["children"] = children;
  state.counters["candidates"] = candidates;
}

}  // namespace

// The gradient-orientation histogram of one 320x240 frame (a snapshot costs
// one per camera).
void BM_GradientHistogram(benchmark::State& state) {
  cv::Mat img(240, 320, CV_8UC1);
  cv::RNG rng(5);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  for (auto _ : state) {
    const Histogram h = gradientHistogram(img, HistogramParams{36, 20.0});
    benchmark::DoNotOptimize(h.data());
  }
}

BENCHMARK(BM_GradientHistogram)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AppearanceStep)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);
