// Tracking one camera frame (issue 16, deliverable 2: "features +
// recognition + measurement + filter <= 12 ms on one core"): what a frame
// costs the stack from its pixels to the back-end's update, through the
// library calls the processes make for it (no LCM), with config/vslam.yaml's
// parameters read as the processes read them, on frames rendered as vslam-sim
// renders the apartment scenario (its path, camera noise and motion blur).
//
// Set-up, not timed (30-60 s on the 2-core VM): the scenario's true path at
// its odometry rate. Over its first two laps a Frontend per camera (the
// vslam-frontend library) makes landmarks from its window of three views
// creation_baseline_m apart, at every place: its own recognition index stays
// empty, so no landmark covers a place (the running front-end stops there and
// makes about 30 in three laps). They are proposed to the landmark DB (in
// memory), whose landmarks fill the forward front-end's recognition replica,
// as LANDMARK_UPDATE does, and start in the back-end's particle filter at
// their creation poses with the map prior's sigma (localization in a known
// map, as map_prior_file does), the robot at its true pose. That makes about
// 120 landmarks, not the 1,000: this route holds 1,000 only with one
// every few centimetres, which takes minutes to build here, and
// docs/benchmarks.md shows that a map of 600 such gives the same figure.
//
// Timed, one thread (TBB and OpenCV limited to one): 128 held-out frames of
// the forward camera, evenly over the third lap (no map view comes from it),
// in a loop (the lap ends where it began). Between two of them the robot
// drives on with all its odometry readings (50 Hz, the scenario's noise); the
// readings of the frame's own period (5, at 10 frames/s) are timed as its share:
//   BM_TrackingFeatures                SIFT (Frontend::extract)
//   BM_TrackingRecognitionMeasurement  Frontend::track: recognition of every
//                                      camera's landmarks, the measurements,
//                                      the creation window, the view-jump
//                                      test (ms_contin)
//   BM_TrackingFilter                  the frame's odometry readings (the
//                                      back-end's prediction and the pose it
//                                      publishes) and its measurements
//                                      (pre-filter, filter update, the DB's
//                                      statistics)
//   BM_TrackingWholeFrame              all of it, in the stack's order
// Each run is one pass over the held-out frames, so every benchmark averages
// the same frames. Figures in docs/benchmarks.md.
//
//   build/bin/bench_tracking [--benchmark_filter=WholeFrame]

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <future>
#include <memory>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "backend/backend.hpp"
#include "config/stack_config.hpp"
#include "frontend/frontend.hpp"
#include "landmark_db/landmark_database.hpp"
#include "sim/motion.hpp"
#include "sim/odometry_sim.hpp"
#include "sim/scenario.hpp"
#include "stages/backend_stage.hpp"
#include "stages/frontend_stage.hpp"
#include "stages/landmark_db_stage.hpp"
#include "stages/prefilter_config.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace {

namespace fs = std::filesystem;
using namespace vslam;

const fs::path kSource = VSLAM_SOURCE_DIR;
constexpr int kMapLaps = 2;                      // the map's laps; the next one is held out
constexpr size_t kHeldOutFrames = 128;           // evenly over the held-out lap
constexpr Utime kStartUtime = 1700000000000000;  // the scenario's t = 0

double msSince(Utime start) { return 1e-3 * static_cast<double>(monotonicUtime() - start); }

// config/vslam.yaml as the processes read it.
struct StackParams {
  std::array<stages::FrontendStageParams, 2> frontend;  // forward, backward
  stages::BackendStageParams backend;
  stages::LandmarkDbParams landmark_db;
};

StackParams loadStack() {
  const auto stack = config::StackConfig::loadFile(kSource / "config/vslam.yaml");
  const backend::PrefilterParams prefilter = stages::loadPrefilter(stack);
  StackParams p;
  p.frontend[0] =
      stages::FrontendStageParams::load(stack.process("frontend_forward"), stack.robot, prefilter);
  p.frontend[1] =
      stages::FrontendStageParams::load(stack.process("frontend_backward"), stack.robot, prefilter);
  p.backend = stages::BackendStageParams::load(stack.process("backend"), stack.robot, prefilter);
  p.landmark_db = stages::LandmarkDbParams::load(stack.process("landmark_db"), stack.robot);
  return p;
}

