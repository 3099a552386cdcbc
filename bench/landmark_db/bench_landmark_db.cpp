// Where recognition should run (docs/landmark-db.md, "Recognition: replica
// or server"): the cost on loopback UDP multicast of
//   - BM_ServerQuery: recognition in the DB process. Every frame's features
//     (num descriptors x 128 bytes, keypoints, scales, orientations) go to the
//     DB and a small answer comes back: bytes and round-trip time per frame,
//     without the matching itself (which costs the same in either place).
//   - BM_ReplicaUpdate: recognition in each front-end over a replica. Each
//     landmark (num points) goes once from the DB to the front-end, which
//     decodes it and adds it to its recognition index: bytes and time per
//     landmark.
// Needs a multicast route (ip route add 224.0.0.0/4 dev lo), e.g. in a private
// network namespace: unshare -rn sh -c 'ip link set lo up; ip link set lo
// multicast on; ip route add 224.0.0.0/4 dev lo; build-db/bin/bench_landmark_db'
#include <benchmark/benchmark.h>

#include <atomic>
#include <lcm/lcm-cpp.hpp>
#include <random>
#include <thread>
#include <vslam/landmark_request_t.hpp>
#include <vslam/landmark_update_t.hpp>

#include "frontend/landmark_index.hpp"

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7668?ttl=0&recv_buf_size=8388608";

vslam::landmark_t features(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_real_distribution<float> u(-1, 1);
  vslam::landmark_t l{};
  l.landmark_id = seed;
  l.camera = "forward";
  l.num_points = n;
  l.descriptor_size = 128;
  l.points.assign(static_cast<size_t>(n), {0, 0, 0});
  l.keypoints.assign(static_cast<size_t>(n), {0, 0});
  l.scales.assign(static_cast<size_t>(n), 2);
  l.orientations.assign(static_cast<size_t>(n), 0);
  l.descriptors.assign(static_cast<size_t>(n), std::vector<uint8_t>(128));
  for (int i = 0; i < n; ++i) {
    auto& p = l.points[static_cast<size_t>(i)];
    p = {2 + u(rng), u(rng), 0.5f + u(rng)};
    for (auto& d : l.descriptors[static_cast<size_t>(i)]) d = static_cast<uint8_t>(byte(rng));
  }
  return l;
}

// The far side: answers every message on REQ with a small message on ACK,
// after `work` on the received one.
class Peer {
 public:
  explicit Peer(std::function<void(const vslam::landmark_update_t&)> work)
      : work_(std::move(work)), lcm_(kUrl), thread_([this] { run(); }) {}
  ~Peer() {
    stop_ = true;
    thread_.join();
  }
  bool good() { return lcm_.good(); }

 private:
  static void onReq(const lcm::ReceiveBuffer* rbuf, const std::string&, Peer* self) {
    vslam::landmark_update_t m;
    if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
    self->work_(m);
    vslam::landmark_request_t ack{};
    ack.requester = "peer";
    ack.num_ids = 4;  // e.g. the recognized landmarks of a frame
    ack.landmark_ids = {1, 2, 3, 4};
    self->lcm_.publish("BENCH_ACK", &ack);
  }
  void run() {
    lcm_.subscribeFunction("BENCH_REQ", &Peer::onReq, this);
    while (!stop_) lcm_.handleTimeout(20);
  }
  std::function<void(const vslam::landmark_update_t&)> work_;
  lcm::LCM lcm_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct Client {
  lcm::LCM lcm{kUrl};
  int acks = 0;
  Client() { lcm.subscribeFunction("BENCH_ACK", &Client::onAck, this); }
  static void onAck(const lcm::ReceiveBuffer*, const std::string&, Client* self) { ++self->acks; }
  bool roundTrip(const vslam::landmark_update_t& m) {
    const int before = acks;
    lcm.publish("BENCH_REQ", &m);
    while (acks == before) {
      if (lcm.handleTimeout(1000) <= 0) return false;
    }
    return true;
  }
};

void BM_ServerQuery(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  Peer peer([](const vslam::landmark_update_t&) {});
  Client client;
  if (!peer.good() || !client.lcm.good()) {
    state.SkipWithError("no LCM (multicast route?)");
    return;
  }
  vslam::landmark_update_t m{};
  m.op = vslam::landmark_update_t::OP_SNAPSHOT;
  m.landmark = features(n, 1);
  for (auto _ : state) {
    if (!client.roundTrip(m)) {
      state.SkipWithError("lost a message");
      return;
    }
  }
  state.counters["bytes_per_query"] = m.getEncodedSize();
}
BENCHMARK(BM_ServerQuery)
    ->Arg(300)
    ->Arg(600)
    ->Arg(1200)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_ReplicaUpdate(benchmark::State& state) {
  const int points = static_cast<int>(state.range(0));
  vslam::frontend::LandmarkIndex index;
  int64_t next = 1;
  Peer peer([&](const vslam::landmark_update_t& m) {
    const vslam::landmark_t& l = m.landmark;
    vslam::frontend::LandmarkModel model;
    model.id = next++;
    model.descriptors.create(l.num_points, 128, CV_32F);
    for (int i = 0; i < l.num_points; ++i) {
      const auto& p = l.points[static_cast<size_t>(i)];
      model.points_robot.emplace_back(p[0], p[1], p[2]);
      for (int c = 0; c < 128; ++c) {
        model.descriptors.at<float>(i, c) =
            l.descriptors[static_cast<size_t>(i)][static_cast<size_t>(c)];
      }
    }
    index.add(std::move(model));
  });
  Client client;
  if (!peer.good() || !client.lcm.good()) {
    state.SkipWithError("no LCM (multicast route?)");
    return;
  }
  vslam::landmark_update_t m{};
  m.op = vslam::landmark_update_t::OP_CREATED;
  m.landmark = features(points, 2);
  for (auto _ : state) {
    if (!client.roundTrip(m)) {
      state.SkipWithError("lost a message");
      return;
    }
  }
  state.counters["bytes_per_landmark"] = m.getEncodedSize();
}
BENCHMARK(BM_ReplicaUpdate)
    ->Arg(100)
    ->Arg(200)
    ->Arg(400)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
