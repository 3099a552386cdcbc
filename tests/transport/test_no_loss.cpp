// Camera-sized messages between processes at the stack's default LCM URL:
// 10 s of 30 Hz 640x480 gray8 frames (300 x 307 KB) must all arrive, in order,
// intact. The same stream with the kernel's default socket buffer (the URL
// without recv_buf_size) is measured and printed, not asserted.
// Each run is in its own fresh network namespace.

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>
#include <vslam/image_t.hpp>

#include "config/stack_config.hpp"
#include "peer_protocol.hpp"
#include "process_harness.hpp"

namespace tt = vslam::transport_test;

namespace {

constexpr int kFrames = 300;
constexpr double kHz = 30.0;
constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr const char* kChannel = "CAM_TEST_IMAGE";

struct StreamResult {
  int received = 0;
  int intact = 0;        // carried exactly the pattern of their seq
  int out_of_order = 0;  // seq not above the previous one
  int undecodable = 0;
  std::vector<int64_t> seqs;
  int peer_published = -1;  // from the peer's DONE
  bool peer_ok = false;
  std::string peer_status;
};

// Runs the image peer against `url` and checks every frame as it arrives.
StreamResult streamFrames(const std::string& url) {
  StreamResult r;
  tt::TestBus bus(url);
  if (!bus.good()) {
    ADD_FAILURE() << "cannot open LCM at " << url;
    return r;
  }
  vslam::image_t frame;  // reused: keeps its 307 KB buffer
  int64_t last_seq = -1;
  // A deep LCM queue: this test is about the socket, not the application's
  // queue policy (the check below takes ~1 ms per frame anyway).
  bus.subscribe(
      kChannel,
      [&](const std::string&, const uint8_t* data, size_t size) {
        ++r.received;
        if (frame.decode(data, 0, static_cast<int>(size)) != static_cast<int>(size)) {
          ++r.undecodable;
          return;
        }
        r.seqs.push_back(frame.seq);
        if (frame.seq <= last_seq) ++r.out_of_order;
        last_seq = frame.seq;
        if (tt::hasPattern(frame, frame.seq, kWidth, kHeight) &&
            frame.utime == tt::kDriveStartUtime + static_cast<int64_t>(frame.seq * 1e6 / kHz)) {
          ++r.intact;
        }
      },
      kFrames);

  tt::Child peer = tt::Child::spawn({VSLAM_TRANSPORT_PEER, "images", url, std::to_string(kFrames),
                                     std::to_string(kHz), std::to_string(kWidth),
                                     std::to_string(kHeight), kChannel});
  const auto status = tt::spinUntilPeerDone(bus, peer, kFrames / kHz + 20.0);
  r.peer_ok = tt::exitedWith(status, 0);
  r.peer_status = status ? tt::describeStatus(*status) : "did not finish";
  if (!bus.doneCounts().empty()) r.peer_published = bus.doneCounts().back();
  return r;
}

class NoLoss : public tt::NetnsTest {};

TEST_F(NoLoss, DefaultUrlCarries30HzVgaFramesWithoutLoss) {
  VSLAM_IN_FRESH_NETNS();
  const std::string url = vslam::config::kDefaultLcmUrl;
  ASSERT_NE(url.find("recv_buf_size="), std::string::npos) << url;
  const StreamResult r = streamFrames(url);
  ASSERT_TRUE(r.peer_ok) << "image publisher " << r.peer_status;
  EXPECT_EQ(r.peer_published, kFrames) << "frames the publisher sent";
  std::printf("[ no loss ] %s: %d/%d frames received, %d intact\n", url.c_str(), r.received,
              kFrames, r.intact);
  RecordProperty("frames_received", r.received);
  EXPECT_EQ(r.received, kFrames);
  EXPECT_EQ(r.undecodable, 0);
  EXPECT_EQ(r.out_of_order, 0);
  EXPECT_EQ(r.intact, r.received) << "frames whose pixels or header differ from what was sent";
  // In order and none missing: exactly 0, 1, ..., 299.
  std::vector<int64_t> expected(kFrames);
  for (int i = 0; i < kFrames; ++i) expected[static_cast<size_t>(i)] = i;
  EXPECT_EQ(r.seqs, expected);
}

TEST_F(NoLoss, KernelDefaultBufferLossIsReported) {
  VSLAM_IN_FRESH_NETNS();
  // The default URL minus its receive buffer option: the kernel's default
  // socket buffer (net.core.rmem_default). Informational only.
  std::string url = vslam::config::kDefaultLcmUrl;
  const auto opt = url.find("&recv_buf_size=");
  ASSERT_NE(opt, std::string::npos) << url;
  url.erase(opt, url.find('&', opt + 1) == std::string::npos ? std::string::npos
                                                             : url.find('&', opt + 1) - opt);
  ASSERT_EQ(url.find("recv_buf_size"), std::string::npos) << url;
  const StreamResult r = streamFrames(url);
  ASSERT_TRUE(r.peer_ok) << "image publisher " << r.peer_status;
  const int lost = kFrames - r.received;
  std::printf(
      "[ kernel default buffer ] %s: %d/%d frames received, %d lost (%.1f %%), "
      "%d out of order, %d with wrong content (not asserted)\n",
      url.c_str(), r.received, kFrames, lost, 100.0 * lost / kFrames, r.out_of_order,
      r.received - r.intact - r.undecodable);
  RecordProperty("frames_received", r.received);
  RecordProperty("frames_lost", lost);
  // What does arrive is still whole and correct (LCM drops incomplete messages).
  EXPECT_EQ(r.undecodable, 0);
  EXPECT_EQ(r.intact, r.received);
}

}  // namespace
