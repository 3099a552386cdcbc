#include "stages/appearance_stage.hpp"

#include <algorithm>
#include <map>
#include <vslam/appearance_event_t.hpp>
#include <vslam/appearance_map_t.hpp>

#include "appearance/map_file.hpp"
#include "stages/image_gray.hpp"
#include "util/log.hpp"

namespace vslam::stages {

namespace {

using P = AppearanceParams;
using config::InRange;

// The snapshots: cameras, actions, histograms.
config::ParamTable<P> observationKeys() {
  config::ParamTable<P> t;
  t.add("cameras", &P::camera_names,
        "cameras of the robot file, one histogram each (e.g. `[forward, backward]`)")
      .required()
      .add(
          "action_distance_m", [](auto& p) -> auto& { return p.action.distance_m; },
          InRange{0.05, 100}, "m", "a move of this length is one action")
      .required()
      .degrees(
          "action_turn_deg", [](auto& p) -> auto& { return p.action.turn_rad; }, InRange{1, 360},
          "a turn of this angle is one action")
      .required()
      .add(
          "action_rest_s", [](auto& p) -> auto& { return p.action.rest_s; }, InRange{0.02, 10}, "s",
          "this long without odometry motion ends an action...")
      .add(
          "action_min_fraction", [](auto& p) -> auto& { return p.action.min_fraction; },
          InRange{0.01, 1}, "", "...that covered at least this fraction of a move or turn")
      .add("snapshot_timeout_s", &P::snapshot_timeout_s, InRange{0.05, 60}, "s",
           "after an action, wait this long for every camera's next frame, then use those that "
           "came")
      .add("input_timeout_s", &P::input_timeout_s, InRange{0.05, 3600}, "s",
           "a camera's images or odometry quieter than this (the stage's clock) are logged once "
           "and raise health to WARN until they resume")
      .add(
          "histogram_bins", [](auto& p) -> auto& { return p.histogram.bins; }, InRange{2, 1024}, "",
          "k, bins over [-π, π]")
      .required()
      .add(
          "min_gradient", [](auto& p) -> auto& { return p.histogram.min_magnitude; },
          config::nonNegative(), "grey levels",
          "Sobel magnitude a pixel needs to count (flat regions have no orientation)")
      .required()
      .add(
          "histogram_grid_cols", [](auto& p) -> auto& { return p.histogram.grid_cols; },
          InRange{1, 64}, "",
          "a histogram per cell of a grid over the image, concatenated: its columns...")
      .required()
      .add(
          "histogram_grid_rows", [](auto& p) -> auto& { return p.histogram.grid_rows; },
          InRange{1, 64}, "", "...and rows; 1 x 1 is the paper's one histogram")
      .required()
      .check([](const config::ConfigNode& node, const P& p) {
        if (appearance::histogramLength(p.histogram) > 4096) {
          throw node.error("histogram_grid_cols",
                           "histogram_bins x histogram_grid_cols x histogram_grid_rows is " +
                               std::to_string(appearance::histogramLength(p.histogram)) +
                               " values per camera; at most 4096");
        }
      });
  return t;
}

// The path-hypothesis tree (paper section V) and its additions.
config::ParamTable<P> hypothesisTreeKeys() {
  config::ParamTable<P> t;
  t.add(
       "beta", [](auto& p) -> auto& { return p.slam.beta; }, config::positive(), "",
       "β of P(z|x) = 1/(χ²)^β (eq. 5)")
      .required()
      .add(
          "new_state_ratio", [](auto& p) -> auto& { return p.slam.new_state_ratio; },
          InRange{1e-6, 10}, "",
          "a new state is scored as a match at this fraction of the median χ² distance between "
          "the snapshot and the stored states")
      .required()
      .add(
          "min_chi2", [](auto& p) -> auto& { return p.slam.min_chi2; }, InRange{1e-9, 1}, "",
          "floor of χ² in eq. 5")
      .add(
          "transition_gate", [](auto& p) -> auto& { return p.slam.gate; }, config::positive(), "",
          "largest Mahalanobis² of a revisit (11.34: 99 % for 3 dof)")
      .required()
      .add(
          "place_sigma_m", [](auto& p) -> auto& { return p.slam.place_sigma_m; },
          config::positive(), "m",
          "extent of a state: how far from a snapshot the robot is "
          "still \"there\"")
      .required()
      .degrees(
          "place_sigma_deg", [](auto& p) -> auto& { return p.slam.place_sigma_rad; },
          InRange{0.01, 180}, "...and how far turned")
      .required()
      .add(
          "min_belief", [](auto& p) -> auto& { return p.slam.min_belief; }, InRange{0, 1}, "",
          "hypotheses below this belief are pruned")
      .required()
      .add(
          "max_hypotheses", [](auto& p) -> auto& { return p.slam.max_hypotheses; },
          InRange{1, 100000}, "", "bound on the number of hypotheses")
      .required()
      .add(
          "revisit_horizon", [](auto& p) -> auto& { return p.slam.revisit_horizon; },
          InRange{0, 100000}, "links",
          "links traced either side of a re-visited state; 0 = along the path only, as the "
          "paper")
      .required()
      .add(
          "relocalization_prior", [](auto& p) -> auto& { return p.slam.relocalization_prior; },
          InRange{0, 1}, "",
          "prior of a relocalization seed: the probability that the robot was put down in that "
          "state (carried, restarted) since the last step")
      .required()
      .add(
          "relocalization_candidates",
          [](auto& p) -> auto& { return p.slam.relocalization_candidates; }, InRange{0, 1000}, "",
          "relocalization seeds per step: the states that look most like the snapshot; 0 = "
          "the paper's tree only")
      .required()
      .add(
          "relocalization_match_ratio",
          [](auto& p) -> auto& { return p.slam.relocalization_match_ratio; }, InRange{1e-6, 1}, "",
          "a state is seeded only if its χ² to the snapshot is at most this fraction of the "
          "new state's score (1: any state that looks more like it than a new place)")
      .required()
      .add(
          "relocalization_recent_visits",
          [](auto& p) -> auto& { return p.slam.relocalization_recent_visits; }, InRange{0, 100000},
          "visits",
          "no seed in a state that the trace reaches or that is among the path's last visits "
          "(there the trace decides; in a corridor the state a metre back looks like the "
          "snapshot), unless the view jumped: the snapshot looks no more like the path's last "
          "state than a new place would")
      .required()
      .add(
          "relocalization_views", [](auto& p) -> auto& { return p.slam.relocalization_views; },
          "a seed matches a state by the best of the snapshots a path took there, its "
          "revisits' too, not by its first snapshot alone")
      .add("turned_revisits", &P::turned_revisits,
           "a state can be revisited and seeded facing the other way, each camera compared with "
           "the one that faced its way then (cameras of the robot file that face opposite ways, "
           "e.g. forward and backward)")
      .add(
          "action_error", [](auto& p) -> auto& { return p.action_error.relative_translation; },
          config::nonNegative(), "per m, per rad",
          "the link's error proportional to the action (paper: 0.03)")
      .required()
      .add(
          "odometry_sigma_translation",
          [](auto& p) -> auto& { return p.action_error.odometry_translation; },
          config::nonNegative(), "m/√m", "plus the odometry's random walk (as `deadreckon`)")
      .required()
      .add(
          "odometry_sigma_rotation",
          [](auto& p) -> auto& { return p.action_error.odometry_rotation; }, config::nonNegative(),
          "rad/√(m+rad)", "...and its heading's")
      .required();
  return t;
}

// The map file.
config::ParamTable<P> mapFileKeys() {
  config::ParamTable<P> t;
  t.add("map_period_s", &P::map_period_s, config::positive(), "s", "`APPEARANCE_MAP` period")
      .path("map_file", &P::map_file, false,
            "SQLite map file, relative to the config file or under `$XDG_DATA_HOME/` or `~/`; \"\" "
            "keeps the map in memory only")
      .add("map_load", &P::map_load,
           "start from the map file if it exists (required with `map_file`)")
      .add("map_save", &P::map_save, "write the map file at shutdown (required with `map_file`)")
      .add("map_save_period_s", &P::map_save_period_s, config::nonNegative(), "s",
           "also write it this often (0: only at shutdown)")
      .check([](const config::ConfigNode& node, const P& p) {
        if (p.map_file.empty()) return;
        for (const char* key : {"map_load", "map_save"}) {
          if (!node.has(key)) throw node.error(key, "missing (required with map_file)");
        }
      });
  return t;
}

}  // namespace

const config::ParamTable<AppearanceParams>& AppearanceParams::table() {
  static const config::ParamTable<P> declared = [] {
    const auto whole = [](auto& p) -> auto& { return p; };
    config::ParamTable<P> t;
    t.merge(whole, observationKeys())
        .merge(whole, hypothesisTreeKeys())
        .merge(whole, mapFileKeys());
    return t;
  }();
  return declared;
}

AppearanceParams AppearanceParams::load(const config::ConfigNode& node,
                                        const config::RobotConfig& robot) {
  AppearanceParams p;
  table().load(node, p);
  for (const auto& name : p.camera_names) {
    try {
      p.cameras.push_back(robot.camera(name));
    } catch (const std::out_of_range&) {
      throw node.error("cameras", "no camera '" + name + "' in " + robot.file.string());
    }
  }
  if (p.cameras.empty()) throw node.error("cameras", "needs at least one camera");
  // One relative error for moves and turns, as the paper's.
  p.action_error.relative_rotation = p.action_error.relative_translation;
  p.odometry_channel = robot.channels.odometry;
  p.hypotheses_channel = robot.channels.appearance_hypotheses;
  p.map_channel = robot.channels.appearance_map;
  p.event_channel = robot.channels.appearance_event;
  return p;
}

AppearanceStage::AppearanceStage(AppearanceParams params)
    : params_(std::move(params)),
      slam_(params_.slam, static_cast<int>(params_.cameras.size()),
            appearance::histogramLength(params_.histogram)),
      detector_(params_.action) {
  slam_.setActionModel(params_.action_error);
  if (params_.turned_revisits) {
    std::vector<appearance::CameraView> views;
    for (const auto& c : params_.cameras) {
      views.push_back(appearance::cameraView(c.robot_T_camera.linear(), c.width, c.fx));
    }
    slam_.setTurnedCameras(appearance::turnedCameras(views));
  }
  const bool load = params_.map_load && !params_.map_file.empty();
  if (std::error_code ec; load && std::filesystem::exists(params_.map_file, ec)) {
    // A map that cannot be used is a configuration error: better to stop
    // than to overwrite it with a fresh one at shutdown.
    const auto map = appearance::loadMap(params_.map_file);
    slam_.loadMap(map, cameraNames());
    loaded_map_ = true;
    log::info("appearance map ", params_.map_file.string(), ": ", map.states.size(), " states, ",
              map.path.size(), " visits");
  } else if (load) {
    log::info("no appearance map at ", params_.map_file.string(), " yet: starting a new one");
  }
}

std::vector<std::string> AppearanceStage::cameraNames() const {
  std::vector<std::string> names;
  for (const auto& c : params_.cameras) names.push_back(c.name);
  return names;
}

void AppearanceStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  for (const auto& camera : params_.cameras) {
    watchdogs_.push_back(std::make_unique<bus::InputWatchdog>(
        "images on " + camera.image_channel, "image_age_s_" + camera.name, params_.input_timeout_s,
        ": snapshots go on without this camera"));
  }
  watchdogs_.push_back(std::make_unique<bus::InputWatchdog>(
      "odometry on " + params_.odometry_channel, "odometry_age_s", params_.input_timeout_s,
      ": no actions are detected"));
  for (auto& watchdog : watchdogs_) watchdog->begin(ctx.clock.now());
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
  for (size_t i = 0; i < params_.cameras.size(); ++i) {
    // Latest wins: only the frame after an action matters.
    ctx.bus.subscribe<vslam::image_t>(
        params_.cameras[i].image_channel, [this, i](const vslam::image_t& m) { onImage(i, m); }, 2);
  }
}

