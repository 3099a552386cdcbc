#include "viewer/viewer_cli.hpp"

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <thread>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/particle_set_t.hpp>
#include <vslam/pose_estimate_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "bus/bus.hpp"
#include "bus/log_reader.hpp"
#include "config/stack_config.hpp"
#include "stages/image_gray.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"
#include "util/process.hpp"
#include "util/time.hpp"
#include "viewer/viewer_model.hpp"

namespace vslam::viewer {
namespace {

namespace fs = std::filesystem;

struct ViewerOptions {
  std::string lcm_url, config_file, log_file, snapshot_dir, size_text = "1280x720";
  double every_s = 5.0;
  double speed = 1.0;
  bool no_window = false;
  cv::Size size{1280, 720};
};

const char* kWindow = "vslam-viewer";

// Subscribes the model to every channel it shows, on `bus`; times are seconds
// since the first message (`t0_us`, set by the first one).
void subscribeModel(bus::Bus& bus, const config::RobotConfig& robot, ViewerModel& model,
                    int64_t& t0_us) {
  const auto& ch = robot.channels;
  // Copied into each handler (they outlive this function); t0_us outlives them.
  const auto seconds = [&t0_us](int64_t utime) {
    if (t0_us == 0) t0_us = utime;
    return toSeconds(utime - t0_us);
  };
  bus.subscribe<vslam::pose_estimate_t>(ch.pose_estimate, [&model, seconds](
                                                              const vslam::pose_estimate_t& m) {
    model.addEstimate({seconds(m.utime), m.x, m.y, m.theta}, m.kidnapped, m.effective_sample_size);
  });
  bus.subscribe<vslam::pose_estimate_t>(ch.pose_odometry,
                                        [&model, seconds](const vslam::pose_estimate_t& m) {
                                          model.addOdometry({seconds(m.utime), m.x, m.y, m.theta});
                                        });
  bus.subscribe<vslam::ground_truth_pose_t>(
      ch.ground_truth, [&model, seconds](const vslam::ground_truth_pose_t& m) {
        model.addGroundTruth({seconds(m.utime), m.x, m.y, m.theta});
      });
  bus.subscribe<vslam::map_t>(ch.map, [&model](const vslam::map_t& m) {
    std::vector<Landmark> landmarks;
    landmarks.reserve(m.landmarks.size());
    for (const auto& l : m.landmarks) {
      landmarks.push_back(
          {l.landmark_id, l.x, l.y, l.covariance[0], l.covariance[1], l.covariance[4]});
    }
    model.setMap(std::move(landmarks));
  });
  bus.subscribe<vslam::particle_set_t>(ch.particles, [&model](const vslam::particle_set_t& m) {
    std::vector<Particle> particles;
    particles.reserve(m.particles.size());
    for (const auto& p : m.particles) {
      particles.push_back({p.x, p.y, p.theta, p.weight, p.kind == vslam::particle_t::KIND_DUAL});
    }
    model.setParticles(std::move(particles));
  });
  bus.subscribe<vslam::appearance_map_t>(
      ch.appearance_map, [&model](const vslam::appearance_map_t& m) {
        std::map<int64_t, AppearanceState> states;
        for (const auto& s : m.states) states[s.state_id] = {s.odom_x, s.odom_y};
        std::vector<std::pair<int64_t, int64_t>> links;
        links.reserve(m.links.size());
        for (const auto& l : m.links) links.emplace_back(l.from_state, l.to_state);
        model.setAppearanceMap(std::move(states), std::move(links));
      });
  bus.subscribe<vslam::appearance_hypotheses_t>(
      ch.appearance_hypotheses, [&model](const vslam::appearance_hypotheses_t& m) {
        model.setAppearanceBest(m.best_state_id, m.best_belief, m.num_hypotheses);
      });
  bus.subscribe<vslam::landmark_update_t>(
      ch.landmark_update,
      [&model](const vslam::landmark_update_t& m) {
        const auto& l = m.landmark;
        if (m.op == vslam::landmark_update_t::OP_REMOVED ||
            m.op == vslam::landmark_update_t::OP_EVICTED) {
          model.removeLandmark(l.landmark_id);
          return;
        }
        if (l.num_points <= 0 || l.descriptor_size <= 0) return;  // statistics only
        cv::Mat d(l.num_points, l.descriptor_size, CV_8U);
        for (int i = 0; i < l.num_points; ++i) {
          std::copy(l.descriptors[static_cast<size_t>(i)].begin(),
                    l.descriptors[static_cast<size_t>(i)].end(), d.ptr<uint8_t>(i));
        }
        model.setLandmarkDescriptors(l.landmark_id, d);
      },
      200);
  bus.subscribe<vslam::visual_measurement_t>(
      ch.visual_measurement_filtered, [&model, seconds](const vslam::visual_measurement_t& m) {
        model.addMeasurement(m.camera, m.landmark_id,
                             m.status == vslam::visual_measurement_t::STATUS_ACCEPTED,
                             seconds(m.utime));
      });
  for (const auto& cam : robot.cameras) {
    bus.subscribe<vslam::image_t>(
        cam.image_channel,
        [&model, &bus, seconds, name = cam.name](const vslam::image_t& m) {
          cv::Mat gray;
          if (const auto why = stages::imageToGray(m, &gray)) {
            bus.reportMalformed(name, *why);
            return;
          }
          model.setImage(name, gray, seconds(m.utime));
        },
        2);
  }
}

// Writes a snapshot named after the robot time; false (logged) on failure.
bool writeSnapshot(ViewerModel& model, const ViewerOptions& o) {
  char name[64];
  std::snprintf(name, sizeof(name), "viewer-%07.1f.png", model.time());
  const fs::path file = fs::path(o.snapshot_dir) / name;
  if (!cv::imwrite(file.string(), model.render(o.size))) {
    log::error("cannot write ", file.string());
    return false;
  }
  log::info("snapshot ", file.string());
  return true;
}

bool isRight(int key) { return key == '.' || key == 65363 || key == 0x1000014; }
bool isLeft(int key) { return key == ',' || key == 65361 || key == 0x1000012; }

// Plays a log into the model: paced by its time at `speed` (0: as fast as
// possible), with a window: space pauses, . and , (or the arrows) seek 10 s,
// q quits. Returns the exit status.
int playLog(const ViewerOptions& o, const config::RobotConfig& robot, bool window) {
  double seek_to = -1;  // robot seconds to reach without drawing
  for (;;) {            // one pass per backward seek
    ViewerModel model;
    lcm::LCM lcm("memq://");
    WallClock clock;
    bus::Bus bus(lcm, clock, "viewer");
    int64_t t0_us = 0;
    subscribeModel(bus, robot, model, t0_us);
    std::unique_ptr<bus::LogReader> reader;
    try {
      reader = std::make_unique<bus::LogReader>(o.log_file, bus::LogDamage::kSkip);
    } catch (const bus::LogError& e) {
      log::error(e.what());
      return kExitFailure;
    }
    double next_snapshot = 0, next_draw_wall = 0, log_start = -1, last_written = -1;
    // Pacing: robot time anchor_t was shown at wall time anchor_wall; a pause
    // or a seek sets a new anchor (-1: at the next event shown).
    double anchor_t = -1, anchor_wall = 0;
    bool restart = false;
    while (!stopRequested()) {
      const lcm::LogEvent* ev = reader->next();
      if (!ev) break;
      if (log_start < 0) log_start = toSeconds(ev->timestamp);
      lcm.publish(ev->channel, ev->data, static_cast<unsigned>(ev->datalen));
      while (lcm.handleTimeout(0) > 0) {
      }
      const double t = toSeconds(ev->timestamp) - log_start;
      model.setTime(t);
      if (!o.snapshot_dir.empty() && t >= next_snapshot) {
        if (!writeSnapshot(model, o)) return kExitFailure;
        last_written = model.time();
        next_snapshot = (std::floor(t / o.every_s) + 1) * o.every_s;
      }
      if (t < seek_to) continue;
      if (o.speed > 0) {
        const double wall = toSeconds(monotonicUtime());
        if (anchor_t < 0) anchor_t = t, anchor_wall = wall;
        const double ahead = (t - anchor_t) / o.speed - (wall - anchor_wall);
        if (ahead > 0.002) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
      }
      if (!window) continue;
      const double now = toSeconds(monotonicUtime());
      if (now < next_draw_wall) continue;
      next_draw_wall = now + 0.1;
      cv::imshow(kWindow, model.render(o.size));
      int key = cv::waitKeyEx(1);
      if (key == ' ') {  // pause until space again (or a seek, or q)
        do key = cv::waitKeyEx(100);
        while (key != ' ' && key != 'q' && key != 27 && !isLeft(key) && !isRight(key) &&
               !stopRequested());
        anchor_t = -1;
      }
      if (key == 'q' || key == 27) return kExitOk;
      if (isRight(key)) seek_to = t + 10, anchor_t = -1;
      if (isLeft(key)) {
        seek_to = std::max(0.0, t - 10);
        restart = true;
        break;
      }
    }
    if (restart) continue;
    log::info("end of ", o.log_file, " at ", model.time(), " s");
    // The last frame too, unless it was just written.
    if (!o.snapshot_dir.empty() && model.time() > last_written && !writeSnapshot(model, o)) {
      return kExitFailure;
    }
    if (window) {
      cv::imshow(kWindow, model.render(o.size));
      log::info("press q to close the window");
      while (!stopRequested()) {
        const int key = cv::waitKeyEx(100);
        if (key == 'q' || key == 27) break;
      }
    }
    return kExitOk;
  }
}

int watchBus(const ViewerOptions& o, const config::StackConfig& stack, bool window) {
  const std::string url = config::resolveLcmUrl(o.lcm_url, stack.lcm_url);
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    log::error("cannot open LCM on ", url);
    return kExitFailure;
  }
  ViewerModel model;
  WallClock clock;
  bus::Bus bus(lcm, clock, "viewer");
  int64_t t0_us = 0;
  subscribeModel(bus, stack.robot, model, t0_us);
  log::info("watching ", url);
  double next_snapshot = 0, next_draw = 0;
  while (!stopRequested()) {
    lcm.handleTimeout(20);
    const double t = model.time();
    if (!o.snapshot_dir.empty() && t0_us != 0 && t >= next_snapshot) {
      if (!writeSnapshot(model, o)) return kExitFailure;
      next_snapshot = (std::floor(t / o.every_s) + 1) * o.every_s;
    }
    const double now = toSeconds(monotonicUtime());
    if (!window || now < next_draw) continue;
    next_draw = now + 0.1;
    cv::imshow(kWindow, model.render(o.size));
    const int key = cv::waitKeyEx(1);
    if (key == 'q' || key == 27) break;
  }
  return kExitOk;
}

}  // namespace

