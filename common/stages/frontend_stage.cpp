#include "stages/frontend_stage.hpp"

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "util/log.hpp"

namespace vslam::stages {
namespace {

constexpr int64_t kIdsPerCamera = 1000000000;
constexpr Utime kMaxOdometryGap = 200000;  // us: no pose for a frame farther from any reading

double msSince(Utime start) { return 1e-3 * static_cast<double>(monotonicUtime() - start); }

}  // namespace

FrontendParams FrontendParams::load(const config::ConfigNode& node,
                                    const config::RobotConfig& robot) {
  FrontendParams p;
  const std::string camera = node.getString("camera");
  bool found = false;
  for (size_t i = 0; i < robot.cameras.size(); ++i) {
    if (robot.cameras[i].name == camera) {
      p.camera = robot.cameras[i];
      p.camera_number = static_cast<int>(i) + 1;
      found = true;
    }
  }
  if (!found) throw node.error("camera", "no camera '" + camera + "' in " + robot.file.string());
  p.odometry_channel = robot.channels.odometry;
  p.measurement_channel = robot.channels.visual_measurement;
  p.proposal_channel = robot.channels.landmark_proposal;
  p.creation_baseline_m = node.getDouble("creation_baseline_m", 0.20, config::InRange{0.02, 2.0});
  p.max_measurements_per_frame =
      static_cast<int>(node.getInt("max_measurements_per_frame", 4, config::InRange{1, 100}));
  p.sift.nfeatures =
      static_cast<int>(node.getInt("sift_max_features", 0, config::InRange{0, 100000}));
  p.recognition.ratio = node.getDouble("match_ratio", 0.8, config::InRange{0.1, 1.0});
  p.creation.match.ratio = p.recognition.ratio;
  p.recognition.min_matches =
      static_cast<int>(node.getInt("min_matches", 10, config::InRange{4, 1000}));
  return p;
}

FrontendStage::FrontendStage(FrontendParams params)
    : params_(std::move(params)),
      extractor_(params_.camera, params_.sift),
      creator_(params_.camera, params_.creation),
      measurement_camera_(frontend::MeasurementCamera::fromConfig(params_.camera)),
      index_(params_.recognition) {}

FrontendStage::~FrontendStage() { stop(); }

void FrontendStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  worker_ = std::make_unique<bus::LatestWinsWorker<vslam::image_t>>(
      ctx.mode, [this](vslam::image_t& img) { process(img); });
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
  ctx.bus.subscribe<vslam::landmark_update_t>(
      params_.proposal_channel, [this](const vslam::landmark_update_t& m) { onProposal(m); });
  // A small queue: frames wait in the worker's one-slot mailbox, not in LCM.
  ctx.bus.subscribe<vslam::image_t>(
      params_.camera.image_channel, [this](const vslam::image_t& m) { onImage(m); }, 2);
}

void FrontendStage::drain() {
  if (worker_) worker_->drain();
}

void FrontendStage::stop() {
  if (worker_) worker_->stop();
}

void FrontendStage::onOdometry(const vslam::odometry_t& m) {
  const Pose2 pose{m.x, m.y, m.theta};
  if (!pose.isFinite()) {
    ctx_->bus.reportMalformed(params_.odometry_channel, "non-finite odometry pose");
    return;
  }
  std::lock_guard<std::mutex> lock(odometry_mutex_);
  if (!odometry_.empty() && m.utime <= odometry_.back().first) return;  // stale or duplicate
  odometry_.emplace_back(m.utime, pose);
  while (odometry_.size() > 500) odometry_.pop_front();  // 10 s at 50 Hz
}

bool FrontendStage::odometryAt(Utime t, Pose2* pose) {
  std::lock_guard<std::mutex> lock(odometry_mutex_);
  if (odometry_.empty()) return false;
  const auto after = std::lower_bound(odometry_.begin(), odometry_.end(), t,
                                      [](const auto& a, Utime v) { return a.first < v; });
  if (after == odometry_.end()) {
    if (t - odometry_.back().first > kMaxOdometryGap) return false;
    *pose = odometry_.back().second;
    return true;
  }
  if (after == odometry_.begin() || after->first == t) {
    if (after->first - t > kMaxOdometryGap) return false;
    *pose = after->second;
    return true;
  }
  const auto before = std::prev(after);
  const double s =
      static_cast<double>(t - before->first) / static_cast<double>(after->first - before->first);
  const Pose2 step = before->second.between(after->second);
  *pose = before->second.compose({s * step.x, s * step.y, s * step.theta});
  return true;
}

