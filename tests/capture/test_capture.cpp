// The capture library on recordings made here: an MJPG video and a PNG folder
// with an rgb.txt. Times, sequence, loop, speed, the end of a recording, a
// folder whose files are deleted mid-run, the rescale of intrinsics, the
// encodings, and the V4L2 and GStreamer paths where the machine has them.
#include <gtest/gtest.h>

#include <chrono>
#include <opencv2/imgproc.hpp>

#include "capture/camera.hpp"
#include "capture/frame_source.hpp"
#include "capture/image_encoding.hpp"
#include "capture/image_folder.hpp"
#include "capture/intrinsics_scale.hpp"
#include "capture_test_util.hpp"

namespace {

using namespace vslam;
using namespace vslam::capture;
using namespace vslam::capture_test;

CameraParams fastParams() {
  CameraParams p;
  p.speed = 0;  // as fast as it decodes
  p.reopen_initial_s = 0.01;
  p.reopen_max_s = 0.05;
  return p;
}

std::unique_ptr<Camera> makeCamera(const std::string& source, const CameraParams& params) {
  const SourceSpec spec = SourceSpec::parse(source);
  return std::make_unique<Camera>(
      openSource(spec), [spec] { return openSource(spec); }, params);
}

// Reads up to n frames, giving up after `max_calls` calls of next().
std::vector<Frame> readFrames(Camera& camera, size_t n, int max_calls = 200) {
  std::vector<Frame> frames;
  Frame f;
  for (int i = 0; i < max_calls && frames.size() < n; ++i) {
    if (camera.next(&f, 0.2) == Camera::Result::kFrame) frames.push_back(f);
  }
  return frames;
}

TEST(SourceSpec, ParsesEachKindAndNamesWhatIsWrong) {
  EXPECT_EQ(SourceSpec::parse("v4l2:/dev/video0").kind, SourceSpec::Kind::kV4l2);
  EXPECT_EQ(SourceSpec::parse("video:a.avi").location, "a.avi");
  EXPECT_EQ(SourceSpec::parse("gstreamer:a ! b:c ! appsink").location, "a ! b:c ! appsink");
  EXPECT_EQ(SourceSpec::parse("folder:dir").kind, SourceSpec::Kind::kFolder);
  for (const char* bad : {"/dev/video0", "webcam:0", "video:"}) {
    try {
      SourceSpec::parse(bad);
      ADD_FAILURE() << bad << " parsed";
    } catch (const SourceError& e) {
      EXPECT_EQ(e.setting(), "source");
    }
  }
}

TEST(VideoFile, FramesCarryTheFileTimesAndConsecutiveSequenceNumbers) {
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 12, 10.0, {160, 120});
  auto camera = makeCamera("video:" + (dir.path() / "v.avi").string(), fastParams());
  EXPECT_EQ(camera->outputSize(), cv::Size(160, 120));
  const auto frames = readFrames(*camera, 12);
  ASSERT_EQ(frames.size(), 12u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));
    EXPECT_EQ(frames[i].source_index, static_cast<int64_t>(i));
    EXPECT_EQ(indexOf(frames[i].image), static_cast<int64_t>(i)) << "frame " << i;
    if (i > 0) {
      EXPECT_NEAR(frames[i].utime - frames[i - 1].utime, 100000, 1000);
    }
  }
  // Robot time: the wall clock at the first frame.
  const auto wall_now = std::chrono::duration_cast<std::chrono::microseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
  EXPECT_LT(std::llabs(frames.front().utime - wall_now), 60 * 1000000LL);
}

TEST(VideoFile, EndWithoutLoopIsReportedAndRetriedWithoutRepeatingAFrame) {
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 6, 10.0, {160, 120});
  auto camera = makeCamera("video:" + (dir.path() / "v.avi").string(), fastParams());
  ASSERT_EQ(readFrames(*camera, 6).size(), 6u);
  Frame f;
  // Past the end: nothing more, the source reopened (and ended again) with back-off.
  for (int i = 0; i < 5; ++i) EXPECT_EQ(camera->next(&f, 0.1), Camera::Result::kTimeout);
  const CameraCounters c = camera->counters();
  EXPECT_EQ(c.frames, 6);
  EXPECT_GE(c.sources_lost, 1);
  EXPECT_GE(c.reopen_attempts, 1);
  EXPECT_EQ(camera->state(), SourceState::kReopening);
  EXPECT_EQ(camera->lastProblem(), "end of stream");
  camera->stop();
  EXPECT_EQ(camera->next(&f, 1.0), Camera::Result::kStopped);
}