void AppearanceStage::onOdometry(const vslam::odometry_t& m) {
  watchdogs_.back()->arrived(ctx_->clock.now(), m.utime);
  const Pose2 pose{m.x, m.y, m.theta};
  if (!pose.isFinite()) {
    ctx_->bus.reportMalformed(params_.odometry_channel,
                              "odometry seq " + std::to_string(m.seq) + " has a non-finite pose");
    return;
  }
  if (have_odometry_ && m.utime <= odometry_utime_) {
    ctx_->bus.countDropped();  // duplicate or out of order
    return;
  }
  have_odometry_ = true;
  odometry_utime_ = m.utime;
  odometry_ = pose;
  if (!slam_.initialized() && !pending_) {
    // The first snapshot z_0 is taken where the robot starts.
    reference_ = pose;
    detector_.setReference(m.utime, pose);
    pending_ = Pending{};
    pending_->utime = m.utime;
  } else if (!pending_) {
    if (const auto action = detector_.add(m.utime, pose)) {
      pending_ = Pending{};
      pending_->utime = action->utime;
    }
  }
  if (pending_ && pending_->collected > 0 &&
      toSeconds(m.utime - pending_->utime) > params_.snapshot_timeout_s) {
    ++partial_snapshots_;
    takeSnapshot();
  }
}

