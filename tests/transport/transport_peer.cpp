// vslam-transport-peer: the publishing side of the transport tests, run as a
// separate process (inside the test's private network namespace).
//
//   vslam-transport-peer mixed  URL ROUNDS HZ      every vslam type, ROUNDS times
//   vslam-transport-peer drive  URL N HZ           N odometry_t of a straight 1 m drive on ODOMETRY
//   vslam-transport-peer images URL N HZ W H CHAN  N gray8 W x H image_t with a per-frame pattern
//   vslam-transport-peer run    URL                the record/replay run (odometry, ground truth,
//   images)
//
// Every mode first waits for the test's ACK to its HELLO (see peer_protocol.hpp),
// publishes at a fixed rate against absolute deadlines, then publishes DONE.
// Exit codes: 0 done, 2 usage or LCM error, 3 no handshake.

#include <sys/prctl.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <thread>
#include <vector>

#include "peer_protocol.hpp"

namespace tt = vslam::transport_test;
using Clock = std::chrono::steady_clock;

namespace {

struct AckWaiter {
  std::string token;
  bool acked = false;
  // A plain function, not a member: see TestBus::Handler (process_harness.hpp).
  static void onAck(const lcm::ReceiveBuffer* rbuf, const std::string&, AckWaiter* self) {
    if (std::string(static_cast<const char*>(rbuf->data), rbuf->data_size) == self->token) {
      self->acked = true;
    }
  }
};

bool handshake(lcm::LCM& lcm, double timeout_s) {
  AckWaiter waiter;
  waiter.token = "hello-" + std::to_string(getpid());
  lcm::Subscription* sub = lcm.subscribeFunction(tt::kAckChannel, &AckWaiter::onAck, &waiter);
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (!waiter.acked && Clock::now() < deadline) {
    lcm.publish(tt::kHelloChannel, waiter.token.data(), static_cast<unsigned>(waiter.token.size()));
    const auto until = Clock::now() + std::chrono::milliseconds(20);
    while (!waiter.acked && Clock::now() < until) lcm.handleTimeout(5);
  }
  lcm.unsubscribe(sub);
  return waiter.acked;
}

// Publishes `msgs` with slot k at start + k / hz.
int publishPaced(lcm::LCM& lcm, const std::vector<tt::Outgoing>& msgs, double hz) {
  const auto start = Clock::now();
  int published = 0;
  for (const auto& m : msgs) {
    std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                              std::chrono::duration<double>(m.tick / hz)));
    if (lcm.publish(m.channel, m.bytes.data(), static_cast<unsigned>(m.bytes.size())) == 0) {
      ++published;
    } else {
      std::fprintf(stderr, "vslam-transport-peer: publish on %s failed\n", m.channel.c_str());
    }
  }
  return published;
}

int usage() {
  std::fprintf(stderr,
               "usage: vslam-transport-peer mixed URL ROUNDS HZ | drive URL N HZ | "
               "images URL N HZ W H CHANNEL | run URL\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // Never outlive the test that started us.
  prctl(PR_SET_PDEATHSIG, SIGKILL);
  if (argc < 3) return usage();
  const std::string mode = argv[1];
  const std::string url = argv[2];
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "vslam-transport-peer: cannot open LCM at %s\n", url.c_str());
    return 2;
  }
  if (!handshake(lcm, 10.0)) {
    std::fprintf(stderr, "vslam-transport-peer: no ACK to HELLO within 10 s\n");
    return 3;
  }

  int published = 0;
  if (mode == "mixed" && argc == 5) {
    published = publishPaced(lcm, tt::mixedSequence(std::atoi(argv[3])), std::atof(argv[4]));
  } else if (mode == "drive" && argc == 5) {
    const int n = std::atoi(argv[3]);
    const double hz = std::atof(argv[4]);
    std::vector<tt::Outgoing> msgs;
    for (int i = 0; i < n; ++i) {
      msgs.push_back({"ODOMETRY", tt::encodeToBytes(tt::straightDriveOdometry(i, n, hz)), i});
    }
    published = publishPaced(lcm, msgs, hz);
  } else if (mode == "images" && argc == 8) {
    const int n = std::atoi(argv[3]);
    const double hz = std::atof(argv[4]);
    const int w = std::atoi(argv[5]);
    const int h = std::atoi(argv[6]);
    const std::string channel = argv[7];
    // Frames are generated just in time (300 x 307 KB would be 92 MB up front).
    vslam::image_t img;
    std::vector<uint8_t> buffer;
    const auto start = Clock::now();
    for (int i = 0; i < n; ++i) {
      tt::fillPatternImage(img, i, w, h, tt::kDriveStartUtime + static_cast<int64_t>(i * 1e6 / hz),
                           "transport_test");
      buffer.resize(static_cast<size_t>(img.getEncodedSize()));
      img.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
      std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                                std::chrono::duration<double>(i / hz)));
      if (lcm.publish(channel, buffer.data(), static_cast<unsigned>(buffer.size())) == 0)
        ++published;
    }
  } else if (mode == "run" && argc == 3) {
    published = publishPaced(lcm, tt::recordRunSequence(), tt::kRunHz);
  } else {
    return usage();
  }

  const std::string done = std::to_string(published);
  lcm.publish(tt::kDoneChannel, done.data(), static_cast<unsigned>(done.size()));
  return 0;
}