void FrontendStage::onImage(const vslam::image_t& msg) {
  if (!worker_->post(msg)) ctx_->bus.countDropped();
}

void FrontendStage::onProposal(const vslam::landmark_update_t& m) {
  const vslam::landmark_t& l = m.landmark;
  if (m.op != vslam::landmark_update_t::OP_PROPOSED || l.camera == params_.camera.name) return;
  if (l.num_points <= 0 || l.descriptor_size != 128) {
    ctx_->bus.reportMalformed(params_.proposal_channel,
                              "landmark " + std::to_string(l.landmark_id) + " without SIFT points");
    return;
  }
  frontend::LandmarkModel model;
  model.id = l.landmark_id;
  model.descriptors.create(l.num_points, 128, CV_32F);
  for (int i = 0; i < l.num_points; ++i) {
    model.points_robot.emplace_back(l.points[i][0], l.points[i][1], l.points[i][2]);
    for (int c = 0; c < 128; ++c) {
      model.descriptors.at<float>(i, c) =
          static_cast<float>(l.descriptors[i][static_cast<size_t>(c)]);
    }
  }
  std::lock_guard<std::mutex> lock(index_mutex_);
  index_.add(std::move(model));
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  ++stats_.foreign_landmarks;
}

bool FrontendStage::toGray(const vslam::image_t& msg, cv::Mat* gray) {
  const std::string& channel = params_.camera.image_channel;
  if (msg.width != params_.camera.width || msg.height != params_.camera.height) {
    ctx_->bus.reportMalformed(channel, "image " + std::to_string(msg.width) + "x" +
                                           std::to_string(msg.height) + ", but camera '" +
                                           params_.camera.name + "' is calibrated for " +
                                           std::to_string(params_.camera.width) + "x" +
                                           std::to_string(params_.camera.height));
    return false;
  }
  const size_t rows = static_cast<size_t>(msg.height);
  switch (msg.encoding) {
    case vslam::image_t::ENCODING_GRAY8:
    case vslam::image_t::ENCODING_BGR8: {
      const int channels = msg.encoding == vslam::image_t::ENCODING_GRAY8 ? 1 : 3;
      if (msg.row_stride < msg.width * channels ||
          msg.data.size() < rows * static_cast<size_t>(msg.row_stride)) {
        ctx_->bus.reportMalformed(channel, "image data shorter than height x row_stride");
        return false;
      }
      const cv::Mat view(msg.height, msg.width, channels == 1 ? CV_8UC1 : CV_8UC3,
                         const_cast<uint8_t*>(msg.data.data()),
                         static_cast<size_t>(msg.row_stride));
      if (channels == 1) {
        view.copyTo(*gray);
      } else {
        cv::cvtColor(view, *gray, cv::COLOR_BGR2GRAY);
      }
      return true;
    }
    case vslam::image_t::ENCODING_JPEG:
      *gray = cv::imdecode(msg.data, cv::IMREAD_GRAYSCALE);
      if (gray->empty() || gray->cols != msg.width || gray->rows != msg.height) {
        ctx_->bus.reportMalformed(channel, "JPEG does not decode to the announced size");
        return false;
      }
      return true;
    default:
      ctx_->bus.reportMalformed(channel, "unknown encoding " + std::to_string(msg.encoding));
      return false;
  }
}