bool AppearanceStage::validImage(const config::CameraConfig& camera, const vslam::image_t& msg) {
  const auto error = checkImage(camera, msg);
  if (error) ctx_->bus.reportMalformed(camera.image_channel, *error);
  return !error;
}

bool AppearanceStage::toGray(const config::CameraConfig& camera, const vslam::image_t& msg) {
  const auto error = imageToGray(msg, &gray_);
  if (error) ctx_->bus.reportMalformed(camera.image_channel, *error);
  return !error;
}

void AppearanceStage::onImage(size_t camera, const vslam::image_t& msg) {
  watchdogs_[camera]->arrived(ctx_->clock.now(), msg.utime);
  // Every frame is checked (a bad camera shows in health even between
  // snapshots); only the first frame after an action is used.
  if (!validImage(params_.cameras[camera], msg)) return;
  if (!pending_ || msg.utime < pending_->utime) return;
  if (pending_->histograms.empty()) {
    pending_->histograms.assign(params_.cameras.size(), appearance::Histogram{});
    pending_->image_utime.assign(params_.cameras.size(), 0);
  }
  if (!pending_->histograms[camera].empty()) return;
  if (!toGray(params_.cameras[camera], msg)) return;
  pending_->histograms[camera] = appearance::gradientHistogram(gray_, params_.histogram);
  pending_->image_utime[camera] = msg.utime;
  if (++pending_->collected == static_cast<int>(params_.cameras.size())) takeSnapshot();
}