TEST(VideoFile, LoopOffsetsEachLapSoTimesKeepRising) {
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 5, 10.0, {160, 120});
  CameraParams p = fastParams();
  p.loop = true;
  auto camera = makeCamera("video:" + (dir.path() / "v.avi").string(), p);
  const auto frames = readFrames(*camera, 15);
  ASSERT_EQ(frames.size(), 15u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));
    EXPECT_EQ(indexOf(frames[i].image), static_cast<int64_t>(i % 5)) << "frame " << i;
    // One frame period everywhere, the joins between laps included.
    if (i > 0) {
      EXPECT_NEAR(frames[i].utime - frames[i - 1].utime, 100000, 1000) << "frame " << i;
    }
  }
  EXPECT_EQ(camera->counters().laps, 2);
  EXPECT_EQ(camera->counters().sources_lost, 0);
}

TEST(VideoFile, PacedAtSpeedTimesStayTheRecordings) {
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 9, 10.0, {160, 120});
  CameraParams p = fastParams();
  p.speed = 4.0;
  auto camera = makeCamera("video:" + (dir.path() / "v.avi").string(), p);
  const auto start = std::chrono::steady_clock::now();
  const auto frames = readFrames(*camera, 9);
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(frames.size(), 9u);
  // 0.8 s of recording at 4x cannot take less than 0.2 s.
  EXPECT_GE(wall, 0.2);
  EXPECT_NEAR(frames.back().utime - frames.front().utime, 800000, 2000);
}

TEST(VideoFile, RateLimitAndResize) {
  TempDir dir;
  writeVideo(dir.path() / "v.avi", 20, 10.0, {320, 240});
  CameraParams p = fastParams();
  p.max_fps = 5;
  p.width = 160;
  p.height = 120;
  auto camera = makeCamera("video:" + (dir.path() / "v.avi").string(), p);
  EXPECT_EQ(camera->outputSize(), cv::Size(160, 120));
  const auto frames = readFrames(*camera, 10);
  ASSERT_EQ(frames.size(), 10u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].image.size(), cv::Size(160, 120));
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));  // dropped frames are not numbered
    EXPECT_EQ(frames[i].source_index, static_cast<int64_t>(2 * i));
    if (i > 0) {
      EXPECT_NEAR(frames[i].utime - frames[i - 1].utime, 200000, 1000);
    }
  }
  EXPECT_GE(camera->counters().dropped_rate, 9);
}

TEST(ImageFolder, AlternatingCamerasTakeTheFirstFrameOfTheirSlotEachPeriod) {
  // 25 Hz frames; two cameras sharing max_fps 10 take turns in 0.2 s periods.
  TempDir dir;
  const int n = 50;
  const double frame_period_s = 0.04;
  writeFolder(dir.path(), n, 0.0, frame_period_s, {64, 48});
  // The folder's frame times as the library reads them (rgb.txt, microseconds).
  std::vector<Utime> media(n);
  for (int i = 0; i < n; ++i) media[i] = std::llround((0.0 + i * frame_period_s) * 1e6);
  for (int slot : {0, 1}) {
    CameraParams p = fastParams();
    p.max_fps = 10;
    p.alternate = {slot, 2};
    auto camera = makeCamera("folder:" + dir.path().string(), p);
    const auto first = readFrames(*camera, 1);
    ASSERT_EQ(first.size(), 1u);
    // Every frame's robot time, from the first one taken and the file's times.
    const int64_t k = first[0].source_index;
    std::vector<int64_t> expected;  // source indices: the first in the slot of each period
    int64_t last_period = -1;
    for (int i = 0; i < n; ++i) {
      const Utime t = first[0].utime + media[i] - media[k];
      const int64_t period = t / 200000;
      if ((t % 200000) / 100000 == slot && period != last_period) {
        expected.push_back(i);
        last_period = period;
      }
    }
    ASSERT_GE(expected.size(), 9u);
    EXPECT_EQ(expected.front(), k) << "slot " << slot;
    const auto rest = readFrames(*camera, expected.size() - 1);
    std::vector<int64_t> got{k};
    for (size_t i = 0; i < rest.size(); ++i) {
      got.push_back(rest[i].source_index);
      EXPECT_EQ(rest[i].seq, static_cast<int64_t>(i + 1));  // turns not taken are not numbered
    }
    EXPECT_EQ(got, expected) << "slot " << slot;
    EXPECT_EQ(camera->counters().dropped_turn,
              expected.back() + 1 - static_cast<int64_t>(expected.size()));
    EXPECT_EQ(camera->counters().dropped_rate, 0);
  }
  // Taking turns needs the rate the turns share.
  CameraParams no_rate = fastParams();
  no_rate.alternate = {0, 2};
  EXPECT_THROW(makeCamera("folder:" + dir.path().string(), no_rate), std::invalid_argument);
  CameraParams bad_slot = fastParams();
  bad_slot.max_fps = 10;
  bad_slot.alternate = {2, 2};
  EXPECT_THROW(makeCamera("folder:" + dir.path().string(), bad_slot), std::invalid_argument);
}

