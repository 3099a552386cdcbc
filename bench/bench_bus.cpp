// Cost of the stage framework itself: typed publish + decode + dispatch over
// memq://, and lock-step replay throughput with the dead-reckoning stage.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/bus.hpp"
#include "bus/lockstep_replay.hpp"
#include "stages/deadreckon_stage.hpp"
#include "support/test_logs.hpp"

using namespace vslam;

static void BM_BusRoundTripOdometry(benchmark::State& state) {
  lcm::LCM lcm("memq://");
  WallClock clock;
  bus::Bus bus(lcm, clock, "bench");
  int64_t handled = 0;
  bus.subscribe<vslam::odometry_t>("ODO", [&](const vslam::odometry_t&) { ++handled; });
  vslam::odometry_t m{};
  for (auto _ : state) {
    ++m.seq;
    bus.publish("ODO", m);
    lcm.handleTimeout(0);
  }
  state.SetItemsProcessed(handled);
}
BENCHMARK(BM_BusRoundTripOdometry);

static void BM_BusRoundTripImage(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = w * 3 / 4;
  lcm::LCM lcm("memq://");
  WallClock clock;
  bus::Bus bus(lcm, clock, "bench");
  bus.subscribe<vslam::image_t>(
      "IMG", [&](const vslam::image_t& img) { benchmark::DoNotOptimize(img.data.data()); });
  vslam::image_t img{};
  img.width = w;
  img.height = h;
  img.row_stride = w;
  img.data.assign(static_cast<size_t>(w * h), 7);
  img.data_size = w * h;
  for (auto _ : state) {
    bus.publish("IMG", img);
    lcm.handleTimeout(0);
  }
  state.SetBytesProcessed(state.iterations() * w * h);
}
BENCHMARK(BM_BusRoundTripImage)->Arg(320)->Arg(640);

static void BM_LockstepReplayDeadReckon(benchmark::State& state) {
  const auto dir = vslam::test::scratchDir("bench_replay");
  vslam::test::writeDrivingLog(dir / "in.lcmlog", 60.0, 0.0);  // 3001 odometry + 3001 truth
  int64_t events = 0;
  for (auto _ : state) {
    bus::ReplayOptions opt;
    opt.input = dir / "in.lcmlog";
    opt.output = dir / "out.lcmlog";
    bus::LockstepReplay replay(opt);
    stages::DeadReckonParams p;
    p.noise = {0.05, 0.05};
    p.odometry_channel = "ODOMETRY";
    p.pose_channel = "POSE_ODOMETRY";
    replay.addStage("deadreckon", std::make_unique<stages::DeadReckonStage>(p));
    events += replay.run().events_read;
  }
  state.SetItemsProcessed(events);
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_LockstepReplayDeadReckon)->Unit(benchmark::kMillisecond);
