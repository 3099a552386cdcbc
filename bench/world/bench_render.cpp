// Software renderer speed: one frame (gray or colour) of the shipped worlds
// at 320x240 and 640x480 with the simulated camera's distortion, cycling
// through the poses along each world's route (heading to the next waypoint,
// camera 0.3 m above the floor). Single-threaded. Figures in
// docs/world-format.md ("Rendering speed").
//
//   build/bin/bench_render [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "world/renderer.hpp"
#include "world/world.hpp"

using namespace vslam::world;
namespace fs = std::filesystem;

namespace {

const fs::path kWorlds = fs::path(VSLAM_SOURCE_DIR) / "config/worlds";
const char* const kWorldNames[] = {"apartment", "living_room", "loop"};

const World& world(int index) {
  static std::map<int, std::unique_ptr<World>> cache;
  auto& w = cache[index];
  if (!w)
    w = std::make_unique<World>(
        World::loadFile(kWorlds / (std::string(kWorldNames[index]) + ".yaml")));
  return *w;
}

// The simulated camera (config/calib/sim_320x240.yml), scaled for 640x480.
CameraModel camera(int width) {
  const double s = width / 320.0;
  return CameraModel{width,
                     width * 3 / 4,
                     277.13 * s,
                     277.13 * s,
                     160.0 * s,
                     120.0 * s,
                     {-0.05, 0.01, 0.0, 0.0, 0.0}};
}

// Poses along the world's first route, looking where the robot drives.
std::vector<Eigen::Isometry3d> routePoses(const World& w) {
  std::vector<Eigen::Isometry3d> poses;
  const auto& wp = w.routes.at(0).waypoints;
  for (size_t i = 0; i < wp.size(); ++i) {
    const Eigen::Vector2d a = wp[i], b = wp[(i + 1) % wp.size()];
    const double yaw = std::atan2(b.y() - a.y(), b.x() - a.x());
    for (double s : {0.0, 0.5}) {
      const Eigen::Vector2d p = a + s * (b - a);
      poses.push_back(levelCameraPose({p.x(), p.y(), 0.3}, yaw));
    }
  }
  return poses;
}

void BM_Render(benchmark::State& state) {
  const World& w = world(static_cast<int>(state.range(0)));
  const int width = static_cast<int>(state.range(1));
  const bool color = state.range(2) != 0;
  Renderer r(w, camera(width));
  const auto poses = routePoses(w);
  RenderEffects fx;
  fx.noise_sigma = 2.0;
  cv::Mat out;
  size_t i = 0;
  for (auto _ : state) {
    fx.noise_seed = i;
    r.render(poses[i++ % poses.size()], {}, fx, color, out);
    benchmark::DoNotOptimize(out.data);
  }
  state.SetLabel(std::string(kWorldNames[state.range(0)]) + " " + std::to_string(width) + "x" +
                 std::to_string(width * 3 / 4) + (color ? " bgr" : " gray") + ", " +
                 std::to_string(poses.size()) + " poses");
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Render)
    ->ArgNames({"world", "width", "color"})
    ->ArgsProduct({{0, 1, 2}, {320, 640}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

// Motion blur with 4 samples across the exposure (apartment, 320x240 gray).
void BM_RenderBlurred4(benchmark::State& state) {
  const World& w = world(0);
  Renderer r(w, camera(320));
  const auto poses = routePoses(w);
  cv::Mat out;
  size_t i = 0;
  for (auto _ : state) {
    const Eigen::Isometry3d& p = poses[i++ % poses.size()];
    std::vector<Eigen::Isometry3d> samples;
    for (int k = 0; k < 4; ++k) {
      Eigen::Isometry3d s = p;
      s.translation() += p.linear().col(2) * 0.01 * k;
      samples.push_back(s);
    }
    r.renderBlurred(samples, {}, {}, false, out);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_RenderBlurred4)->Unit(benchmark::kMillisecond);

// One-off cost per camera: texture pyramids and the distortion map.
void BM_RendererConstruct(benchmark::State& state) {
  const World& w = world(0);
  for (auto _ : state) {
    Renderer r(w, camera(static_cast<int>(state.range(0))));
    benchmark::DoNotOptimize(&r);
  }
}
BENCHMARK(BM_RendererConstruct)->Arg(320)->Arg(640)->Unit(benchmark::kMillisecond);

// Loading the apartment world file (YAML, textures from disk).
void BM_LoadApartment(benchmark::State& state) {
  for (auto _ : state) {
    World w = World::loadFile(kWorlds / "apartment.yaml");
    benchmark::DoNotOptimize(w.surfaces.data());
  }
}
BENCHMARK(BM_LoadApartment)->Unit(benchmark::kMillisecond);

}  // namespace