void FrontendStage::process(vslam::image_t& msg) {
  if (!toGray(msg, &gray_)) return;
  View view;
  view.utime = msg.utime;
  Utime t0 = monotonicUtime();
  extractor_.extract(gray_, &view.features);
  const double sift_ms = msSince(t0);

  t0 = monotonicUtime();
  std::vector<frontend::Recognition> recognized;
  {
    std::lock_guard<std::mutex> lock(index_mutex_);
    recognized = index_.recognize(view.features);
  }
  const double recognition_ms = msSince(t0);

  t0 = monotonicUtime();
  int measured = 0, failures = 0;
  bool place_covered = false;
  for (const auto& r : recognized) {
    if (measured >= params_.max_measurements_per_frame) break;
    const auto result = frontend::measurePose(r.points_robot, r.observations, measurement_camera_,
                                              params_.measurement);
    if (!result.ok()) {
      ++failures;
      continue;
    }
    const frontend::PoseMeasurement& pm = result.measurement;
    vslam::visual_measurement_t out{};
    out.utime = msg.utime;
    out.seq = measurement_seq_++;
    out.camera = params_.camera.name;
    out.image_seq = msg.seq;
    out.landmark_id = r.landmark_id;
    out.dx = pm.relative.x;
    out.dy = pm.relative.y;
    out.dtheta = pm.relative.theta;
    out.proj_err_rms = pm.proj_err_rms_px;
    out.num_points = pm.num_points;
    out.slope = pm.slope;
    out.status = vslam::visual_measurement_t::STATUS_UNFILTERED;
    ctx_->bus.publish(params_.measurement_channel, out);
    ++measured;
    place_covered = place_covered || frontend::prefilter(pm, params_.prefilter) ==
                                         frontend::MeasurementStatus::kAccepted;
  }
  const double measurement_ms = msSince(t0);

  const bool have_pose = odometryAt(msg.utime, &view.odometry);
  t0 = monotonicUtime();
  if (have_pose) considerCreation(std::move(view), place_covered);
  const double creation_ms = msSince(t0);

  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.frames;
  stats_.features += static_cast<int64_t>(view.features.size());
  stats_.recognitions += static_cast<int64_t>(recognized.size());
  stats_.measurements += measured;
  stats_.measurement_failures += failures;
  stats_.no_odometry += have_pose ? 0 : 1;
  stats_.sift_ms += sift_ms;
  stats_.recognition_ms += recognition_ms;
  stats_.measurement_ms += measurement_ms;
  stats_.creation_ms += creation_ms;
}

void FrontendStage::considerCreation(View view, bool place_covered) {
  // A place a known landmark already measures well needs no new one.
  if (place_covered) {
    views_.clear();
    return;
  }
  while (!views_.empty() &&
         toSeconds(view.utime - views_.front().utime) > params_.max_view_span_s) {
    views_.pop_front();
  }
  if (!views_.empty()) {
    const Pose2 d = views_.back().odometry.between(view.odometry);
    if (std::hypot(d.x, d.y) < params_.creation_baseline_m) return;
  }
  views_.push_back(std::move(view));
  if (views_.size() < 3) return;

  const auto result = creator_.create(views_[0].features, views_[1].features, views_[2].features,
                                      {views_[0].odometry, views_[1].odometry, views_[2].odometry});
  if (!result.ok()) {
    log::debug("no landmark from views at ", views_[0].utime, ": ", result.reason);
    views_.pop_front();  // slide: the next view may make a better triple
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.creation_failures;
    return;
  }
  const int64_t id = params_.camera_number * kIdsPerCamera + next_landmark_++;
  frontend::LandmarkModel model;
  model.id = id;
  model.points_robot = result.landmark.points_robot;
  model.descriptors.create(static_cast<int>(result.landmark.feature_index.size()), 128, CV_32F);
  for (size_t i = 0; i < result.landmark.feature_index.size(); ++i) {
    views_[0]
        .features.descriptors.row(result.landmark.feature_index[i])
        .copyTo(model.descriptors.row(static_cast<int>(i)));
  }
  {
    std::lock_guard<std::mutex> lock(index_mutex_);
    index_.add(std::move(model));
  }
  publishProposal(views_[0], result.landmark, id);
  views_.clear();
  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.created;
}