// The apartment scenario's true path, one step per odometry period (as
// vslam-sim drives it, without rendering).
struct PathStep {
  Pose2 pose;    // after the step, world frame
  Pose2 motion;  // the step, in the robot frame before it
  int lap = 0;
};

struct ScenarioPath {
  sim::Scenario scenario;
  std::unique_ptr<world::World> world;
  std::vector<PathStep> steps;  // steps[0]: the start
  Utime dt_us = 0;
  size_t steps_per_frame = 0;

  Utime utime(size_t k) const { return kStartUtime + static_cast<Utime>(k) * dt_us; }
};

ScenarioPath samplePath(double frame_rate_hz) {
  ScenarioPath p;
  p.scenario = sim::Scenario::loadByName("apartment", kSource / "config/scenarios");
  p.world = std::make_unique<world::World>(world::World::loadFile(p.scenario.world_file));
  sim::MotionParams motion = p.scenario.motion;
  // The route and the start come from the world file, as in sim::Simulator.
  for (const auto& route : p.world->routes) {
    if (route.name == motion.route) motion.waypoints = route.waypoints;
  }
  if (!motion.has_start)
    motion.start = {p.world->start.x(), p.world->start.y(), p.world->start.z()};
  const world::World* w = p.world.get();
  auto driver = sim::makeDriver(
      motion, [w](double x, double y, double r) { return w->isFree(x, y, r); }, 1);
  const auto* waypoints = dynamic_cast<const sim::WaypointDriver*>(driver.get());
  if (waypoints == nullptr || motion.waypoints.empty())
    throw std::runtime_error("the apartment scenario should drive its world's route");
  p.dt_us = static_cast<Utime>(std::llround(1e6 / p.scenario.odometry.rate_hz));
  p.steps_per_frame = static_cast<size_t>(std::lround(p.scenario.odometry.rate_hz / frame_rate_hz));
  Pose2 pose = motion.start, step;
  p.steps.push_back({pose, {}, 0});
  while (driver->advance(pose, toSeconds(p.dt_us), &step)) {
    pose = pose.compose(step);
    // A lap ends on arriving at the route's first waypoint, when the driver
    // heads for the second (target 1 + laps x waypoints).
    const size_t target = std::max<size_t>(waypoints->target(), 1);
    p.steps.push_back({pose, step, static_cast<int>((target - 1) / motion.waypoints.size())});
  }
  return p;
}

world::CameraModel cameraModel(const config::CameraConfig& c) {
  return {c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.distortion};
}

// The gray frame of `camera` at path step k as vslam-sim renders it: sensor
// noise, and motion blur over the exposure that ends at the step.
void renderFrame(world::Renderer& renderer, const config::CameraConfig& camera,
                 const ScenarioPath& path, size_t k, uint64_t seed, cv::Mat* out) {
  const sim::CameraParams& c = path.scenario.cameras;
  world::RenderEffects fx;
  fx.noise_sigma = c.noise_sigma;
  fx.noise_seed = seed;
  const Pose2& now = path.steps[k].pose;
  if (!c.motion_blur || c.blur_samples < 2 || k == 0) {
    renderer.render(frontend::isometryFromPose2(now) * camera.robot_T_camera, {}, fx, false, *out);
    return;
  }
  const Pose2& before = path.steps[k - 1].pose;
  const double exposed = std::min(1.0, c.exposure_time_s / toSeconds(path.dt_us));
  std::vector<Eigen::Isometry3d> samples;
  for (int i = 0; i < c.blur_samples; ++i) {
    const double s = 1.0 - exposed * (1.0 - static_cast<double>(i) / (c.blur_samples - 1));
    samples.push_back(frontend::isometryFromPose2(interpolate(before, now, s)) *
                      camera.robot_T_camera);
  }
  renderer.renderBlurred(samples, {}, fx, false, *out);
}

