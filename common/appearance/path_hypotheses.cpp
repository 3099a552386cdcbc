#include "appearance/path_hypotheses.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "odometry/motion_model.hpp"
#include "util/statistics.hpp"

namespace vslam::appearance {
namespace {

// The robot's pose relative to a state, traced back one link: given the
// pose R of the robot in the frame of a link's `to` state and the link's
// action a (pose of `to` in the frame of `from`), the robot in `from`'s
// frame is a (+) R, with covariance J_a S_a J_a^T + J_R S_R J_R^T.
struct Trace {
  Pose2 pose;
  Eigen::Matrix3d covariance;

  void prepend(const Pose2& step, const Eigen::Matrix3d& step_covariance) {
    PoseWithCovariance traced(step, step_covariance);
    traced.apply(pose, covariance);
    pose = traced.pose();
    covariance = traced.covariance();
  }
  void prepend(const Link& link) { prepend(link.action, link.covariance); }
};

// Covariance of the inverse of a pose with covariance s.
Eigen::Matrix3d inverseCovariance(const Pose2& p, const Eigen::Matrix3d& s) {
  const double c = std::cos(p.theta), sn = std::sin(p.theta);
  Eigen::Matrix3d j;
  j << -c, -sn, sn * p.x - c * p.y,  //
      sn, -c, c * p.x + sn * p.y,    //
      0, 0, -1;
  return j * s * j.transpose();
}

// The robot's trace in the frame of a visit's state, from its trace in
// the frame the robot had at the visit; and back.
Trace inStateFrame(const PathNode& visit, Trace t) {
  if (!visit.is_new) t.prepend(visit.offset, visit.offset_covariance);
  return t;
}
Trace inVisitFrame(const PathNode& visit, Trace t) {
  if (!visit.is_new) {
    t.prepend(visit.offset.inverse(), inverseCovariance(visit.offset, visit.offset_covariance));
  }
  return t;
}

// Eq. 4 averaged over the cameras both have: camera c of z against camera
// camera_of(c) of the state (-1: none); NaN if none compares.
template <typename CameraOf>
double meanChiSquare(const std::vector<Histogram>& z, const std::vector<Histogram>& state,
                     CameraOf camera_of) {
  double sum = 0;
  int n = 0;
  for (size_t c = 0; c < z.size(); ++c) {
    const int s = camera_of(c);
    if (s < 0 || static_cast<size_t>(s) >= state.size() || z[c].empty() ||
        state[static_cast<size_t>(s)].empty()) {
      continue;
    }
    sum += chiSquare(z[c], state[static_cast<size_t>(s)]);
    ++n;
  }
  return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

CameraView cameraView(const Eigen::Matrix3d& robot_R_camera, int width_px, double fx_px) {
  return {robot_R_camera.col(2), fx_px > 0 ? 2.0 * std::atan(0.5 * width_px / fx_px) : 0.0};
}

std::vector<int> turnedCameras(const std::vector<CameraView>& cameras) {
  constexpr double kTolerance = 5.0 * M_PI / 180.0;
  const auto heading = [](const Eigen::Vector3d& a) { return std::atan2(a.y(), a.x()); };
  const auto elevation = [](const Eigen::Vector3d& a) {
    return std::atan2(a.z(), std::hypot(a.x(), a.y()));
  };
  std::vector<int> turned(cameras.size(), -1);
  for (size_t i = 0; i < cameras.size(); ++i) {
    for (size_t j = 0; j < cameras.size(); ++j) {
      const CameraView& a = cameras[i];
      const CameraView& b = cameras[j];
      if (i == j || a.axis.norm() <= 0 || b.axis.norm() <= 0 || a.horizontal_fov_rad <= 0) {
        continue;
      }
      const bool opposite =
          std::abs(wrapAngle(heading(a.axis) + M_PI - heading(b.axis))) < kTolerance;
      const bool level = std::abs(elevation(a.axis) - elevation(b.axis)) < kTolerance;
      const bool as_wide =
          std::abs(a.horizontal_fov_rad - b.horizontal_fov_rad) < 0.05 * a.horizontal_fov_rad;
      if (opposite && level && as_wide) {
        turned[i] = static_cast<int>(j);
        break;
      }
    }
  }
  return turned;
}

Eigen::Matrix3d ActionErrorModel::covariance(const Pose2& action) const {
  const double d = std::hypot(action.x, action.y);
  const double a = std::abs(action.theta);
  const double var_t = relative_translation * relative_translation * d * d +
                       odometry_translation * odometry_translation * d;
  const double var_r = relative_rotation * relative_rotation * a * a +
                       odometry_rotation * odometry_rotation * (d + a);
  return alongTrackCovariance(action, var_t, var_r);
}

PathNode::~PathNode() {
  // Dropping the last reference to a long path would otherwise recurse once per node.
  std::shared_ptr<PathNode> p = std::move(parent);
  while (p && p.use_count() == 1) {
    std::shared_ptr<PathNode> next = std::move(p->parent);
    p = std::move(next);
  }
}

AppearanceSlam::AppearanceSlam(SlamParams params, int num_cameras, int bins)
    : params_(params), num_cameras_(num_cameras), bins_(bins) {
  if (num_cameras < 1 || bins < 1) {
    throw std::invalid_argument("AppearanceSlam: need at least one camera and one bin");
  }
  if (params_.max_hypotheses < 1) throw std::invalid_argument("max_hypotheses must be >= 1");
}

const State& AppearanceSlam::state(int64_t id) const {
  if (id < 0 || id >= static_cast<int64_t>(states_.size()) ||
      states_[static_cast<size_t>(id)].id != id) {
    throw std::out_of_range("no appearance state " + std::to_string(id));
  }
  return states_[static_cast<size_t>(id)];
}

double AppearanceSlam::distance(const std::vector<Histogram>& a, const std::vector<Histogram>& b) {
  return meanChiSquare(a, b, [](size_t c) { return static_cast<int>(c); });
}

double AppearanceSlam::turnedDistance(const std::vector<Histogram>& z,
                                      const std::vector<Histogram>& state) const {
  return meanChiSquare(
      z, state, [this](size_t c) { return c < turned_camera_.size() ? turned_camera_[c] : -1; });
}

void AppearanceSlam::setTurnedCameras(const std::vector<int>& turned) {
  if (!turned.empty() && static_cast<int>(turned.size()) != num_cameras_) {
    throw std::invalid_argument("setTurnedCameras: " + std::to_string(turned.size()) +
                                " entries for " + std::to_string(num_cameras_) + " cameras");
  }
  for (const int t : turned) {
    if (t < -1 || t >= num_cameras_) {
      throw std::invalid_argument("setTurnedCameras: no camera " + std::to_string(t));
    }
  }
  turned_camera_ = turned;
  can_turn_ = std::any_of(turned.begin(), turned.end(), [](int t) { return t >= 0; });
}

double AppearanceSlam::logNew() const {
  return -params_.beta * std::log(std::max(new_state_chi2_, params_.min_chi2));
}

void AppearanceSlam::scoreNewState(const Snapshot& z, int64_t new_state) {
  // The snapshot's distance to every stored state, kept as this step's
  // observations, and their median.
  std::vector<double> d;
  d.reserve(states_.size());
  for (const auto& s : states_) {
    if (s.id < 0 || s.id == new_state) continue;
    const double c = distance(z.histograms, s.histograms);
    chi2_cache_[static_cast<size_t>(s.id)] = c;
    if (std::isfinite(c)) d.push_back(c);
  }
  // No state to compare with (the first snapshot): the score does not matter.
  new_state_chi2_ = 1.0;
  if (!d.empty()) new_state_chi2_ = params_.new_state_ratio * upperMedian(&d);
  // Nothing to compare (a camera missing on either side): no evidence either way.
  for (double& c : chi2_cache_) {
    if (std::isnan(c)) c = new_state_chi2_;
  }
}

int64_t AppearanceSlam::addState(const Snapshot& z) {
  if (static_cast<int>(z.histograms.size()) != num_cameras_) {
    throw std::invalid_argument("snapshot has " + std::to_string(z.histograms.size()) +
                                " histograms for " + std::to_string(num_cameras_) + " cameras");
  }
  for (const auto& h : z.histograms) {
    if (!h.empty() && static_cast<int>(h.size()) != bins_) {
      throw std::invalid_argument("snapshot histogram has " + std::to_string(h.size()) +
                                  " bins, the map " + std::to_string(bins_));
    }
  }
  State s;
  s.id = static_cast<int64_t>(states_.size());
  s.utime = z.utime;
  s.odometry = z.odometry;
  s.histograms = z.histograms;
  states_.push_back(std::move(s));
  chi2_cache_.assign(states_.size(), -1.0);
  chi2_turned_cache_.assign(states_.size(), -1.0);
  seen_.resize(states_.size(), 0);
  view_seen_.resize(states_.size(), 0);
  view_log_.resize(states_.size());
  view_at_.resize(states_.size());
  trace_pose_.resize(states_.size());
  trace_cov_.resize(states_.size());
  return states_.back().id;
}

double AppearanceSlam::observationLog(int64_t state_id, const std::vector<Histogram>& z,
                                      bool turned) {
  const size_t s = static_cast<size_t>(state_id);
  double& chi2 = turned ? chi2_turned_cache_[s] : chi2_cache_[s];
  if (chi2 < 0) {  // not scored by scoreNewState (it scores every stored state as it was seen)
    chi2 = turned ? turnedDistance(z, states_[s].histograms) : distance(z, states_[s].histograms);
    if (!std::isfinite(chi2)) chi2 = new_state_chi2_;
  }
  return -params_.beta * std::log(std::max(chi2, params_.min_chi2));
}

void AppearanceSlam::collectViews(const PathNode* path, const std::vector<Histogram>& z) {
  ++view_generation_;
  if (!params_.relocalization_views) return;
  for (const PathNode* n = path; n; n = n->parent.get()) {
    if (n->is_new || n->snapshot_id < 0 || n->snapshot_id == n->state_id) continue;
    const size_t s = static_cast<size_t>(n->state_id);
    if (view_seen_[s] != view_generation_) {
      view_seen_[s] = view_generation_;
      view_log_[s] = {-std::numeric_limits<double>::infinity(),
                      -std::numeric_limits<double>::infinity()};
      view_at_[s] = {};
    }
    // The robot now facing the state's way (or turned around) faces this
    // view's way if the visit did too (or did not).
    for (const bool turned : {false, true}) {
      if (turned && !can_turn_) break;
      const bool against_view = turned != n->turned();
      const double obs = observationLog(n->snapshot_id, z, against_view);
      double& best = view_log_[s][turned ? 1 : 0];
      if (obs > best) {
        best = obs;
        // Where the robot stood at that visit, facing the view's way or turned from it.
        view_at_[s][turned ? 1 : 0] =
            against_view ? n->offset.compose(Pose2{0, 0, M_PI}) : n->offset;
      }
    }
  }
}

double AppearanceSlam::bestViewLog(int64_t state_id, const std::vector<Histogram>& z, bool* turned,
                                   Pose2* at) {
  Pose2 at_seen, at_turned;
  const double as_seen = viewLog(state_id, z, false, &at_seen);
  *turned = false;
  if (at) *at = at_seen;
  if (!can_turn_) return as_seen;
  const double turned_around = viewLog(state_id, z, true, &at_turned);
  *turned = turned_around > as_seen;
  if (at && *turned) *at = at_turned;
  return *turned ? turned_around : as_seen;
}

double AppearanceSlam::viewLog(int64_t state_id, const std::vector<Histogram>& z, bool turned,
                               Pose2* at) {
  const double own = observationLog(state_id, z, turned);
  const size_t s = static_cast<size_t>(state_id);
  const int t = turned ? 1 : 0;
  const bool by_view = view_seen_[s] == view_generation_ && view_log_[s][t] > own;
  if (at) *at = by_view ? view_at_[s][t] : Pose2{0, 0, turned ? M_PI : 0.0};
  return by_view ? view_log_[s][t] : own;
}

void AppearanceSlam::loadMap(const SavedMap& map, const std::vector<std::string>& cameras) {
  if (initialized() || !states_.empty()) {
    throw std::logic_error("loadMap: the map must be loaded before the first snapshot");
  }
  if (map.cameras != cameras) throw std::invalid_argument("map was made with other cameras");
  if (map.bins != bins_) {
    throw std::invalid_argument("map has " + std::to_string(map.bins) + " bins, config " +
                                std::to_string(bins_));
  }
  if (map.path.empty()) return;
  int64_t max_id = -1;
  for (const auto& s : map.states) max_id = std::max(max_id, s.id);
  states_.assign(static_cast<size_t>(max_id + 1), State{});
  for (const auto& s : map.states) {
    if (s.id < 0) throw std::invalid_argument("map state with negative id");
    if (static_cast<int>(s.histograms.size()) != num_cameras_) {
      throw std::invalid_argument("map state " + std::to_string(s.id) + " has " +
                                  std::to_string(s.histograms.size()) + " histograms");
    }
    states_[static_cast<size_t>(s.id)] = s;
  }
  std::shared_ptr<PathNode> node;
  std::vector<bool> visited(states_.size(), false);
  for (const auto& v : map.path) {
    if (v.state_id < 0 || v.state_id > max_id || states_[static_cast<size_t>(v.state_id)].id < 0) {
      throw std::invalid_argument("map path visits unknown state " + std::to_string(v.state_id));
    }
    auto n = std::make_shared<PathNode>();
    n->hypothesis_id = -1;
    n->state_id = v.state_id;
    n->step = -1;
    n->is_new = !visited[static_cast<size_t>(v.state_id)];
    n->snapshot_id = n->is_new ? v.state_id : -1;
    visited[static_cast<size_t>(v.state_id)] = true;
    n->link = v.link;
    if (!node) n->link.known = false;
    n->path_length = node ? node->path_length + 1 : 1;
    n->num_states = (node ? node->num_states : 0) + (n->is_new ? 1 : 0);
    n->parent = std::move(node);
    node = std::move(n);
  }
  loaded_path_ = std::move(node);
  chi2_cache_.assign(states_.size(), -1.0);
  chi2_turned_cache_.assign(states_.size(), -1.0);
  seen_.assign(states_.size(), 0);
  view_seen_.assign(states_.size(), 0);
  view_log_.assign(states_.size(), {});
  view_at_.assign(states_.size(), {});
  trace_pose_.resize(states_.size());
  trace_cov_.resize(states_.size());
}

StepResult AppearanceSlam::initialize(const Snapshot& z) {
  if (initialized()) throw std::logic_error("initialize: already initialized");
  const int64_t id = addState(z);
  scoreNewState(z, id);
  std::vector<Child> children;
  Link unknown;
  unknown.known = false;
  children.push_back({loaded_path_, id, true, unknown, 0.0});
  if (loaded_path_) {
    // "At state k of the map": linked from the map path's end by the pose of
    // k in the end's frame, traced through the map (the robot's relation to
    // the map is unknown: every state is equally likely a priori).
    children.front().log_weight = logNew();
    ++generation_;
    Trace t{Pose2{}, Eigen::Matrix3d::Zero()};
    for (const PathNode* n = loaded_path_.get(); n; n = n->parent.get()) {
      if (seen_[static_cast<size_t>(n->state_id)] != generation_) {
        seen_[static_cast<size_t>(n->state_id)] = generation_;
        // As the state was seen, and turned around: the link goes to where
        // the robot stands in the state.
        for (const bool turned : {false, true}) {
          if (turned && !can_turn_) break;
          const Pose2 offset{0, 0, turned ? M_PI : 0.0};
          PoseWithCovariance to_visit(t.pose.inverse(), inverseCovariance(t.pose, t.covariance));
          to_visit.apply(offset, Eigen::Matrix3d::Zero());
          Link link;
          link.action = to_visit.pose();
          link.covariance = to_visit.covariance();
          link.model = action_model_;
          children.push_back({loaded_path_, n->state_id, false, link,
                              observationLog(n->state_id, z.histograms, turned), offset,
                              placeCovariance()});
        }
      }
      if (!n->parent || !n->link.known) break;
      t.prepend(n->link);
    }
  }
  loaded_path_.reset();
  return select(std::move(children), id);
}

void AppearanceSlam::expand(const Hypothesis& h, const Link& action, const Snapshot& z,
                            int64_t new_state, std::vector<Child>* children, int* candidates,
                            std::vector<int64_t>* reachable) {
  const double log_belief = std::log(h.belief);
  children->push_back({h.node, new_state, true, action, log_belief + logNew()});

  // The path back from the leaf, with the robot's traced pose in the frame of
  // each visit's state (forward in time from that visit to now) as far as
  // the links are known: the first `traced` visits. The rest of the path is
  // kept for finding a revisit's previous visit (a relocalization seed's
  // link is unknown, but its state's neighbours in the map are known).
  chain_.clear();
  chain_pose_.clear();
  chain_cov_.clear();
  Trace t{action.action, action.covariance};
  bool tracing = true;
  for (const PathNode* n = h.node.get(); n; n = n->parent.get()) {
    chain_.push_back(n);
    if (!tracing) continue;
    chain_pose_.push_back(t.pose);
    chain_cov_.push_back(t.covariance);
    if (!n->parent || !n->link.known) {
      tracing = false;
      continue;
    }
    t.prepend(n->link);
  }
  const size_t traced = chain_pose_.size();
  // Each state's last visit.
  ++generation_;
  candidates_.clear();
  // The robot's trace in the frame of a visit's state.
  const auto offer = [&](const PathNode& visit, const Trace& in_visit_frame) {
    const Trace in_state = inStateFrame(visit, in_visit_frame);
    const size_t s = static_cast<size_t>(visit.state_id);
    if (seen_[s] != generation_) {
      seen_[s] = generation_;
      trace_pose_[s] = in_state.pose;
      trace_cov_[s] = in_state.covariance;
      candidates_.push_back(visit.state_id);
    } else if (in_state.covariance.trace() < trace_cov_[s].trace()) {
      trace_pose_[s] = in_state.pose;
      trace_cov_[s] = in_state.covariance;
    }
  };
  size_t revisit = chain_.size();  // the most recent revisit on the traced path
  for (size_t i = 0; i < traced; ++i) {
    const size_t s = static_cast<size_t>(chain_[i]->state_id);
    if (seen_[s] != generation_) offer(*chain_[i], Trace{chain_pose_[i], chain_cov_[i]});
    if (revisit == chain_.size() && !chain_[i]->is_new) revisit = i;
  }
  // Through the revisit: from the previous visit of the same state, both ways.
  if (params_.revisit_horizon > 0 && revisit < chain_.size()) {
    const int64_t p = chain_[revisit]->state_id;
    size_t q = revisit + 1;
    while (q < chain_.size() && chain_[q]->state_id != p) ++q;
    if (q < chain_.size()) {
      const size_t horizon = static_cast<size_t>(params_.revisit_horizon);
      // The robot in the frame it had at the previous visit q: through P.
      const Trace at_q = inVisitFrame(
          *chain_[q], inStateFrame(*chain_[revisit], {chain_pose_[revisit], chain_cov_[revisit]}));
      // Backward in time from q: the usual trace, started at P.
      Trace back = at_q;
      for (size_t j = q; j + 1 < chain_.size() && j < q + horizon; ++j) {
        if (!chain_[j]->link.known) break;
        back.prepend(chain_[j]->link);
        offer(*chain_[j + 1], back);
      }
      // Forward in time from q: links used in reverse.
      Trace fwd = at_q;
      for (size_t j = q; j > revisit + 1 && j + horizon > q; --j) {
        const Link& next = chain_[j - 1]->link;  // from chain_[j]'s state to chain_[j-1]'s
        if (!next.known) break;
        Link reverse;
        reverse.action = next.action.inverse();
        reverse.covariance = inverseCovariance(next.action, next.covariance);
        fwd.prepend(reverse);
        offer(*chain_[j - 1], fwd);
      }
    }
  }

  const Eigen::Matrix3d place = placeCovariance();
  for (const int64_t state : candidates_) {
    const size_t s = static_cast<size_t>(state);
    const Pose2& r = trace_pose_[s];
    const Eigen::Matrix3d innovation_inv = (trace_cov_[s] + place).inverse();
    const Eigen::Matrix3d gain_complement = place * innovation_inv;  // I - K
    // The state as it was seen, and turned around (its heading + pi).
    for (const bool turned : {false, true}) {
      if (turned && !can_turn_) break;
      const double facing = turned ? M_PI : 0.0;
      const Eigen::Vector3d v(r.x, r.y, wrapAngle(r.theta - facing));
      const double m2 = v.dot(innovation_inv * v);
      if (m2 > params_.gate) continue;
      ++*candidates;
      // Left to the trace, not seeded: a state the trace reaches with more
      // weight than a seed's prior would give it. (After a carry the trace
      // can still reach a state near the put-down place, but only as an
      // unlikely drive: there the seed is the likelier explanation.)
      if (reachable && log_belief - 0.5 * m2 >= std::log(params_.relocalization_prior))
        reachable->push_back(state);
      // Where the robot is in the state: the trace drawn toward the state's pose.
      const Eigen::Vector3d offset = gain_complement * v;
      Eigen::Matrix3d offset_cov = gain_complement * trace_cov_[s];
      offset_cov = 0.5 * (offset_cov + offset_cov.transpose());
      children->push_back({h.node, state, false, action,
                           log_belief - 0.5 * m2 + observationLog(state, z.histograms, turned),
                           Pose2{offset.x(), offset.y(), wrapAngle(offset.z() + facing)},
                           offset_cov});
    }
  }
}

Eigen::Matrix3d AppearanceSlam::placeCovariance() const {
  Eigen::Matrix3d place = Eigen::Matrix3d::Zero();
  place(0, 0) = place(1, 1) = params_.place_sigma_m * params_.place_sigma_m;
  place(2, 2) = params_.place_sigma_rad * params_.place_sigma_rad;
  return place;
}

void AppearanceSlam::seedRelocalizations(const Hypothesis& h, const Snapshot& z,
                                         const std::vector<int64_t>& reachable,
                                         std::vector<Child>* children) {
  // The states of h's map, but for those its trace reaches likelier than a
  // seed's prior and those of its last relocalization_recent_visits
  // visits: over a few links the trace is reliable, and it alone says
  // whether the robot is back (in a corridor the state a metre back looks
  // like the snapshot, and is not where the robot is). Unless the view
  // jumped: a snapshot that looks no more like h's last state than a new
  // place would is not the next view along a corridor, and a carried robot
  // is often put down beside the states it made just before.
  collectViews(h.node.get(), z.histograms);
  bool last_turned = false;
  const bool view_jumped = bestViewLog(h.node->state_id, z.histograms, &last_turned) <= logNew();
  ++generation_;
  for (const int64_t s : reachable) seen_[static_cast<size_t>(s)] = generation_;
  struct Match {
    double log_likelihood;
    int64_t state;
    bool turned;
    Pose2 at;  // where in the state: where the best view of it was taken
  };
  std::vector<Match> matches;
  // log P(z | x_k) a seed needs: chi2 at most relocalization_match_ratio times the new state's.
  const double log_needed = logNew() - params_.beta * std::log(params_.relocalization_match_ratio);
  int visits = 0;
  for (const PathNode* n = h.node.get(); n; n = n->parent.get()) {
    const size_t s = static_cast<size_t>(n->state_id);
    const bool recent = !view_jumped && visits++ < params_.relocalization_recent_visits;
    if (seen_[s] == generation_) continue;
    seen_[s] = generation_;
    if (recent) continue;
    // As it was seen or turned around, whichever looks more like the snapshot.
    bool turned = false;
    Pose2 at;
    const double obs = bestViewLog(n->state_id, z.histograms, &turned, &at);
    // Only a state that looks clearly more like the snapshot than a new place would.
    if (obs > log_needed) matches.push_back({obs, n->state_id, turned, at});
  }
  if (matches.empty()) return;
  const size_t k = std::min(matches.size(), static_cast<size_t>(params_.relocalization_candidates));
  std::partial_sort(matches.begin(), matches.begin() + static_cast<std::ptrdiff_t>(k),
                    matches.end(), [](const Match& a, const Match& b) {
                      return a.log_likelihood > b.log_likelihood ||
                             (a.log_likelihood == b.log_likelihood && a.state < b.state);
                    });
  // The seed's prior is taken from the whole tree (its belief sums to 1),
  // not from h's share of it: the belief is spread over hypotheses that
  // differ only in earlier choices, and being put down here does not depend
  // on those.
  const double log_prior = std::log(params_.relocalization_prior);
  Link put_down;
  put_down.known = false;  // nothing traces across: the robot was carried or restarted
  // Put down somewhere within the state's extent.
  const Eigen::Matrix3d place = placeCovariance();
  for (size_t i = 0; i < k; ++i) {
    const Match& m = matches[i];
    children->push_back(
        {h.node, m.state, false, put_down, log_prior + m.log_likelihood, m.at, place});
  }
}

StepResult AppearanceSlam::step(const Pose2& action, const Snapshot& z) {
  if (!initialized()) throw std::logic_error("step: initialize with the first snapshot first");
  if (!action.isFinite()) throw std::invalid_argument("step: non-finite action");
  ++step_;
  const int64_t id = addState(z);
  scoreNewState(z, id);
  Link link;
  link.action = action;
  link.model = action_model_;
  link.covariance = action_model_.covariance(action);
  std::vector<Child> children;
  int candidates = 0;
  std::vector<int64_t> reachable;  // likely by the most believed hypothesis' trace
  for (size_t i = 0; i < hypotheses_.size(); ++i) {
    expand(hypotheses_[i], link, z, id, &children, &candidates, i == 0 ? &reachable : nullptr);
  }
  // Seeds only while no mapped place explains the snapshots: the most
  // believed hypothesis held the robot to be somewhere new, or a new place
  // leads this step (a robot that was following its map and was carried
  // seeds at once, not one step later). A robot following its map needs none.
  const size_t seeds_from = children.size();
  if (params_.relocalization_candidates > 0 && params_.relocalization_prior > 0 &&
      (hypotheses_.front().node->is_new || newPlaceLeads(children))) {
    seedRelocalizations(hypotheses_.front(), z, reachable, &children);
  }
  StepResult r = select(std::move(children), id);
  r.relocalization_seeds = static_cast<int>(r.children) - static_cast<int>(seeds_from);
  r.revisit_candidates = candidates;
  return r;
}

double AppearanceSlam::maxLogWeight(const std::vector<Child>& children) {
  double max_lw = -std::numeric_limits<double>::infinity();
  for (const auto& c : children) {
    if (std::isfinite(c.log_weight)) max_lw = std::max(max_lw, c.log_weight);
  }
  return max_lw;
}

bool AppearanceSlam::newPlaceLeads(const std::vector<Child>& children) {
  // The belief of each place this step, as select ranks them: the children
  // that end in the same state summed.
  const double max_lw = maxLogWeight(children);
  if (!std::isfinite(max_lw)) return false;
  std::map<int64_t, double> at_state;
  double new_place = 0;
  for (const auto& c : children) {
    if (!std::isfinite(c.log_weight)) continue;
    const double w = std::exp(c.log_weight - max_lw);
    if (c.is_new) {
      new_place += w;
    } else {
      at_state[c.state_id] += w;
    }
  }
  return std::all_of(at_state.begin(), at_state.end(),
                     [&](const auto& place) { return place.second < new_place; });
}

StepResult AppearanceSlam::select(std::vector<Child> children, int64_t new_state) {
  StepResult r;
  r.step = step_;
  r.new_state_id = new_state;
  r.children = static_cast<int>(children.size());
  const double max_lw = maxLogWeight(children);
  std::vector<std::pair<double, size_t>> order;  // (belief, child)
  if (std::isfinite(max_lw)) {
    double total = 0;
    for (size_t i = 0; i < children.size(); ++i) {
      const double w =
          std::isfinite(children[i].log_weight) ? std::exp(children[i].log_weight - max_lw) : 0.0;
      total += w;
      order.emplace_back(w, i);
    }
    for (auto& o : order) o.first /= total;
    // Highest belief first; ties in creation order (deterministic).
    std::stable_sort(order.begin(), order.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    size_t keep = 1;  // the most believed always survives
    while (keep < order.size() && order[keep].first >= params_.min_belief) ++keep;
    r.pruned_threshold = static_cast<int>(order.size() - keep);
    const size_t bound = static_cast<size_t>(params_.max_hypotheses);
    if (keep > bound) {
      r.pruned_bound = static_cast<int>(keep - bound);
      keep = bound;
    }
    order.resize(keep);
    // Most believed first by where the robot is now: the hypotheses that
    // differ only in earlier choices agree on it, so a place's belief is the
    // sum of theirs; within a place, by belief. (By single belief, a seed
    // could lead while the new place's belief is split among the paths
    // that lead to it.)
    std::map<int64_t, double> at_state;
    for (const auto& [belief, i] : order) at_state[children[i].state_id] += belief;
    std::stable_sort(order.begin(), order.end(), [&](const auto& a, const auto& b) {
      const double pa = at_state[children[a.second].state_id];
      const double pb = at_state[children[b.second].state_id];
      return pa > pb || (pa == pb && a.first > b.first);
    });
  } else {
    // Nothing finite (non-finite input): restart from the snapshot as a new
    // state, not linked to the old map.
    r.lost = true;
    Child c{hypotheses_.empty() ? nullptr : best().node, new_state, true, Link{}, 0.0};
    c.link.known = false;
    children.assign(1, c);
    order.assign(1, {1.0, 0});
  }

  double total = 0;
  for (const auto& o : order) total += o.first;
  std::vector<Hypothesis> next;
  next.reserve(order.size());
  for (const auto& [belief, i] : order) {
    Child& c = children[i];
    auto n = std::make_shared<PathNode>();
    n->hypothesis_id = next_hypothesis_++;
    n->state_id = c.state_id;
    n->step = step_;
    n->is_new = c.is_new;
    n->snapshot_id = new_state;
    n->link = c.link;
    n->offset = c.offset;
    n->offset_covariance = c.offset_covariance;
    n->path_length = c.parent ? c.parent->path_length + 1 : 1;
    n->num_states = (c.parent ? c.parent->num_states : 0) + (c.is_new ? 1 : 0);
    n->parent = c.parent;
    next.push_back({std::move(n), belief / total});
    const PathNode& node = *next.back().node;
    HypothesisInfo info;
    info.hypothesis_id = node.hypothesis_id;
    info.parent_id = node.parent ? node.parent->hypothesis_id : -1;
    info.state_id = node.state_id;
    info.is_new_state = node.is_new;
    info.belief = next.back().belief;
    info.path_length = node.path_length;
    r.hypotheses.push_back(info);
  }
  hypotheses_ = std::move(next);
  return r;
}

SavedMap AppearanceSlam::bestMap(const std::vector<std::string>& cameras) const {
  SavedMap m;
  m.cameras = cameras;
  m.bins = bins_;
  if (!initialized()) return m;
  std::vector<const PathNode*> chain;
  for (const PathNode* n = best().node.get(); n; n = n->parent.get()) chain.push_back(n);
  std::reverse(chain.begin(), chain.end());
  std::vector<bool> added(states_.size(), false);
  const PathNode* previous = nullptr;
  for (const PathNode* n : chain) {
    // A saved visit is at its state: its link goes from state to state, the
    // robot's motion with both visits' offsets folded in,
    // offset_previous (+) action (+) offset^-1.
    Link link = n->link;
    if (previous && link.known && !(previous->is_new && n->is_new)) {
      PoseWithCovariance s(previous->offset, previous->offset_covariance);
      s.apply(link.action, link.covariance);
      s.apply(n->offset.inverse(), inverseCovariance(n->offset, n->offset_covariance));
      link.action = s.pose();
      link.covariance = s.covariance();
    }
    previous = n;
    m.path.push_back({n->state_id, link});
    if (!added[static_cast<size_t>(n->state_id)]) {
      added[static_cast<size_t>(n->state_id)] = true;
      m.states.push_back(states_[static_cast<size_t>(n->state_id)]);
    }
  }
  if (!m.path.empty()) m.path.front().link.known = false;
  return m;
}

}  // namespace vslam::appearance