// Opening `spec` throws a SourceError on "source" whose message holds `text`.
void expectSourceError(const std::string& spec, const std::string& text) {
  try {
    openSource(SourceSpec::parse(spec));
    FAIL() << "opened " << spec;
  } catch (const SourceError& e) {
    EXPECT_EQ(e.setting(), "source");
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

TEST(VideoFile, MissingFileIsASourceError) {
  expectSourceError("video:/nonexistent/v.avi", "/nonexistent/v.avi");
}

TEST(ImageFolder, TimesFromTheTimestampsFile) {
  TempDir dir;
  writeFolder(dir.path(), 8, 1305031102.175304, 0.05, {160, 120});
  auto camera = makeCamera("folder:" + dir.path().string(), fastParams());
  EXPECT_EQ(camera->outputSize(), cv::Size(160, 120));
  const auto frames = readFrames(*camera, 8);
  ASSERT_EQ(frames.size(), 8u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));
    EXPECT_EQ(indexOf(frames[i].image), static_cast<int64_t>(i));
    if (i > 0) {
      EXPECT_NEAR(frames[i].utime - frames[i - 1].utime, 50000, 2);
    }
  }
}

TEST(ImageFolder, ALoopOfAFolderKeepsTimesRising) {
  TempDir dir;
  writeFolder(dir.path(), 3, 100.0, 0.1, {64, 48});
  CameraParams p = fastParams();
  p.loop = true;
  auto camera = makeCamera("folder:" + (dir.path() / "rgb.txt").string(), p);
  const auto frames = readFrames(*camera, 7);
  ASSERT_EQ(frames.size(), 7u);
  for (size_t i = 1; i < frames.size(); ++i) {
    EXPECT_NEAR(frames[i].utime - frames[i - 1].utime, 100000, 2) << "frame " << i;
  }
}

TEST(ImageFolder, AMissingImageIsAReadErrorAndSkipped) {
  TempDir dir;
  writeFolder(dir.path(), 6, 0.0, 0.1, {64, 48});
  fs::remove(dir.path() / imageName(2));
  auto camera = makeCamera("folder:" + dir.path().string(), fastParams());
  const auto frames = readFrames(*camera, 5);
  ASSERT_EQ(frames.size(), 5u);
  const std::vector<int64_t> expected{0, 1, 3, 4, 5};
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].source_index, expected[i]);
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));
  }
  EXPECT_EQ(camera->counters().read_errors, 1);
  EXPECT_EQ(camera->counters().sources_lost, 0);
}