uint64_t frameSeed(size_t camera, size_t k) { return (static_cast<uint64_t>(camera) << 40) + k; }

// A landmark as the front-end proposes it and the DB stores it (what
// FrontendStage::makeProposal and the DB stage's conversion do, without the
// message between).
struct Proposal {
  landmark_db::LandmarkInfo info;
  landmark_db::LandmarkStructure structure;
};

Proposal proposalOf(const std::string& camera, int64_t proposal_id,
                    const frontend::NewLandmark& created) {
  const frontend::View& view = created.first_view;
  const frontend::CreatedLandmark& lm = created.landmark;
  Proposal p;
  p.info.camera = camera;
  p.info.proposal_id = proposal_id;
  p.info.created_utime = view.utime;
  p.info.created_odom = view.odometry;
  landmark_db::LandmarkStructure& s = p.structure;
  s.num_points = static_cast<int32_t>(lm.points_robot.size());
  s.descriptor_size = 128;
  for (size_t i = 0; i < lm.points_robot.size(); ++i) {
    const size_t f = static_cast<size_t>(lm.feature_index[i]);
    for (int k = 0; k < 3; ++k) s.points.push_back(static_cast<float>(lm.points_robot[i][k]));
    s.keypoints.push_back(static_cast<float>(view.features.normalized[f].x()));
    s.keypoints.push_back(static_cast<float>(view.features.normalized[f].y()));
    s.scales.push_back(view.features.keypoints[f].size);
    s.orientations.push_back(static_cast<float>(view.features.keypoints[f].angle * M_PI / 180.0));
    const float* d = view.features.descriptors.ptr<float>(static_cast<int>(f));
    for (int c = 0; c < 128; ++c)
      s.descriptors.push_back(static_cast<uint8_t>(std::clamp(std::lround(d[c]), 0L, 255L)));
  }
  return p;
}

// A DB landmark as a front-end's replica holds it (the front-end stage's
// conversion of LANDMARK_UPDATE).
frontend::LandmarkModel replicaModel(int64_t id, const landmark_db::LandmarkStructure& s) {
  frontend::LandmarkModel m;
  m.id = id;
  m.descriptors.create(s.num_points, 128, CV_32F);
  for (int i = 0; i < s.num_points; ++i) {
    const size_t k = static_cast<size_t>(i);
    m.points_robot.emplace_back(s.points[3 * k], s.points[3 * k + 1], s.points[3 * k + 2]);
    for (int c = 0; c < 128; ++c)
      m.descriptors.at<float>(i, c) = s.descriptors[128 * k + static_cast<size_t>(c)];
  }
  return m;
}

struct CameraMap {
  std::vector<Proposal> proposals;
  int views = 0, failures = 0;
};

// One camera's landmarks over the map laps: its Frontend is given the frames
// at which the robot has driven creation_baseline_m since the last one it
// was given (the frames it makes views of; SIFT of the others would be
// wasted), with their true odometry.
CameraMap buildCameraMap(const ScenarioPath& path, const frontend::FrontendParams& params,
                         size_t camera_index) {
  const config::CameraConfig& camera = params.camera;
  world::Renderer renderer(*path.world, cameraModel(camera));
  frontend::Frontend creator(params);
  CameraMap out;
  cv::Mat image;
  double travelled = params.creation_baseline_m;  // the first frame is a view
  for (size_t k = 0; k < path.steps.size() && path.steps[k].lap < kMapLaps; ++k) {
    travelled += std::hypot(path.steps[k].motion.x, path.steps[k].motion.y);
    if (k % path.steps_per_frame != 0 || travelled < params.creation_baseline_m) continue;
    travelled = 0;
    renderFrame(renderer, camera, path, k, frameSeed(camera_index, k), &image);
    creator.addOdometry(path.utime(k), path.steps[k].pose);
    frontend::Features features;
    creator.extract(image, &features);
    ++out.views;
    const frontend::FrameResult r = creator.track(path.utime(k), std::move(features));
    if (r.creation_failure) ++out.failures;
    if (r.created) {
      out.proposals.push_back(
          proposalOf(camera.name, static_cast<int64_t>(out.proposals.size()) + 1, *r.created));
    }
  }
  return out;
}

