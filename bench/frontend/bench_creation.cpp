// Landmark creation speed on rendered simulator frames (realistic texture):
// SIFT extraction per frame at 320x240 and 640x480 (with and without the
// doubled first octave: SiftParams::double_first_octave), ratio-test matching of
// two frames, and the whole three-view creation (matching, two-view
// geometry, bundle adjustment) on triples of views 20 cm apart along the
// apartment's route. OpenCV threads as given by the `threads` argument
// (1 = one core). Figures in docs/frontend.md ("Landmark creation").
//
//   build/bin/bench_creation [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/matching.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace {

namespace fs = std::filesystem;
using namespace vslam;
using namespace vslam::frontend;

const fs::path kSource = VSLAM_SOURCE_DIR;

const world::World& apartment() {
  static const world::World w = world::World::loadFile(kSource / "config/worlds/apartment.yaml");
  return w;
}

// The simulated camera (config/calib/sim_320x240.yml), scaled to `width`.
config::CameraIntrinsics intrinsics(int width) {
  config::CameraIntrinsics in =
      config::readOpenCvCalibration(kSource / "config/calib/sim_320x240.yml");
  const double s = width / static_cast<double>(in.width);
  in.width = width;
  in.height = static_cast<int>(std::lround(in.height * s));
  in.fx *= s;
  in.fy *= s;
  in.cx *= s;
  in.cy *= s;
  return in;
}

Eigen::Isometry3d robotTCamera() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = config::robotRotationCamera(0, 0, 0);
  t.translation() = Eigen::Vector3d(0.1, 0, 0.3);
  return t;
}

// Robot poses at the route's waypoints heading to the next one, and the
// world's start.
std::vector<Pose2> startPoses() {
  const world::World& w = apartment();
  std::vector<Pose2> poses{{w.start.x(), w.start.y(), w.start.z()}};
  const auto& wp = w.routes.at(0).waypoints;
  for (size_t i = 0; i + 1 < wp.size(); ++i) {
    const Eigen::Vector2d d = wp[i + 1] - wp[i];
    poses.push_back({wp[i].x(), wp[i].y(), std::atan2(d.y(), d.x())});
  }
  return poses;
}

// Three views 20 cm apart from each start pose: images and odometry.
struct Triple {
  cv::Mat images[3];
  std::array<Pose2, 3> odometry;
};

std::vector<Triple> renderTriples(int width) {
  const config::CameraIntrinsics in = intrinsics(width);
  world::Renderer renderer(apartment(), world::CameraModel{in.width, in.height, in.fx, in.fy, in.cx,
                                                           in.cy, in.distortion});
  std::vector<Triple> triples;
  for (const Pose2& start : startPoses()) {
    Triple t;
    for (int k = 0; k < 3; ++k) {
      t.odometry[k] = start.compose(Pose2{0.2 * k, 0, 0});
      renderer.render(isometryFromPose2(t.odometry[k]) * robotTCamera(), {}, {}, false,
                      t.images[k]);
      t.images[k] = t.images[k].clone();
    }
    triples.push_back(std::move(t));
  }
  return triples;
}

const std::vector<Triple>& triples(int width) {
  static std::vector<Triple> t320 = renderTriples(320), t640 = renderTriples(640);
  return width == 320 ? t320 : t640;
}

void BM_Sift(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  cv::setNumThreads(static_cast<int>(state.range(1)));
  const auto& views = triples(width);
  SiftParams sift;
  sift.double_first_octave = state.range(2) != 0;
  FeatureExtractor extractor(intrinsics(width), sift);
  Features features;
  size_t i = 0, total = 0;
  for (auto _ : state) {
    const Triple& t = views[(i / 3) % views.size()];
    extractor.extract(t.images[i % 3], &features);
    total += features.size();
    ++i;
  }
  state.counters["features"] = static_cast<double>(total) / static_cast<double>(i);
  state.SetLabel(std::to_string(width) + "x" + std::to_string(width * 3 / 4) + ", " +
                 std::to_string(views.size() * 3) + " frames");
}
BENCHMARK(BM_Sift)
    ->ArgNames({"width", "threads", "double_first_octave"})
    ->ArgsProduct({{320, 640}, {1, 2}, {1, 0}})
    ->Unit(benchmark::kMillisecond);

std::vector<std::array<Features, 3>> extractAll(int width) {
  FeatureExtractor extractor(intrinsics(width));
  std::vector<std::array<Features, 3>> all;
  for (const Triple& t : triples(width)) {
    std::array<Features, 3> f;
    for (int k = 0; k < 3; ++k) extractor.extract(t.images[k], &f[k]);
    all.push_back(std::move(f));
  }
  return all;
}

// Ratio-test matching of two consecutive views (one of the three pairs).
void BM_MatchPair(benchmark::State& state) {
  const auto all = extractAll(320);
  RatioMatcher matcher;
  std::vector<cv::DMatch> matches;
  size_t i = 0, total = 0;
  for (auto _ : state) {
    const auto& f = all[i++ % all.size()];
    matcher.match(f[0].descriptors, f[1].descriptors, &matches);
    total += matches.size();
  }
  state.counters["matches"] = static_cast<double>(total) / static_cast<double>(i);
}
BENCHMARK(BM_MatchPair)->Unit(benchmark::kMillisecond);

// The whole creation from three views' features (SIFT not included).
void BM_Creation(benchmark::State& state) {
  const int width = static_cast<int>(state.range(0));
  cv::setNumThreads(1);
  const auto all = extractAll(width);
  const config::CameraIntrinsics in = intrinsics(width);
  LandmarkCreator creator(0.5 * (in.fx + in.fy), robotTCamera());
  size_t i = 0, ok = 0, points = 0, three_way = 0;
  double ms_matching = 0, ms_two_view = 0, ms_ba = 0;
  for (auto _ : state) {
    const size_t k = i++ % all.size();
    const CreationResult r =
        creator.create(all[k][0], all[k][1], all[k][2], triples(width)[k].odometry);
    ok += r.ok();
    points += r.landmark.points_robot.size();
    three_way += static_cast<size_t>(r.diagnostics.num_three_way);
    ms_matching += r.diagnostics.ms_matching;
    ms_two_view += r.diagnostics.ms_two_view;
    ms_ba += r.diagnostics.ms_bundle_adjustment;
  }
  const double n = static_cast<double>(i);
  state.counters["created_%"] = 100.0 * static_cast<double>(ok) / n;
  state.counters["points"] =
      static_cast<double>(points) / static_cast<double>(std::max<size_t>(ok, 1));
  state.counters["three_way"] = static_cast<double>(three_way) / n;
  state.counters["ms_match"] = ms_matching / n;
  state.counters["ms_2view"] = ms_two_view / n;
  state.counters["ms_ba"] = ms_ba / n;
  state.SetLabel(std::to_string(all.size()) + " triples along the apartment route");
}
BENCHMARK(BM_Creation)->ArgNames({"width"})->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond);

}  // namespace