int runViewerCli(const std::vector<std::string>& args) {
  ViewerOptions o;
  CLI::App app{
      "vslam-viewer: a live top-down view of the stack from the bus (or a log): landmarks with\n"
      "their 2-sigma ellipses, particles, the estimated, odometry-only and ground-truth\n"
      "trajectories, appearance-SLAM states and links, each camera's image with its SIFT\n"
      "features and the matches of the landmark it measured, and a health line.\n"
      "Keys: space pause, . and , (or the arrows) seek 10 s in a log, q quit.",
      "vslam-viewer"};
  app.add_option("--log", o.log_file, "play this LCM log instead of watching the bus")
      ->check(CLI::ExistingFile);
  app.add_option("--speed", o.speed, "with --log: times real time (0: as fast as possible)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--snapshot", o.snapshot_dir, "write PNG snapshots into this folder");
  app.add_option("--every", o.every_s, "with --snapshot: seconds of robot time between them")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 86400.0));
  app.add_option("--size", o.size_text, "frame size WIDTHxHEIGHT")->capture_default_str();
  app.add_flag("--no-window", o.no_window, "no window even where a display exists");
  app.add_option("--config", o.config_file,
                 "stack configuration: channels and cameras (default $VSLAM_CONFIG, else "
                 "config/vslam.yaml)");
  app.add_option("--lcm-url", o.lcm_url, "LCM URL when watching the bus");
  const auto code = parseCommandLine(app, "vslam-viewer", args, std::cout, std::cerr, [&] {
    std::smatch m;
    if (!std::regex_match(o.size_text, m, std::regex(R"((\d{3,4})x(\d{3,4}))"))) {
      throw CLI::ValidationError("--size: expected WIDTHxHEIGHT, e.g. 1280x720, got " +
                                 o.size_text);
    }
    o.size = {std::stoi(m[1]), std::stoi(m[2])};
    if (o.size.width < 640 || o.size.height < 360) {
      throw CLI::ValidationError("--size: at least 640x360");
    }
  });
  if (code) return *code;

  const char* display = std::getenv("DISPLAY");
  const bool window = !o.no_window && display != nullptr && *display != '\0';
  if (!window && o.snapshot_dir.empty()) {
    log::error(
        "no display (DISPLAY is not set, or --no-window): give --snapshot DIR to write "
        "PNGs instead");
    return kExitUsage;
  }
  if (!o.snapshot_dir.empty()) {
    std::error_code ec;
    fs::create_directories(o.snapshot_dir, ec);
    if (ec) {
      log::error("cannot create ", o.snapshot_dir, ": ", ec.message());
      return kExitUsage;
    }
  }
  const std::string config_file = config::resolveStackConfig(o.config_file);
  std::unique_ptr<config::StackConfig> stack;
  try {
    stack = std::make_unique<config::StackConfig>(config::StackConfig::loadFile(config_file));
  } catch (const config::ConfigError& e) {
    log::error("configuration error: ", e.what());
    return kExitUsage;
  }
  installStopSignalHandlers();
  if (window) {
    cv::namedWindow(kWindow, cv::WINDOW_AUTOSIZE);
    log::info("window on display ", display);
  }
  const int status =
      o.log_file.empty() ? watchBus(o, *stack, window) : playLog(o, stack->robot, window);
  if (window) cv::destroyAllWindows();
  return status;
}

}  // namespace vslam::viewer