struct HeldOutFrame {
  cv::Mat image;
  frontend::Features features;  // for the part benchmarks
  // What Frontend::track gave for it in the set-up: BM_TrackingFilter's input.
  std::vector<frontend::LandmarkMeasurement> measurements;
  // True steps from the previous held-out frame, one per odometry period.
  std::vector<Pose2> motion;
  Pose2 truth;
};

class Session {
 public:
  static Session& get() {
    static Session session;
    return session;
  }

  size_t numFrames() const { return frames_.size(); }
  const HeldOutFrame& frame(size_t i) const { return frames_[i]; }
  Utime now() const { return utime_; }
  frontend::Frontend& frontend() { return *frontend_; }
  const backend::Backend& backend() const { return *backend_; }
  const std::string& label() const { return label_; }

  // The robot drives on towards the next held-out frame: the odometry
  // readings of the frames in between (not timed), ...
  void driveToNextFrame() {
    const auto& motion = frames_[next_].motion;
    for (size_t i = 0; i + steps_per_frame_ < motion.size(); ++i) odometryReading(motion[i]);
  }
  // ... then those of the frame's own period, its share of the odometry, to
  // the back-end and the front-end as the odometry driver's messages go.
  const HeldOutFrame& frameOdometry() {
    const HeldOutFrame& f = frames_[next_];
    for (size_t i = f.motion.size() - steps_per_frame_; i < f.motion.size(); ++i)
      odometryReading(f.motion[i]);
    next_ = (next_ + 1) % frames_.size();
    return f;
  }

  // One visual measurement of the current frame through the back-end (the
  // pre-filter and the filter) and the DB's statistics, as the back-end and
  // DB stages handle VISUAL_MEASUREMENT and VISUAL_MEASUREMENT_FILTERED.
  backend::MeasurementResult fuse(const frontend::LandmarkMeasurement& m) {
    db_->recordMeasurement(m.landmark_id, utime_);
    backend::MeasurementInput in;
    in.utime = utime_;
    in.landmark_id = m.landmark_id;
    in.relative = m.measurement.relative;
    in.proj_err_rms_px = m.measurement.proj_err_rms_px;
    in.num_points = m.measurement.num_points;
    in.slope = m.measurement.slope;
    const backend::MeasurementResult r = backend_->addMeasurement(in);
    if (r.status != backend::MeasurementStatus::kUnfiltered)
      db_->recordVerdict(m.landmark_id, r.status == backend::MeasurementStatus::kAccepted, utime_);
    return r;
  }

