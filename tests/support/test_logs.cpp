#include "support/test_logs.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <vector>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/log_writer.hpp"

namespace vslam::test {

void writeDrivingLog(const std::filesystem::path& file, double seconds, double image_hz) {
  bus::LogWriter log(file);
  const int64_t t0 = 1700000000000000;
  const double v = 0.3, omega = 0.2;  // m/s, rad/s
  int64_t seq = 0, image_seq = 0;
  const int64_t image_period = image_hz > 0 ? static_cast<int64_t>(1e6 / image_hz) : 0;
  int64_t next_image = t0;
  for (int64_t t = t0; t <= t0 + static_cast<int64_t>(seconds * 1e6); t += 20000, ++seq) {
    const double s = (t - t0) * 1e-6;
    const double th = omega * s;
    vslam::odometry_t odo{};
    odo.utime = t;
    odo.seq = seq;
    odo.x = v / omega * std::sin(th);
    odo.y = v / omega * (1 - std::cos(th));
    odo.theta = std::remainder(th, 2 * M_PI);
    odo.distance = v * s;
    odo.rotation = omega * s;
    odo.v = v;
    odo.omega = omega;
    log.writeMessage(t, "ODOMETRY", odo);
    vslam::ground_truth_pose_t gt{};
    gt.utime = t;
    gt.seq = seq;
    gt.x = odo.x;
    gt.y = odo.y;
    gt.theta = odo.theta;
    log.writeMessage(t + 100, "GROUND_TRUTH", gt);
    if (image_period > 0 && t >= next_image) {
      vslam::image_t img{};
      img.utime = t;
      img.seq = image_seq++;
      img.camera = "forward";
      img.width = 320;
      img.height = 240;
      img.row_stride = 320;
      img.encoding = vslam::image_t::ENCODING_GRAY8;
      img.exposure = 1.0f;
      img.data.resize(320 * 240);
      for (int y = 0; y < 240; ++y) {
        for (int x = 0; x < 320; ++x) {
          img.data[y * 320 + x] = static_cast<uint8_t>((x + y + 3 * img.seq) * 7 % 251);
        }
      }
      img.data_size = static_cast<int32_t>(img.data.size());
      log.writeMessage(t + 200, "CAM_FORWARD_IMAGE", img);
      next_image += image_period;
    }
  }
}

std::vector<RecordedEvent> readLog(const std::filesystem::path& file) {
  lcm::LogFile log(file.string(), "r");
  if (!log.good()) throw std::runtime_error("cannot open " + file.string());
  std::vector<RecordedEvent> out;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    const auto* d = static_cast<const uint8_t*>(ev->data);
    out.push_back({ev->timestamp, ev->channel, std::vector<uint8_t>(d, d + ev->datalen)});
  }
  return out;
}

std::string readFileBytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

int runCommand(const std::string& command, std::string* output) {
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[512];
  while (std::fgets(buf, sizeof(buf), p)) *output += buf;
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

namespace {

// Scratch directories are removed when the test process exits, so a test
// that fails half-way (or a caller that forgets) leaves nothing in /tmp:
// CTest runs every test case as a process of its own. Only by the process
// that made them, not by a forked child.
class RemovedAtExit {
 public:
  void add(const std::filesystem::path& dir) { dirs_.push_back(dir); }
  ~RemovedAtExit() {
    if (::getpid() != owner_) return;
    for (const auto& dir : dirs_) {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  }

 private:
  pid_t owner_ = ::getpid();
  std::vector<std::filesystem::path> dirs_;
};

}  // namespace

std::filesystem::path scratchDir(const std::string& tag) {
  static RemovedAtExit removed_at_exit;
  auto dir =
      std::filesystem::temp_directory_path() / ("vslam_" + tag + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  removed_at_exit.add(dir);
  return dir;
}

}  // namespace vslam::test