void AppearanceStage::takeSnapshot() {
  appearance::Snapshot z;
  z.histograms = std::move(pending_->histograms);
  z.histograms.resize(params_.cameras.size());
  z.utime = 0;
  for (const Utime t : pending_->image_utime) z.utime = std::max(z.utime, t);
  z.odometry = odometry_;
  pending_.reset();

  const Utime t0 = monotonicUtime();
  appearance::StepResult r;
  if (!slam_.initialized()) {
    r = slam_.initialize(z);
  } else {
    r = slam_.step(reference_.between(odometry_), z);
  }
  const double seconds = toSeconds(monotonicUtime() - t0);
  reference_ = odometry_;
  detector_.setReference(odometry_utime_, odometry_);
  map_dirty_ = true;
  publishStep(r, z.utime, seconds);
  if (loaded_map_ && map_published_step_ < 0) publishMap(z.utime);
}

void AppearanceStage::publishStep(const appearance::StepResult& r, Utime utime, double seconds) {
  vslam::appearance_hypotheses_t out;
  out.utime = utime;
  out.step = r.step;
  out.best_state_id = r.best().state_id;
  out.best_belief = r.best().belief;
  // Wall-clock timing is informational; in lock-step replay it would make
  // two runs of the same log differ, so it is left 0 there (as health is).
  out.step_seconds = ctx_->mode == bus::ExecutionMode::kLive ? seconds : 0.0;
  out.num_hypotheses = static_cast<int32_t>(r.hypotheses.size());
  for (const auto& h : r.hypotheses) {
    vslam::appearance_hypothesis_t m;
    m.hypothesis_id = h.hypothesis_id;
    m.parent_id = h.parent_id;
    m.state_id = h.state_id;
    m.is_new_state = h.is_new_state;
    m.belief = h.belief;
    m.path_length = h.path_length;
    out.hypotheses.push_back(m);
  }
  ctx_->bus.publish(params_.hypotheses_channel, out);

  // Events: the best hypothesis changes kind, or jumps to another branch.
  const auto& best = r.best();
  std::optional<int8_t> event;
  if (r.lost) {
    event = vslam::appearance_event_t::EVENT_LOST;
  } else if (!best.is_new_state && (!last_best_ || last_best_->is_new_state ||
                                    (best.parent_id != last_best_->hypothesis_id &&
                                     best.state_id != last_best_->state_id))) {
    event = vslam::appearance_event_t::EVENT_RELOCALIZED;
    ++relocalizations_;
  } else if (best.is_new_state && last_best_ && !last_best_->is_new_state) {
    event = vslam::appearance_event_t::EVENT_NEW_STATE;
  }
  if (event) {
    vslam::appearance_event_t e;
    e.utime = utime;
    e.step = r.step;
    e.event = *event;
    e.state_id = best.state_id;
    e.previous_state_id = last_best_ ? last_best_->state_id : -1;
    e.belief = best.belief;
    ctx_->bus.publish(params_.event_channel, e);
    if (*event == vslam::appearance_event_t::EVENT_RELOCALIZED) {
      log::info("step ", r.step, ": re-localized in state ", best.state_id, " (belief ",
                best.belief, ", ", r.hypotheses.size(), " hypotheses)");
    } else if (*event == vslam::appearance_event_t::EVENT_LOST) {
      log::warn("step ", r.step, ": every hypothesis lost; restarted from a new state");
    }
  }
  last_best_ = best;

  ++steps_;
  ++steps_total_;
  const double ms = 1e3 * seconds;
  step_ms_sum_ += ms;
  step_ms_max_ = std::max(step_ms_max_, ms);
}