void FrontendStage::publishProposal(const View& v1, const frontend::CreatedLandmark& lm,
                                    int64_t id) {
  vslam::landmark_update_t m{};
  m.utime = v1.utime;
  m.database_id = "";
  m.revision = 0;
  m.op = vslam::landmark_update_t::OP_PROPOSED;
  vslam::landmark_t& l = m.landmark;
  l.landmark_id = id;
  l.proposal_id = id;
  l.version = 0;
  l.camera = params_.camera.name;
  l.created_utime = v1.utime;
  l.created_odom_x = v1.odometry.x;
  l.created_odom_y = v1.odometry.y;
  l.created_odom_theta = v1.odometry.theta;
  const size_t n = lm.points_robot.size();
  l.num_points = static_cast<int32_t>(n);
  l.descriptor_size = 128;
  l.points.assign(n, std::vector<float>(3));
  l.keypoints.assign(n, std::vector<float>(2));
  l.scales.resize(n);
  l.orientations.resize(n);
  l.descriptors.assign(n, std::vector<uint8_t>(128));
  for (size_t i = 0; i < n; ++i) {
    const int f = lm.feature_index[i];
    for (int k = 0; k < 3; ++k) l.points[i][k] = static_cast<float>(lm.points_robot[i][k]);
    l.keypoints[i][0] = static_cast<float>(v1.features.normalized[static_cast<size_t>(f)].x());
    l.keypoints[i][1] = static_cast<float>(v1.features.normalized[static_cast<size_t>(f)].y());
    l.scales[i] = v1.features.keypoints[static_cast<size_t>(f)].size;
    l.orientations[i] =
        static_cast<float>(v1.features.keypoints[static_cast<size_t>(f)].angle * M_PI / 180.0);
    const float* d = v1.features.descriptors.ptr<float>(f);
    for (int c = 0; c < 128; ++c) {
      l.descriptors[i][static_cast<size_t>(c)] =
          static_cast<uint8_t>(std::clamp(std::lround(d[c]), 0L, 255L));
    }
  }
  ctx_->bus.publish(params_.proposal_channel, m);
}

void FrontendStage::collectHealth(bus::HealthReport& report) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const Stats d{stats_.frames - last_.frames,
                stats_.features - last_.features,
                stats_.recognitions - last_.recognitions,
                stats_.measurements - last_.measurements,
                stats_.measurement_failures - last_.measurement_failures,
                stats_.created - last_.created,
                stats_.creation_failures - last_.creation_failures,
                stats_.foreign_landmarks - last_.foreign_landmarks,
                stats_.no_odometry - last_.no_odometry,
                stats_.sift_ms - last_.sift_ms,
                stats_.recognition_ms - last_.recognition_ms,
                stats_.measurement_ms - last_.measurement_ms,
                stats_.creation_ms - last_.creation_ms};
  last_ = stats_;
  const double frames = std::max<double>(1.0, static_cast<double>(d.frames));
  report.add("frames_processed", static_cast<double>(d.frames), "count");
  report.add("features_per_frame", static_cast<double>(d.features) / frames, "");
  report.add("recognitions", static_cast<double>(d.recognitions), "count");
  report.add("measurements", static_cast<double>(d.measurements), "count");
  report.add("measurement_failures", static_cast<double>(d.measurement_failures), "count");
  report.add("landmarks_created", static_cast<double>(stats_.created), "count");
  report.add("creation_failures", static_cast<double>(d.creation_failures), "count");
  report.add("sift_ms", d.sift_ms / frames, "ms");
  report.add("recognition_ms", d.recognition_ms / frames, "ms");
  report.add("measurement_ms", d.measurement_ms / frames, "ms");
  report.add("creation_ms", d.creation_ms / frames, "ms");
  {
    std::lock_guard<std::mutex> index_lock(index_mutex_);
    report.add("landmarks_known", static_cast<double>(index_.size()), "count");
  }
  report.add("frames_dropped", static_cast<double>(worker_ ? worker_->dropped() : 0), "count");
  if (d.no_odometry > 0) report.warn("frames without odometry: no landmarks can be created");
}

void registerFrontend(bus::StageRegistry& registry) {
  registry.add("frontend", [](const bus::StageSetup& setup) {
    return std::make_unique<FrontendStage>(FrontendParams::load(setup.params, setup.stack.robot));
  });
}

}  // namespace vslam::stages