 private:
  Session() {
    // One core for everything timed; the set-up runs a thread per camera.
    cv::setNumThreads(1);
    const StackParams params = loadStack();
    const Utime setup_start = monotonicUtime();
    const ScenarioPath path = samplePath(params.frontend[0].frontend.camera.frame_rate_hz);
    steps_per_frame_ = path.steps_per_frame;

    auto backward = std::async(
        std::launch::async, [&] { return buildCameraMap(path, params.frontend[1].frontend, 1); });
    const CameraMap forward = buildCameraMap(path, params.frontend[0].frontend, 0);
    const CameraMap back = backward.get();

    // The landmark DB, in memory, takes the proposals in time order.
    db_ = std::make_unique<landmark_db::LandmarkDatabase>(
        std::make_unique<landmark_db::LandmarkStore>(":memory:", landmark_db::StoreOptions{}),
        params.landmark_db.db);
    std::vector<const Proposal*> proposals;
    for (const auto* m : {&forward, &back})
      for (const Proposal& p : m->proposals) proposals.push_back(&p);
    std::stable_sort(proposals.begin(), proposals.end(), [](const Proposal* a, const Proposal* b) {
      return a->info.created_utime < b->info.created_utime;
    });
    for (const Proposal* p : proposals) {
      const auto r = db_->propose(p->info, p->structure);
      if (r.outcome != landmark_db::ProposalOutcome::kCreated)
        throw std::runtime_error("the landmark DB refused a proposal: " + r.reason);
    }

    // The forward front-end's replica: every camera's landmarks the DB holds in memory.
    frontend_ = std::make_unique<frontend::Frontend>(params.frontend[0].frontend);
    for (const int64_t id : db_->activeIds())
      frontend_->addLandmark(replicaModel(id, *db_->structure(id)));

    // Held-out frames: kHeldOutFrames of the forward camera's frames, evenly
    // over the lap after the map's, which ends where it began.
    std::vector<size_t> lap;  // path steps of that lap's frames
    for (size_t k = 0; k < path.steps.size(); ++k) {
      if (path.steps[k].lap == kMapLaps && k % path.steps_per_frame == 0) lap.push_back(k);
    }
    if (lap.size() < kHeldOutFrames)
      throw std::runtime_error("the scenario has no lap to hold out after the map's");
    std::vector<size_t> at;  // path steps of the held-out frames
    for (size_t i = 0; i < kHeldOutFrames; ++i) at.push_back(lap[i * lap.size() / kHeldOutFrames]);
    frames_.resize(at.size());
    for (size_t i = 1; i < at.size(); ++i) {
      for (size_t j = at[i - 1] + 1; j <= at[i]; ++j)
        frames_[i].motion.push_back(path.steps[j].motion);
    }
    // Round the lap: on to its end, then back the last few millimetres and
    // degrees to its first frame's pose, within one frame's odometry period.
    for (size_t j = at.back() + 1; j < path.steps.size(); ++j)
      frames_[0].motion.push_back(path.steps[j].motion);
    const Pose2 gap = path.steps.back().pose.between(path.steps[at[0]].pose);
    const double share = 1.0 / static_cast<double>(steps_per_frame_);
    for (size_t j = 0; j < steps_per_frame_; ++j)
      frames_[0].motion.push_back({share * gap.x, share * gap.y, share * gap.theta});

    const config::CameraConfig& camera = params.frontend[0].frontend.camera;
    const auto render = [&](size_t parity) {
      world::Renderer renderer(*path.world, cameraModel(camera));
      frontend::FeatureExtractor extractor(camera, params.frontend[0].frontend.sift);
      for (size_t i = parity; i < frames_.size(); i += 2) {
        frames_[i].truth = path.steps[at[i]].pose;
        renderFrame(renderer, camera, path, at[i], frameSeed(0, at[i]), &frames_[i].image);
        extractor.extract(frames_[i].image, &frames_[i].features);
      }
    };
    auto odd = std::async(std::launch::async, render, 1);
    render(0);
    odd.get();
    // The measurements each frame gives (no odometry yet: no creation).
    for (size_t i = 0; i < frames_.size(); ++i) {
      frames_[i].measurements =
          frontend_->track(path.utime(at[i]), frames_[i].features).measurements;
    }

    // The back-end localizes in the DB's map from the true pose, on one thread.
    stages::BackendStageParams be = params.backend;
    be.backend.filter.num_threads = 1;
    be.backend.filter.initial_pose = path.steps[at[0]].pose;
    backend_ = std::make_unique<backend::Backend>(be.backend);
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    covariance(0, 0) = covariance(1, 1) = be.map_prior_sigma_xy_m * be.map_prior_sigma_xy_m;
    covariance(2, 2) = be.map_prior_sigma_theta_rad * be.map_prior_sigma_theta_rad;
    std::vector<backend::ParticleFilter::KnownLandmark> known;
    for (const auto& [id, info] : db_->infos()) {
      backend::LandmarkEstimate e;
      e.mean = info.position().vector();
      e.covariance = covariance;
      e.num_observations = 1;
      known.push_back({id, e});
    }
    backend_->loadMap(known);  // as the back-end stage loads a map prior

    // The scenario's odometry noise. The robot stands at the first held-out
    // frame; a pass starts with the second and ends with the first.
    odometry_ = std::make_unique<sim::OdometrySimulator>(path.scenario.odometry, 7);
    odometry_->setPose(path.steps[at[0]].pose);
    dt_us_ = path.dt_us;
    utime_ = path.utime(at[0]);
    backend_->addOdometry({utime_, odometry_seq_++, odometry_->pose()});
    frontend_->addOdometry(utime_, odometry_->pose());
    next_ = 1;

    label_ = std::to_string(db_->numStored()) + " landmarks from " + std::to_string(forward.views) +
             " + " + std::to_string(back.views) + " views (replica " +
             std::to_string(frontend_->numLandmarks()) + ", filter " +
             std::to_string(known.size()) + " x " +
             std::to_string(backend_->filter().particles().size()) + " particles), " +
             std::to_string(frames_.size()) + " held-out frames";
    std::fprintf(stderr, "bench_tracking: set-up %.1f s: %s; %d + %d triples made no landmark\n",
                 msSince(setup_start) / 1000, label_.c_str(), forward.failures, back.failures);
    // From here on TBB runs on the calling thread only.
    control_ =
        std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
  }