void AppearanceStage::publishMap(Utime now) {
  const auto map = slam_.bestMap(cameraNames());
  vslam::appearance_map_t out;
  out.utime = now;
  out.seq = map_seq_++;
  for (const auto& s : map.states) {
    vslam::appearance_state_t m;
    m.state_id = s.id;
    m.utime = s.utime;
    m.odom_x = s.odometry.x;
    m.odom_y = s.odometry.y;
    m.odom_theta = s.odometry.theta;
    m.num_cameras = static_cast<int16_t>(map.cameras.size());
    m.num_bins = static_cast<int16_t>(map.bins);
    m.cameras = map.cameras;
    for (const auto& h : s.histograms) {
      // A camera that gave no image for this snapshot: zeros (sum 0, not 1).
      m.histograms.push_back(h.empty() ? std::vector<float>(static_cast<size_t>(map.bins), 0.f)
                                       : h);
    }
    out.states.push_back(std::move(m));
  }
  // Links: every traversal of the path; a repeated one keeps its last action.
  std::map<std::pair<int64_t, int64_t>, size_t> seen;
  for (size_t i = 1; i < map.path.size(); ++i) {
    const auto& v = map.path[i];
    if (!v.link.known) continue;
    vslam::appearance_link_t l;
    l.from_state = map.path[i - 1].state_id;
    l.to_state = v.state_id;
    l.dx = v.link.action.x;
    l.dy = v.link.action.y;
    l.dtheta = v.link.action.theta;
    l.sigma_translation = v.link.model.relative_translation;
    l.sigma_rotation = v.link.model.relative_rotation;
    l.sigma_translation_sqrt = v.link.model.odometry_translation;
    l.sigma_rotation_sqrt = v.link.model.odometry_rotation;
    const auto key = std::make_pair(l.from_state, l.to_state);
    const auto it = seen.find(key);
    if (it != seen.end()) {
      out.links[it->second] = l;
    } else {
      seen[key] = out.links.size();
      out.links.push_back(l);
    }
  }
  out.num_states = static_cast<int32_t>(out.states.size());
  out.num_links = static_cast<int32_t>(out.links.size());
  ctx_->bus.publish(params_.map_channel, out);
  map_published_step_ = slam_.stepCount();
  last_map_publish_ = now;
}

