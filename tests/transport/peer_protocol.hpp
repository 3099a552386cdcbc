#pragma once
// What the transport tests and their peer process (vslam-transport-peer) agree
// on: handshake channels, and the deterministic message sequences a peer
// publishes and a test expects, so that the receiving side can check every
// byte without the sender telling it what it sent.

#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "message_fill.hpp"

namespace vslam::transport_test {

// The peer publishes HELLO (payload: a token) until the test answers with ACK
// carrying the same token, so no message of the measured stream is sent before
// both sides' multicast sockets are up. DONE (payload: the number of messages
// published) follows the last message of the stream.
inline constexpr const char* kHelloChannel = "TRANSPORT_TEST_HELLO";
inline constexpr const char* kAckChannel = "TRANSPORT_TEST_ACK";
inline constexpr const char* kDoneChannel = "TRANSPORT_TEST_DONE";
// Published by the record test until lcm-logger has written one to its file.
inline constexpr const char* kSyncChannel = "TRANSPORT_TEST_SYNC";

struct Outgoing {
  std::string channel;
  std::vector<uint8_t> bytes;
  int tick = 0;  // publication slot: the publisher sends slot k at start + k / rate
};

// ---- mixed: every vslam type, several rounds -------------------------------

inline std::string mixedChannel(const std::string& type_name) { return "TEST_" + type_name; }

inline std::vector<Outgoing> mixedSequence(int rounds) {
  std::vector<Outgoing> out;
  int tick = 0;
  for (int r = 0; r < rounds; ++r) {
    int k = 0;
    forEachType(AllTypes{}, [&](auto tag) {
      using T = typename decltype(tag)::type;
      out.push_back(
          {mixedChannel(T::getTypeName()), encodeToBytes(filled<T>(r * 100 + k)), tick++});
      ++k;
    });
  }
  return out;
}

// ---- drive: odometry of a straight 1 m drive along +x -----------------------

inline constexpr int64_t kDriveStartUtime = 1700000000000000LL;

// Reading i of n (i = 0..n-1): x goes from 0 to exactly 1 m.
inline vslam::odometry_t straightDriveOdometry(int i, int n, double hz) {
  vslam::odometry_t m;
  m.utime = kDriveStartUtime + static_cast<int64_t>(i * 1e6 / hz);
  m.seq = i;
  m.x = static_cast<double>(i) / (n - 1);
  m.y = 0.0;
  m.theta = 0.0;
  m.distance = m.x;
  m.rotation = 0.0;
  m.v = i == 0 || i == n - 1 ? 0.0 : hz / (n - 1);
  m.omega = 0.0;
  return m;
}

// ---- images: gray8 frames with a per-frame pattern ---------------------------

inline uint8_t patternPixel(int64_t seq, int row, int col) {
  return static_cast<uint8_t>(seq * 37 + row * 7 + col * 13 + ((row * col) >> 4));
}

inline void fillPatternImage(vslam::image_t& m, int64_t seq, int width, int height, int64_t utime,
                             const std::string& camera) {
  m.utime = utime;
  m.seq = seq;
  m.camera = camera;
  m.width = width;
  m.height = height;
  m.row_stride = width;
  m.encoding = vslam::image_t::ENCODING_GRAY8;
  m.exposure = 1.0f;
  m.data_size = width * height;
  m.data.resize(static_cast<size_t>(m.data_size));
  for (int r = 0; r < height; ++r) {
    uint8_t* row = m.data.data() + static_cast<size_t>(r) * static_cast<size_t>(width);
    for (int c = 0; c < width; ++c) row[c] = patternPixel(seq, r, c);
  }
}

// True if the frame carries exactly the pattern of `seq`.
inline bool hasPattern(const vslam::image_t& m, int64_t seq, int width, int height) {
  if (m.seq != seq || m.width != width || m.height != height || m.row_stride != width ||
      m.encoding != vslam::image_t::ENCODING_GRAY8 || m.data_size != width * height ||
      m.data.size() != static_cast<size_t>(width) * static_cast<size_t>(height)) {
    return false;
  }
  for (int r = 0; r < height; ++r) {
    const uint8_t* row = m.data.data() + static_cast<size_t>(r) * static_cast<size_t>(width);
    for (int c = 0; c < width; ++c) {
      if (row[c] != patternPixel(seq, r, c)) return false;
    }
  }
  return true;
}

// ---- run: a short robot run as the stack would record it ---------------------
// 50 ticks at 30 Hz: odometry and ground truth every tick, a 320x240 gray8
// forward camera frame every 5th tick (10 frames).

inline constexpr int kRunTicks = 50;
inline constexpr double kRunHz = 30.0;
inline constexpr int kRunImageEvery = 5;
inline constexpr int kRunImageWidth = 320;
inline constexpr int kRunImageHeight = 240;

inline std::vector<Outgoing> recordRunSequence() {
  std::vector<Outgoing> out;
  for (int i = 0; i < kRunTicks; ++i) {
    const int64_t utime = kDriveStartUtime + static_cast<int64_t>(i * 1e6 / kRunHz);
    vslam::odometry_t odo = straightDriveOdometry(i, kRunTicks, kRunHz);
    out.push_back({"ODOMETRY", encodeToBytes(odo), i});
    vslam::ground_truth_pose_t gt;
    gt.utime = utime;
    gt.seq = i;
    gt.x = odo.x + 0.001 * i;
    gt.y = -0.0005 * i;
    gt.z = 0.0;
    gt.theta = 0.0001 * i;
    out.push_back({"GROUND_TRUTH", encodeToBytes(gt), i});
    if (i % kRunImageEvery == 0) {
      vslam::image_t img;
      fillPatternImage(img, i / kRunImageEvery, kRunImageWidth, kRunImageHeight, utime, "forward");
      out.push_back({"CAM_FORWARD_IMAGE", encodeToBytes(img), i});
    }
  }
  return out;
}

}  // namespace vslam::transport_test
