// Test-side tools for the real-robot launch tests and the video stand-in of
// docs/robot-bringup.md (built as build/tests/vslam-test-log-tools):
//
//   vslam-test-log-tools to-video LOG DIR
//       every camera image channel of LOG (CAM_<NAME>_IMAGE) as DIR/<name>.avi
//       (MJPG at the channel's median frame rate), and ODOMETRY as
//       DIR/odometry.txt in the bridge's pose format "t x y theta"
//       (docs/odometry.md): a recorded robot as video files and a line file
//       for vslam-camera's video: source and vslam-odometry-bridge.
//   vslam-test-log-tools health LOG
//       per instance on HEALTH: the number of messages, the worst level, the
//       last message and every metric's last and largest value, one line each:
//         INSTANCE messages N worst_level L last_message "..."
//         INSTANCE METRIC last V max V
//
// Exit codes: 0 ok, 1 data problem (unreadable log, nothing to write), 2 usage.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>
#include <vslam/health_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "eval/log_events.hpp"
#include "stages/image_gray.hpp"
#include "util/statistics.hpp"

namespace fs = std::filesystem;
using vslam::eval::decodeEvent;
using vslam::eval::forEachLogEvent;
using vslam::eval::LogEventRef;

namespace {

bool isImageChannel(const std::string& ch) {
  return ch.rfind("CAM_", 0) == 0 && ch.size() > 10 && ch.substr(ch.size() - 6) == "_IMAGE";
}

std::string cameraName(const std::string& channel) {
  std::string name = channel.substr(4, channel.size() - 10);
  for (auto& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name;
}

int toVideo(const fs::path& log, const fs::path& dir) {
  fs::create_directories(dir);
  // Frame rates first: the median interval per channel.
  std::map<std::string, std::vector<int64_t>> stamps;
  forEachLogEvent(log, [&](const LogEventRef& ref) {
    if (isImageChannel(ref.event.channel)) {
      stamps[ref.event.channel].push_back(decodeEvent<vslam::image_t>(ref, "vslam.image_t").utime);
    }
  });
  if (stamps.empty()) {
    std::cerr << log.string() << ": no CAM_<NAME>_IMAGE channel\n";
    return 1;
  }
  std::map<std::string, cv::VideoWriter> writers;
  std::map<std::string, double> rates;
  for (auto& [channel, t] : stamps) {
    std::vector<double> dt;
    for (size_t i = 1; i < t.size(); ++i) dt.push_back(static_cast<double>(t[i] - t[i - 1]));
    const double fps = dt.empty() ? 10.0 : 1e6 / vslam::upperMedian(&dt);
    rates[channel] = fps;
    std::cout << channel << ": " << t.size() << " frames at " << fps << " Hz -> "
              << (dir / (cameraName(channel) + ".avi")).string() << "\n";
  }
  FILE* odometry = std::fopen((dir / "odometry.txt").c_str(), "w");
  if (!odometry) {
    std::cerr << (dir / "odometry.txt").string() << ": cannot write\n";
    return 1;
  }
  std::fprintf(odometry, "# t x y theta (s, m, m, rad): ODOMETRY of %s\n", log.c_str());
  int readings = 0;
  cv::Mat gray;
  forEachLogEvent(log, [&](const LogEventRef& ref) {
    const std::string& ch = ref.event.channel;
    if (ch == "ODOMETRY") {
      const auto m = decodeEvent<vslam::odometry_t>(ref, "vslam.odometry_t");
      std::fprintf(odometry, "%.6f %.6f %.6f %.9f\n", static_cast<double>(m.utime) * 1e-6, m.x, m.y,
                   m.theta);
      ++readings;
    } else if (isImageChannel(ch)) {
      const auto m = decodeEvent<vslam::image_t>(ref, "vslam.image_t");
      if (auto why = vslam::stages::imageToGray(m, &gray)) {
        throw vslam::eval::DataError(ch + ": " + *why);
      }
      cv::VideoWriter& w = writers[ch];
      if (!w.isOpened()) {
        const fs::path file = dir / (cameraName(ch) + ".avi");
        if (!w.open(file.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'),
                    rates[ch], gray.size(), false)) {
          throw vslam::eval::DataError(file.string() + ": cannot open for writing");
        }
      }
      w.write(gray);
    }
  });
  std::fclose(odometry);
  std::cout << "ODOMETRY: " << readings << " readings -> " << (dir / "odometry.txt").string()
            << "\n";
  return readings > 0 ? 0 : 1;
}

struct MetricRange {
  double last = 0, max = 0;
  bool seen = false;
};
struct InstanceHealth {
  int messages = 0;
  int worst_level = 0;
  std::string last_message;
  std::map<std::string, MetricRange> metrics;
};

int health(const fs::path& log) {
  std::map<std::string, InstanceHealth> by_instance;
  forEachLogEvent(log, [&](const LogEventRef& ref) {
    if (ref.event.channel != "HEALTH") return;
    const auto m = decodeEvent<vslam::health_t>(ref, "vslam.health_t");
    InstanceHealth& h = by_instance[m.instance];
    ++h.messages;
    h.worst_level = std::max<int>(h.worst_level, m.level);
    h.last_message = m.message;
    for (const auto& metric : m.metrics) {
      MetricRange& r = h.metrics[metric.name];
      r.last = metric.value;
      r.max = r.seen ? std::max(r.max, metric.value) : metric.value;
      r.seen = true;
    }
  });
  for (const auto& [instance, h] : by_instance) {
    std::cout << instance << " messages " << h.messages << " worst_level " << h.worst_level
              << " last_message \"" << h.last_message << "\"\n";
    for (const auto& [name, r] : h.metrics) {
      std::cout << instance << " " << name << " last " << r.last << " max " << r.max << "\n";
    }
  }
  return by_instance.empty() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  try {
    if (args.size() == 3 && args[0] == "to-video") return toVideo(args[1], args[2]);
    if (args.size() == 2 && args[0] == "health") return health(args[1]);
  } catch (const std::exception& e) {
    std::cerr << "vslam-test-log-tools: " << e.what() << "\n";
    return 1;
  }
  std::cerr << "usage: vslam-test-log-tools to-video LOG DIR | health LOG\n";
  return 2;
}