void AppearanceStage::onTimer(Utime now) {
  if (!slam_.initialized()) return;
  if (map_dirty_ && toSeconds(now - last_map_publish_) >= params_.map_period_s) {
    publishMap(now);
    map_dirty_ = false;
  }
  if (params_.map_save && params_.map_save_period_s > 0 &&
      toSeconds(now - last_map_save_) >= params_.map_save_period_s) {
    // A robot standing still does not rewrite its map (flash wears).
    if (last_map_save_ != 0 && steps_total_ != saved_steps_) saveMap(/*periodic=*/true);
    last_map_save_ = now;
  }
}

void AppearanceStage::saveMap(bool periodic) {
  if (!params_.map_save || params_.map_file.empty() || !slam_.initialized()) return;
  try {
    const auto map = slam_.bestMap(cameraNames());
    appearance::saveMap(params_.map_file, map);
    saved_steps_ = steps_total_;
    // Every few seconds while the robot runs: at debug level, not a log line each time.
    log::write(periodic ? log::Level::kDebug : log::Level::kInfo,
               "saved appearance map (" + std::to_string(map.states.size()) + " states) to " +
                   params_.map_file.string());
  } catch (const std::exception& e) {
    log::error("cannot save the appearance map: ", e.what());
  }
}

void AppearanceStage::stop() {
  if (map_dirty_ && ctx_ && slam_.initialized()) publishMap(odometry_utime_);
  saveMap();
}

void AppearanceStage::collectHealth(bus::HealthReport& report) {
  for (auto& watchdog : watchdogs_) watchdog->report(ctx_->clock.now(), report);
  report.add("steps", static_cast<double>(steps_), "count");
  report.add("hypotheses", slam_.initialized() ? static_cast<double>(slam_.hypotheses().size()) : 0,
             "count");
  report.add("states", slam_.initialized() ? static_cast<double>(slam_.best().node->num_states) : 0,
             "count");
  report.add("best_belief", slam_.initialized() ? slam_.best().belief : 0, "");
  report.add("step_ms", steps_ > 0 ? step_ms_sum_ / static_cast<double>(steps_) : 0, "ms");
  report.add("step_ms_max", step_ms_max_, "ms");
  report.add("relocalizations", static_cast<double>(relocalizations_), "count");
  report.add("partial_snapshots", static_cast<double>(partial_snapshots_), "count");
  if (!have_odometry_) report.warn("no odometry: no actions, no snapshots");
  if (pending_ && have_odometry_ &&
      toSeconds(odometry_utime_ - pending_->utime) > params_.snapshot_timeout_s) {
    report.warn("snapshot due but no camera image arrived");
  }
  steps_ = 0;
  step_ms_sum_ = 0;
  step_ms_max_ = 0;
}

void registerAppearance(bus::StageRegistry& registry) {
  registry.add(
      "appearance",
      [](const bus::StageSetup& setup) {
        AppearanceParams params = AppearanceParams::load(setup.params, setup.stack.robot);
        try {
          return std::make_unique<AppearanceStage>(std::move(params));
        } catch (const appearance::MapFileError& e) {
          throw setup.params.error("map_file", e.what());
        } catch (const std::invalid_argument& e) {
          throw setup.params.error("map_file", e.what());
        }
      },
      bus::describeWith(AppearanceParams::table()));
}

}  // namespace vslam::stages