  void odometryReading(const Pose2& true_step) {
    utime_ += dt_us_;
    odometry_->addStep(true_step, toSeconds(utime_ - kStartUtime));
    const Pose2& pose = odometry_->pose();
    backend_->addOdometry({utime_, odometry_seq_++, pose});
    // The back-end stage publishes the estimate at every reading.
    const backend::PoseEstimate e = backend_->filter().estimate();
    benchmark::DoNotOptimize(e.mean);
    frontend_->addOdometry(utime_, pose);
  }

  std::vector<HeldOutFrame> frames_;
  std::unique_ptr<landmark_db::LandmarkDatabase> db_;
  std::unique_ptr<frontend::Frontend> frontend_;
  std::unique_ptr<backend::Backend> backend_;
  std::unique_ptr<sim::OdometrySimulator> odometry_;
  std::unique_ptr<tbb::global_control> control_;
  size_t steps_per_frame_ = 1;
  Utime dt_us_ = 0, utime_ = 0;
  int64_t odometry_seq_ = 0;
  size_t next_ = 0;
  std::string label_;
};

// Per-frame tallies, reported as averages per frame.
struct Tally {
  double frames = 0, features = 0, recognized = 0, measurements = 0, accepted = 0, used = 0,
         thinned = 0, created = 0, error_m = 0;
  double ms_odometry = 0, ms_sift = 0, ms_recognition = 0, ms_measurement = 0, ms_filter = 0,
         ms_continuity = 0;

  void add(const frontend::FrameResult& r) {
    recognized += r.recognitions;
    measurements += static_cast<double>(r.measurements.size());
    created += r.created ? 1 : 0;
    ms_recognition += r.recognition_ms;
    ms_measurement += r.measurement_ms;
    ms_continuity += r.continuity_ms;
  }
  void add(const backend::MeasurementResult& r) {
    accepted += r.status == backend::MeasurementStatus::kAccepted ? 1 : 0;
    used += r.use == backend::MeasurementUse::kUsed ? 1 : 0;
    thinned += r.use == backend::MeasurementUse::kThinned ? 1 : 0;
  }
  void report(benchmark::State& state) const {
    const double n = std::max(1.0, frames);
    const std::pair<const char*, double> all[] = {
        {"features", features},       {"recognized", recognized},  {"measurements", measurements},
        {"accepted", accepted},       {"filter_updates", used},    {"thinned", thinned},
        {"created", created},         {"ms_odom", ms_odometry},    {"ms_sift", ms_sift},
        {"ms_recog", ms_recognition}, {"ms_meas", ms_measurement}, {"ms_filter", ms_filter},
        {"ms_contin", ms_continuity}};
    for (const auto& [name, total] : all) {
      if (total > 0) state.counters[name] = total / n;
    }
    state.SetLabel(Session::get().label());
  }
};