// The "unplug": every image deleted mid-run. Reported, retried with back-off,
// and once the files are back the stream goes on where it stopped: no frame
// twice, none lost.
TEST(ImageFolder, FilesDeletedMidRunAreReportedRetriedAndResumedWithoutRepeats) {
  TempDir dir;
  const cv::Size size{64, 48};
  writeFolder(dir.path(), 10, 50.0, 0.1, size);
  auto camera = makeCamera("folder:" + dir.path().string(), fastParams());
  const auto before = readFrames(*camera, 4);
  ASSERT_EQ(before.size(), 4u);
  for (int i = 0; i < 10; ++i) fs::remove(dir.path() / imageName(i));

  Frame f;
  for (int i = 0; i < 50 && camera->counters().reopen_attempts < 3; ++i) {
    ASSERT_NE(camera->next(&f, 0.05), Camera::Result::kFrame) << "a frame from deleted files";
  }
  CameraCounters c = camera->counters();
  EXPECT_GE(c.sources_lost, 1);
  EXPECT_GE(c.reopen_attempts, 3);
  EXPECT_GE(c.read_errors, 3);
  EXPECT_EQ(c.frames, 4);
  EXPECT_NE(camera->lastProblem().find("is missing"), std::string::npos) << camera->lastProblem();

  for (int i = 0; i < 10; ++i)
    cv::imwrite((dir.path() / imageName(i)).string(), frameImage(i, size));
  const auto after = readFrames(*camera, 6);
  ASSERT_EQ(after.size(), 6u);
  for (size_t i = 0; i < after.size(); ++i) {
    EXPECT_EQ(after[i].source_index, static_cast<int64_t>(4 + i));
    EXPECT_EQ(indexOf(after[i].image), static_cast<int64_t>(4 + i));
    EXPECT_EQ(after[i].seq, static_cast<int64_t>(4 + i));
  }
  EXPECT_GT(after.front().utime, before.back().utime);
  EXPECT_GE(camera->counters().reopens, 1);
  EXPECT_EQ(camera->state(), SourceState::kOpen);
}

