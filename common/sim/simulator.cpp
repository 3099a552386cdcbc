#include "sim/simulator.hpp"

#include <tbb/parallel_for.h>

#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <stdexcept>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/messages.hpp"
#include "util/alternation.hpp"

namespace vslam::sim {
namespace {

template <class Msg>
void emit(EventSink& sink, Utime t, const std::string& channel, const Msg& msg,
          std::vector<uint8_t>& buffer) {
  buffer.resize(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
  sink.write(t, channel, buffer.data(), buffer.size());
}

Eigen::Isometry3d worldTRobot(const Pose2& p) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(p.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(p.x, p.y, 0.0);
  return t;
}

uint64_t mixSeed(uint64_t a, uint64_t b) {
  // splitmix64 step: distinct, well-spread noise seeds per camera and frame.
  uint64_t z = a + 0x9e3779b97f4a7c15ULL * (b + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

LogFileSink::LogFileSink(const std::string& path) : log_(path) {}

void LogFileSink::write(Utime t, const std::string& channel, const void* data, size_t size) {
  log_.write(t, channel, data, size);
}

struct Simulator::Camera {
  const config::CameraConfig* config = nullptr;
  std::unique_ptr<world::Renderer> renderer;
  Utime period_us = 100000;
  Utime next_frame_us = 0;
  std::optional<AlternationGate> turns;  // alternating cameras render only in their slot
  int64_t seq = 0;
  cv::Mat frame;
  vslam::image_t msg;
  std::vector<uint8_t> buffer;
  bool due = false;
  double render_ms = 0;
};

struct Simulator::Person {
  Eigen::Vector2d position;
  Eigen::Vector2d goal;
  double heading = 0;
};

Simulator::Simulator(const Scenario& scenario, const config::RobotConfig& robot, Utime start_utime)
    : scenario_(scenario),
      robot_(robot),
      start_utime_(start_utime),
      odometry_(scenario.odometry, mixSeed(scenario.seed, 1)),
      rng_(mixSeed(scenario.seed, 2)) {
  world_ = std::make_unique<world::World>(world::World::loadFile(scenario_.world_file));
  // Route and start may come from the world file.
  MotionParams& motion = scenario_.motion;
  if (motion.mode == MotionMode::kWaypoints && !motion.route.empty()) {
    std::string known;
    for (const auto& route : world_->routes) {
      if (route.name == motion.route) motion.waypoints = route.waypoints;
      known += (known.empty() ? "" : ", ") + route.name;
    }
    if (motion.waypoints.size() < 2) {
      throw std::runtime_error(scenario_.file.string() + ": motion.route '" + motion.route +
                               "' is not a route of " + scenario_.world_file.string() +
                               " (routes: " + (known.empty() ? "none" : known) + ")");
    }
  }
  if (motion.mode != MotionMode::kTrajectory && !motion.has_start) {
    if (!world_->has_start) {
      throw std::runtime_error(scenario_.file.string() + ": motion.start is not set and " +
                               scenario_.world_file.string() + " has no `start`");
    }
    motion.start = {world_->start.x(), world_->start.y(), world_->start.z()};
  }
  const world::World* w = world_.get();
  const auto is_free = [w](double x, double y, double r) { return w->isFree(x, y, r); };
  driver_ = makeDriver(scenario_.motion, is_free, mixSeed(scenario_.seed, 3));
  if (auto* tr = dynamic_cast<TrajectoryDriver*>(driver_.get())) {
    true_pose_ = tr->startPose();
  } else {
    true_pose_ = scenario_.motion.start;
    if (!world_->isFree(true_pose_.x, true_pose_.y, scenario_.motion.robot_radius_m)) {
      throw std::runtime_error(scenario_.file.string() + ": motion.start (" +
                               std::to_string(true_pose_.x) + ", " + std::to_string(true_pose_.y) +
                               ") is not free space in " + scenario_.world_file.string());
    }
  }
  if (!scenario_.motion.odometry_file.empty()) {
    odometry_trajectory_ =
        std::make_unique<Trajectory>(Trajectory::loadTum(scenario_.motion.odometry_file));
    odometry_.setPose(odometry_trajectory_->at(odometry_trajectory_->start()));
  }
  dt_us_ = static_cast<Utime>(std::llround(1e6 / scenario_.odometry.rate_hz));

  // Textures first: renderers prepare every texture of the world when built.
  if (scenario_.people.count > 0) {
    person_texture_ = world_->addTexture(scenario_.people.texture, scenario_.file.parent_path());
    const auto bounds = world_->bounds();
    std::uniform_real_distribution<double> ux(bounds.min().x(), bounds.max().x());
    std::uniform_real_distribution<double> uy(bounds.min().y(), bounds.max().y());
    const double r = 0.5 * std::hypot(scenario_.people.width_m, scenario_.people.depth_m);
    auto randomFree = [&]() -> Eigen::Vector2d {
      for (int i = 0; i < 10000; ++i) {
        const Eigen::Vector2d p(ux(rng_), uy(rng_));
        if (world_->isFree(p.x(), p.y(), r)) return p;
      }
      throw std::runtime_error(scenario_.world_file.string() + ": no free space for people");
    };
    for (int i = 0; i < scenario_.people.count; ++i) {
      Person p;
      p.position = randomFree();
      p.goal = randomFree();
      people_.push_back(p);
    }
  }

  for (const auto& cam_cfg : robot_.cameras) {
    auto cam = std::make_unique<Camera>();
    cam->config = &cam_cfg;
    world::CameraModel model{cam_cfg.width, cam_cfg.height, cam_cfg.fx,        cam_cfg.fy,
                             cam_cfg.cx,    cam_cfg.cy,     cam_cfg.distortion};
    cam->renderer = std::make_unique<world::Renderer>(*world_, model);
    cam->period_us = static_cast<Utime>(std::llround(1e6 / cam_cfg.frame_rate_hz));
    if (cam_cfg.alternate.active()) cam->turns.emplace(cam_cfg.alternate, cam_cfg.frame_rate_hz);
    cameras_.push_back(std::move(cam));
  }
}

Simulator::~Simulator() = default;

double Simulator::progress() const {
  if (scenario_.duration_s > 0) return std::min(1.0, simTime() / scenario_.duration_s);
  return driver_->progress();
}

double Simulator::exposureAt(double t) const {
  double e = 1.0;
  for (const LightEvent& l : scenario_.lights) {
    if (t >= l.at_s && (l.duration_s <= 0 || t < l.at_s + l.duration_s)) e = l.exposure;
  }
  return e;
}

void Simulator::movePeople(double dt) {
  const double r = 0.5 * std::hypot(scenario_.people.width_m, scenario_.people.depth_m);
  const auto bounds = world_->bounds();
  std::uniform_real_distribution<double> ux(bounds.min().x(), bounds.max().x());
  std::uniform_real_distribution<double> uy(bounds.min().y(), bounds.max().y());
  for (Person& p : people_) {
    Eigen::Vector2d d = p.goal - p.position;
    const double step = scenario_.people.speed_mps * dt;
    const Eigen::Vector2d next = d.norm() <= step ? p.goal : p.position + d.normalized() * step;
    // A person who reached the goal, or would walk into a wall, picks a new goal.
    if (d.norm() <= step || !world_->isFree(next.x(), next.y(), r)) {
      for (int i = 0; i < 100; ++i) {
        const Eigen::Vector2d g(ux(rng_), uy(rng_));
        if (world_->isFree(g.x(), g.y(), r)) {
          p.goal = g;
          break;
        }
      }
      continue;
    }
    p.heading = std::atan2(d.y(), d.x());
    p.position = next;
  }
}

void Simulator::emitCalibration(EventSink& sink, Utime t) {
  std::vector<uint8_t> buffer;
  for (const auto& cam : cameras_) {
    emit(sink, t, cam->config->calibration_channel, bus::calibrationMessage(*cam->config, t),
         buffer);
  }
}

void Simulator::renderDueCameras(EventSink& sink, const Pose2& previous_pose) {
  bool any = false;
  for (auto& cam : cameras_) {
    // A camera taking turns renders at the first odometry step in its slot.
    cam->due = cam->turns ? cam->turns->take(start_utime_ + t_us_) : t_us_ >= cam->next_frame_us;
    any = any || cam->due;
  }
  if (!any) return;

  std::vector<world::Surface> dynamic;
  for (const Person& p : people_) {
    const auto box =
        world::makeBox(Eigen::Vector3d(p.position.x(), p.position.y(), 0.0),
                       Eigen::Vector3d(scenario_.people.depth_m, scenario_.people.width_m,
                                       scenario_.people.height_m),
                       p.heading, person_texture_, scenario_.people.width_m);
    dynamic.insert(dynamic.end(), box.begin(), box.end());
  }
  const double t = simTime();
  world::RenderEffects effects;
  effects.exposure = exposureAt(t);
  effects.noise_sigma = scenario_.cameras.noise_sigma;
  const bool color = scenario_.cameras.encoding == "bgr8";

  // The cameras render in parallel; each owns its renderer and buffers.
  tbb::parallel_for(size_t(0), cameras_.size(), [&](size_t i) {
    Camera& cam = *cameras_[i];
    if (!cam.due) return;
    const Utime begin = monotonicUtime();
    world::RenderEffects fx = effects;
    fx.noise_seed =
        mixSeed(scenario_.seed, (static_cast<uint64_t>(i) << 40) + static_cast<uint64_t>(cam.seq));
    const Eigen::Isometry3d& robot_T_camera = cam.config->robot_T_camera;
    if (scenario_.cameras.motion_blur) {
      // Poses across the exposure, which ends at the frame time; the robot
      // moved from previous_pose to true_pose_ over the last odometry period.
      const double exposure_fraction =
          std::min(1.0, scenario_.cameras.exposure_time_s / toSeconds(dt_us_));
      std::vector<Eigen::Isometry3d> samples;
      const int n = scenario_.cameras.blur_samples;
      for (int k = 0; k < n; ++k) {
        const double s = 1.0 - exposure_fraction * (1.0 - static_cast<double>(k) / (n - 1));
        samples.push_back(worldTRobot(interpolate(previous_pose, true_pose_, s)) * robot_T_camera);
      }
      cam.renderer->renderBlurred(samples, dynamic, fx, color, cam.frame);
    } else {
      cam.renderer->render(worldTRobot(true_pose_) * robot_T_camera, dynamic, fx, color, cam.frame);
    }
    vslam::image_t& m = cam.msg;
    m.utime = start_utime_ + t_us_;
    m.seq = cam.seq++;
    m.camera = cam.config->name;
    m.width = cam.frame.cols;
    m.height = cam.frame.rows;
    m.exposure = static_cast<float>(fx.exposure);
    if (scenario_.cameras.encoding == "jpeg") {
      m.encoding = vslam::image_t::ENCODING_JPEG;
      m.row_stride = 0;
      cv::imencode(".jpg", cam.frame, m.data,
                   {cv::IMWRITE_JPEG_QUALITY, scenario_.cameras.jpeg_quality});
    } else {
      m.encoding = color ? vslam::image_t::ENCODING_BGR8 : vslam::image_t::ENCODING_GRAY8;
      m.row_stride = static_cast<int32_t>(cam.frame.cols * cam.frame.elemSize());
      const size_t bytes = static_cast<size_t>(m.row_stride) * static_cast<size_t>(cam.frame.rows);
      m.data.resize(bytes);
      for (int r = 0; r < cam.frame.rows; ++r) {
        std::memcpy(m.data.data() + static_cast<size_t>(r) * m.row_stride, cam.frame.ptr(r),
                    static_cast<size_t>(m.row_stride));
      }
    }
    m.data_size = static_cast<int32_t>(m.data.size());
    cam.render_ms = 1e-3 * static_cast<double>(monotonicUtime() - begin);
  });
  // Written in camera order so the log is identical whatever the thread timing.
  for (auto& cam : cameras_) {
    if (!cam->due) continue;
    emit(sink, start_utime_ + t_us_, cam->config->image_channel, cam->msg, cam->buffer);
    cam->next_frame_us += cam->period_us;
    ++stats_.frames;
    stats_.render_ms_total += cam->render_ms;
  }
}

bool Simulator::step(EventSink& sink) {
  if (finished_) return false;
  const double t = simTime();
  const double limit = scenario_.duration_s > 0 ? scenario_.duration_s : scenario_.max_duration_s;
  if (t > limit) {
    finished_ = true;
    return false;
  }
  const Pose2 previous = true_pose_;
  if (seq_ > 0) {
    Pose2 motion;
    if (!driver_->advance(true_pose_, toSeconds(dt_us_), &motion)) {
      finished_ = true;
      return false;
    }
    true_pose_ = true_pose_.compose(motion);
    stats_.distance_m += std::hypot(motion.x, motion.y);
    if (odometry_trajectory_) {
      odometry_.setPose(odometry_trajectory_->at(odometry_trajectory_->start() + t));
    } else {
      odometry_.addStep(motion, t);
    }
    // Kidnapping: the robot is carried elsewhere; the wheels notice nothing.
    while (next_kidnap_ < scenario_.kidnaps.size() && t >= scenario_.kidnaps[next_kidnap_].at_s) {
      true_pose_ = scenario_.kidnaps[next_kidnap_++].to;
      ++stats_.kidnaps;
    }
    movePeople(toSeconds(dt_us_));
  }
  const Utime now = start_utime_ + t_us_;
  std::vector<uint8_t> buffer;

  if (t_us_ >= next_calibration_us_) {
    emitCalibration(sink, now);
    next_calibration_us_ += kMicrosPerSecond;
  }

  vslam::ground_truth_pose_t gt{};
  gt.utime = now;
  gt.seq = seq_;
  gt.x = true_pose_.x;
  gt.y = true_pose_.y;
  gt.z = 0;
  gt.theta = true_pose_.theta;
  emit(sink, now, robot_.channels.ground_truth, gt, buffer);

  vslam::odometry_t odo{};
  odo.utime = now;
  odo.seq = seq_;
  odo.x = odometry_.pose().x;
  odo.y = odometry_.pose().y;
  odo.theta = odometry_.pose().theta;
  odo.distance = odometry_.distance();
  odo.rotation = odometry_.rotation();
  const double dt = toSeconds(dt_us_);
  odo.v = seq_ > 0 ? std::hypot(odometry_.lastStep().x, odometry_.lastStep().y) / dt : 0.0;
  odo.omega = seq_ > 0 ? odometry_.lastStep().theta / dt : 0.0;
  emit(sink, now, robot_.channels.odometry, odo, buffer);
  ++stats_.odometry_messages;

  renderDueCameras(sink, previous);

  ++seq_;
  t_us_ += dt_us_;
  stats_.sim_seconds = toSeconds(t_us_);
  return true;
}

}  // namespace vslam::sim