// One pass over the held-out frames per run, so that every benchmark
// averages the same frames (Google Benchmark's own choice of iterations would not).
void onePass(benchmark::internal::Benchmark* b) {
  b->Iterations(static_cast<benchmark::IterationCount>(kHeldOutFrames));
  b->Unit(benchmark::kMillisecond);
}

void BM_TrackingFeatures(benchmark::State& state) {
  Session& s = Session::get();
  frontend::Features features;
  Tally t;
  size_t i = 0;
  for (auto _ : state) {
    s.frontend().extract(s.frame(i++ % s.numFrames()).image, &features);
    t.features += static_cast<double>(features.size());
    ++t.frames;
  }
  t.report(state);
}
BENCHMARK(BM_TrackingFeatures)->Apply(onePass);

void BM_TrackingRecognitionMeasurement(benchmark::State& state) {
  Session& s = Session::get();
  Tally t;
  for (auto _ : state) {
    // The odometry and the filter keep up, untimed: the robot stays localized.
    state.PauseTiming();
    s.driveToNextFrame();
    const HeldOutFrame& f = s.frameOdometry();
    frontend::Features features = f.features;
    state.ResumeTiming();
    const frontend::FrameResult r = s.frontend().track(s.now(), std::move(features));
    state.PauseTiming();
    for (const auto& m : r.measurements) s.fuse(m);
    state.ResumeTiming();
    t.add(r);
    ++t.frames;
  }
  t.report(state);
}
BENCHMARK(BM_TrackingRecognitionMeasurement)->Apply(onePass);

void BM_TrackingFilter(benchmark::State& state) {
  Session& s = Session::get();
  Tally t;
  for (auto _ : state) {
    state.PauseTiming();
    s.driveToNextFrame();
    state.ResumeTiming();
    const HeldOutFrame& f = s.frameOdometry();
    for (const auto& m : f.measurements) t.add(s.fuse(m));
    t.measurements += static_cast<double>(f.measurements.size());
    ++t.frames;
  }
  t.report(state);
}
BENCHMARK(BM_TrackingFilter)->Apply(onePass);

void BM_TrackingWholeFrame(benchmark::State& state) {
  Session& s = Session::get();
  frontend::Features features;
  Tally t;
  const HeldOutFrame* previous = nullptr;
  const int64_t kidnaps = s.backend().counters().kidnaps_detected;
  const int64_t solves = s.backend().counters().graph_solves;
  for (auto _ : state) {
    state.PauseTiming();
    if (previous != nullptr) {  // where the filter put the robot at the last frame
      const Pose2 e = s.backend().filter().estimate().mean;
      t.error_m += std::hypot(e.x - previous->truth.x, e.y - previous->truth.y);
    }
    s.driveToNextFrame();
    state.ResumeTiming();
    Utime t0 = monotonicUtime();
    const HeldOutFrame& f = s.frameOdometry();
    t.ms_odometry += msSince(t0);
    t0 = monotonicUtime();
    s.frontend().extract(f.image, &features);
    t.ms_sift += msSince(t0);
    t.features += static_cast<double>(features.size());
    const frontend::FrameResult r = s.frontend().track(s.now(), std::move(features));
    t.add(r);
    t0 = monotonicUtime();
    for (const auto& m : r.measurements) t.add(s.fuse(m));
    t.ms_filter += msSince(t0);
    ++t.frames;
    previous = &f;
  }
  t.report(state);
  if (t.frames > 1) state.counters["error_m"] = t.error_m / (t.frames - 1);
  state.counters["kidnaps"] =
      static_cast<double>(s.backend().counters().kidnaps_detected - kidnaps);
  // Map correction's pose graph, solved on a worker thread off this path.
  state.counters["graph_solves"] =
      static_cast<double>(s.backend().counters().graph_solves - solves);
}
BENCHMARK(BM_TrackingWholeFrame)->Apply(onePass);

}  // namespace
