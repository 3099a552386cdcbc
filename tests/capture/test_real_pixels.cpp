// Real pixels end to end: OpenCV's own recorded video (vtest.avi, Debian
// opencv-doc: 795 frames of people walking, 768x576 at 10 fps) through the
// capture library, resized to 256x192 with the intrinsics rescaled, into the
// front-end's SIFT extractor: every frame decodes, times rise by the frame
// period, sequence numbers are consecutive, and SIFT finds features in every
// frame.
#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>
#include <opencv2/imgproc.hpp>

#include "capture/camera.hpp"
#include "capture/intrinsics_scale.hpp"
#include "frontend/features.hpp"

namespace {

using namespace vslam;

constexpr const char* kVideo = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";

TEST(RealPixels, OpenCvSampleVideoThroughCaptureIntoSift) {
  if (!std::filesystem::exists(kVideo)) {
    GTEST_SKIP() << kVideo << " is missing: install opencv-doc (scripts/setup does)";
  }
  const capture::SourceSpec spec = capture::SourceSpec::parse(std::string("video:") + kVideo);
  auto source = capture::openSource(spec);
  ASSERT_EQ(source->nativeSize(), cv::Size(768, 576));
  ASSERT_NEAR(source->nominalFps(), 10.0, 1e-6);

  capture::CameraParams params;
  params.speed = 0;  // as fast as it decodes
  params.width = 256;
  params.height = 192;
  capture::Camera camera(
      std::move(source), [spec] { return capture::openSource(spec); }, params);

  // A plausible calibration at the recorded size (a 60 degree lens), rescaled as the frames are.
  config::CameraConfig native;
  native.name = "vtest";
  native.width = 768;
  native.height = 576;
  native.fx = native.fy = 665;
  native.cx = 383.5;
  native.cy = 287.5;
  native.distortion = {0, 0, 0, 0};
  const config::CameraConfig scaled = capture::rescaleIntrinsics(native, 256, 192);
  frontend::FeatureExtractor extractor(scaled);

  frontend::Features features;
  capture::Frame frame;
  std::vector<capture::Frame> frames;
  size_t fewest = SIZE_MAX;
  int64_t last_utime = 0;
  for (int calls = 0; calls < 2000 && camera.state() == capture::SourceState::kOpen; ++calls) {
    if (camera.next(&frame, 0.5) != capture::Camera::Result::kFrame) continue;
    ASSERT_EQ(frame.image.size(), cv::Size(256, 192));
    ASSERT_EQ(frame.seq, static_cast<int64_t>(frames.size()));
    if (!frames.empty()) {
      ASSERT_GT(frame.utime, last_utime);
      EXPECT_NEAR(frame.utime - last_utime, 100000, 1000) << "frame " << frame.seq;
    }
    last_utime = frame.utime;
    cv::Mat gray;
    cv::cvtColor(frame.image, gray, cv::COLOR_BGR2GRAY);
    extractor.extract(gray, &features);
    EXPECT_GE(features.size(), 50u) << "frame " << frame.seq;
    fewest = std::min(fewest, features.size());
    frames.push_back({cv::Mat(), frame.utime, frame.seq, frame.source_index});
  }
  // All 795 frames, then the end of the file is reported.
  EXPECT_EQ(frames.size(), 795u);
  EXPECT_EQ(camera.state(), capture::SourceState::kReopening);
  EXPECT_EQ(camera.lastProblem(), "end of stream");
  EXPECT_EQ(camera.counters().dropped_stale, 0);
  EXPECT_EQ(camera.counters().read_errors, 0);
  RecordProperty("fewest_features", static_cast<int>(fewest));
  std::cout << "vtest.avi: " << frames.size() << " frames, at least " << fewest
            << " SIFT features in each\n";
}

}  // namespace