TEST(ImageFolder, TimestampsFileIsCheckedLineByLine) {
  TempDir dir;
  const std::vector<std::pair<std::string, std::string>> cases{
      {"1.0 a.png\nx b.png\n", ":2: timestamp 'x' is not a number"},
      {"1.0 a.png\n0.5 b.png\n", ":2: timestamp 0.5 is not after the previous one"},
      {"1.0 /etc/passwd\n", ":1: path '/etc/passwd' must be relative"},
      {"1.0 ../a.png\n", ":1: path '../a.png' must be relative"},
      {"1.0 a.png extra\n", ":1: expected 'timestamp relative/path'"},
      {"# only a comment\n", "lists no images"},
  };
  for (const auto& [text, message] : cases) {
    std::ofstream(dir.path() / "rgb.txt") << text;
    try {
      readTimestampsFile(dir.path() / "rgb.txt");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const SourceError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

// The rescale agrees with cv::resize: a blob's centroid lands where the
// rescaled intrinsics put it.
TEST(RescaleIntrinsics, MatchesWhereResizeMovesAPoint) {
  vslam::config::CameraConfig cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = 500;
  cam.fy = 510;
  cam.cx = 319.5;
  cam.cy = 241.25;
  cam.distortion = {0.1, -0.2, 0.001, 0.002};
  const auto half = rescaleIntrinsics(cam, 320, 240);
  EXPECT_DOUBLE_EQ(half.fx, 250);
  EXPECT_DOUBLE_EQ(half.fy, 255);
  EXPECT_DOUBLE_EQ(half.cx, 159.5);
  EXPECT_DOUBLE_EQ(half.cy, 120.375);
  EXPECT_EQ(half.distortion, cam.distortion);
  EXPECT_EQ(half.width, 320);

  // A point at normalized (x, y) seen through both.
  const double x = 0.13, y = -0.21;
  const cv::Point2d full_px(cam.fx * x + cam.cx, cam.fy * y + cam.cy);
  cv::Mat image(cam.height, cam.width, CV_32F, cv::Scalar(0));
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const double d2 = std::pow(c - full_px.x, 2) + std::pow(r - full_px.y, 2);
      image.at<float>(r, c) = static_cast<float>(std::exp(-d2 / (2 * 4.0 * 4.0)));
    }
  }
  cv::Mat small;
  cv::resize(image, small, {320, 240}, 0, 0, cv::INTER_AREA);
  const cv::Moments m = cv::moments(small);
  EXPECT_NEAR(m.m10 / m.m00, half.fx * x + half.cx, 0.02);
  EXPECT_NEAR(m.m01 / m.m00, half.fy * y + half.cy, 0.02);
}

TEST(ImageEncoding, RawAndJpegAsImageTWantsThem) {
  cv::Mat bgr(30, 40, CV_8UC3, cv::Scalar(10, 120, 200));
  EncodedImage out;
  encodeImage(bgr, PixelEncoding::kBgr8, 90, &out);
  EXPECT_EQ(out.width, 40);
  EXPECT_EQ(out.height, 30);
  EXPECT_EQ(out.row_stride, 120);
  ASSERT_EQ(out.data.size(), 3600u);
  EXPECT_EQ(out.data[0], 10);
  EXPECT_EQ(out.data[2], 200);

  encodeImage(bgr, PixelEncoding::kGray8, 90, &out);
  EXPECT_EQ(out.row_stride, 40);
  ASSERT_EQ(out.data.size(), 1200u);
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(out.data[0], gray.at<uint8_t>(0, 0));

  encodeImage(gray, PixelEncoding::kBgr8, 90, &out);
  EXPECT_EQ(out.data.size(), 3600u);

  encodeImage(bgr, PixelEncoding::kJpeg, 90, &out);
  EXPECT_EQ(out.row_stride, 0);
  EXPECT_EQ(out.encoding, PixelEncoding::kJpeg);
  const cv::Mat decoded = cv::imdecode(out.data, cv::IMREAD_COLOR);
  EXPECT_EQ(decoded.size(), bgr.size());

  EXPECT_EQ(parsePixelEncoding("jpeg"), PixelEncoding::kJpeg);
  EXPECT_THROW(parsePixelEncoding("rgb8"), std::invalid_argument);
  EXPECT_THROW(encodeImage(cv::Mat(2, 2, CV_16UC1), PixelEncoding::kGray8, 90, &out),
               std::invalid_argument);
}

bool haveVideoDevice() {
  for (int i = 0; i < 64; ++i) {
    if (fs::exists("/dev/video" + std::to_string(i))) return true;
  }
  return false;
}

TEST(V4l2, AMissingDeviceIsNamed) {
  expectSourceError("v4l2:/dev/video-vslam-none", "no device /dev/video-vslam-none");
}

TEST(V4l2, ReadsFramesFromARealDevice) {
  if (!haveVideoDevice())
    GTEST_SKIP() << "no /dev/video* on this machine: the V4L2 path is not exercised";
  std::unique_ptr<FrameSource> source;
  try {
    source = openSource(SourceSpec::parse("v4l2:/dev/video0"));
  } catch (const SourceError& e) {
    GTEST_SKIP() << "/dev/video0 is not a capture device here: " << e.what();
  }
  Camera camera(
      std::move(source), [] { return openSource(SourceSpec::parse("v4l2:/dev/video0")); },
      CameraParams{});
  const auto frames = readFrames(camera, 5, 50);
  ASSERT_EQ(frames.size(), 5u);
  for (size_t i = 1; i < frames.size(); ++i) EXPECT_GT(frames[i].utime, frames[i - 1].utime);
}

TEST(GStreamer, PipelineThroughAppsink) {
  if (!openCvHasGStreamer()) GTEST_SKIP() << "this OpenCV was built without GStreamer";
  try {
    openSource(SourceSpec::parse("gstreamer:videotestsrc ! fakesink"));
    FAIL() << "a pipeline without appsink was accepted";
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("appsink"), std::string::npos);
  }
  const std::string pipeline =
      "gstreamer:videotestsrc num-buffers=5 ! video/x-raw,width=160,height=120 ! videoconvert ! "
      "appsink";
  std::unique_ptr<FrameSource> source;
  try {
    source = openSource(SourceSpec::parse(pipeline));
  } catch (const SourceError& e) {
    GTEST_SKIP() << "GStreamer's videotestsrc/appsink are missing (gstreamer1.0-plugins-base): "
                 << e.what();
  }
  const SourceSpec spec = SourceSpec::parse(pipeline);
  Camera camera(
      std::move(source), [spec] { return openSource(spec); }, fastParams());
  const auto frames = readFrames(camera, 5, 50);
  ASSERT_EQ(frames.size(), 5u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].image.size(), cv::Size(160, 120));
    EXPECT_EQ(frames[i].seq, static_cast<int64_t>(i));
    if (i > 0) {
      EXPECT_GT(frames[i].utime, frames[i - 1].utime);
    }
  }
}

}  // namespace
