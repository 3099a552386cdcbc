#pragma once
// Appearance-based SLAM after Lee & Sowmya: a topological map of snapshot
// states joined by links (executed actions), and a tree of path hypotheses
// over it. No LCM; the stage (common/stages/appearance_stage.hpp) feeds it
// actions and snapshots.
//
// Per step, after action u_t and snapshot z_{t+1} (paper section V, Fig. 4):
//   For each path hypothesis p (a leaf of the tree: the path it took and the
//   state it ends in):
//     - Prediction. A child for "the robot is in a state never visited": a
//       new state holding z_{t+1}, linked from p's last state by u_t. A child
//       for each state x_k already on p's path that is reachable: the
//       transitional probability P(x_k | p, u_t) comes from tracing forward
//       in time from x_k's last visit on p along every action since, to the
//       robot's pose now, with first-order propagation of each action's
//       error model (Fig. 3): the robot is back in x_k if that traced pose
//       overlaps x_k,
//         m^2 = r^T (S_trace + S_place)^-1 r,   r = traced pose of the robot in x_k's frame,
//         P(x_k | p, u) = exp(-m^2 / 2) if m^2 <= gate, else no child;
//       S_place is the extent of a state (how far from a snapshot's pose the
//       robot still is "there"). The new state is always possible: P = 1.
//     - Observation. P(z | x_k) = 1 / (chi2(h_z, h_k))^beta (eq. 5), with
//       chi2 the mean over cameras of the chi-square distance of their
//       gradient-orientation histograms (eq. 4), floored at min_chi2. A new
//       state cannot be compared with anything; it is scored as if its
//       distance were new_state_ratio times the median distance between z
//       and the stored states: P(z | new) = 1 / (new_state_ratio median)^beta.
//       (The paper gives no score for it. A fixed distance would mean
//       different things in a home of plain walls, where every view is far
//       from every other, and one of repeated wallpaper, where all are close:
//       the median is this home's "an unrelated place".)
//     - Update. theta(child) = alpha P(z | x) P(x | p, u) theta(p) (eq. 6),
//       alpha normalising over every child of every hypothesis.
//   Children whose belief is below min_belief are pruned (the most believed
//   one always survives), at most max_hypotheses are kept (highest belief
//   first), and the survivors are renormalised.
//
// Tracing through a revisit (an addition to the paper, which traces along
// the path only). A path that re-visits state P at step r claims the robot
// was at P then as at P's previous visit at step q; the loop between adds
// only action noise. So besides the trace along the path, each state within
// revisit_horizon links of P's previous visit is also traced from the robot
// through P: backward in time along the path before q, and forward in time
// along the links after q, each link used in reverse (pose of P's successor
// in P's frame, inverted). Of the two traces of a state the one with the
// smaller covariance (trace of the matrix) is used. Without this, once a
// path has closed a loop, the state after P would be predicted from the
// state's own visit a whole lap ago, and a re-localised hypothesis could
// not follow the map's states step by step.
//
// Relocalization seeds (an addition: the paper's tree only traces forward
// from where a hypothesis believes the robot is, so a robot carried
// elsewhere, or restarted in a saved map, never re-enters its map). Each
// step in which no mapped place explains the snapshot (the most believed
// hypothesis p held the robot to be in a new state, or "a new state" leads
// among this step's children: a robot carried while it followed its map),
// p also gets a child "put down in state x_k" for the
// relocalization_candidates states of its map that look most like the
// snapshot, and clearly more like it than a new place would
// (relocalization_match_ratio), but for those p's trace reaches
// or visited in its last relocalization_recent_visits steps (there the
// trace decides; but a view that jumped, one that looks no more like p's
// last state than a new place would, seeds those too: a carried robot is
// often put down beside the states it made just before), with
//   theta(child) = alpha P(z | x_k) relocalization_prior,
// the prior taken from the whole tree (whose belief sums to 1) rather than
// from p's share of it, which is split among hypotheses that differ only in
// earlier choices; and an unknown link (nothing traces across it). Like the
// dual particles of a mixture proposal: from the next step the seed is
// traced through the map from x_k (as through a revisit), so it gains on
// the others only while the following snapshots keep matching the states
// around x_k; a wrong seed goes on as new states, at its small weight, and
// is pruned by min_belief and max_hypotheses.
//
// Where in a state (an addition). A revisit does not put the robot on the
// state's snapshot pose: views within a state's extent (place_sigma) look
// alike, and a robot driving a metre beside its earlier path is revisiting
// it. Each visit keeps the robot's pose in its state's frame with a
// covariance: for a revisit, the Kalman update of the traced pose
// N(r, S_trace) by "the robot is at the state" N(0, S_place),
//   offset     = S_place (S_trace + S_place)^-1 r,
//   covariance = S_place (S_trace + S_place)^-1 S_trace;
// for a relocalization seed (nothing traced) N(0, S_place). Tracing from a
// revisit starts from that offset, so a robot that keeps to a parallel
// track is predicted there at the next state instead of being charged its
// offset again at every step (and a seed does not lose to the new-state
// hypothesis for being half a metre beside the states it matches). The
// saved path folds the offsets into its links (state to state).
//
// Every view of a state (an addition, for the seeds). A revisit's snapshot is
// kept as another view of the state it revisits (PathNode::snapshot_id): the
// robot passed the place again, a little beside or turned, and saw it
// differently. A relocalization seed matches a state by the best of the
// views the hypothesis' path took there, and puts the robot where that view
// was taken (the visit's offset). The paper's observation of a revisit (the
// state's own snapshot) is unchanged: with the views there too, revisits
// went to states whose views, not whose snapshots, were taken near the
// robot (docs/appearance.md).
//
// Turned around (an addition). With cameras that face each other's way
// (setTurnedCameras: a forward and a backward camera), a robot back at a
// state facing the other way sees with each camera what the other saw
// there. Each state is then also a candidate turned around: the trace is
// tested against the state's pose turned by pi (the same gate and extent),
// P(z | x) compares each camera with the one that faced its way, a seed
// takes whichever orientation looks more like the snapshot, and the
// visit's offset holds the pi.
//
// The most believed place (an addition). Hypotheses that differ only in
// earlier choices agree on where the robot is now, so the belief that it is
// in a state is the sum over the hypotheses ending there (the new state's
// is split among every path that leads to it). The hypotheses are ordered,
// and the first is the one published and whose map is saved, by that sum,
// then by belief.
//
// Each hypothesis implies its own map: the states it created (new-state
// steps) and the links along its path. The map of the most believed
// hypothesis (the first, above) is the map the process publishes and saves.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "appearance/gradient_histogram.hpp"
#include "odometry/pose2.hpp"

namespace vslam::appearance {

// Error model of an executed action (the link's "uncertainty model"): the
// paper's error proportional to the action (3 % in its experiment) plus the
// odometry's random-walk noise (the motion model of common/odometry):
//   var(translation) = (relative_translation d)^2 + odometry_translation^2 d
//   var(rotation)    = (relative_rotation |dtheta|)^2 + odometry_rotation^2 (d + |dtheta|)
// d = distance of the action; translation error along its direction.
struct ActionErrorModel {
  double relative_translation = 0.03;  // per metre travelled
  double relative_rotation = 0.03;     // per radian turned
  double odometry_translation = 0.0;   // m / sqrt(m)
  double odometry_rotation = 0.0;      // rad / sqrt(m + rad)

  Eigen::Matrix3d covariance(const Pose2& action) const;
};

// A link: an action from one state to the next and its error model.
struct Link {
  Pose2 action;  // pose of the `to` state in the frame of the `from` state (odometry)
  ActionErrorModel model;
  bool known = true;  // false: the robot was put down somewhere unknown (no tracing across)
  // Covariance of `action`, from `model`, or given directly (a link
  // through a loaded map, whose uncertainty is that of the traced path).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

// A snapshot state: where it was taken and what it saw (one histogram per camera).
struct State {
  int64_t id = -1;
  int64_t utime = 0;  // microseconds
  Pose2 odometry;     // cumulative odometry at the snapshot (informational)
  std::vector<Histogram> histograms;
};

struct Snapshot {
  int64_t utime = 0;
  Pose2 odometry;
  std::vector<Histogram> histograms;  // per camera, in the cameras' order; empty: camera missing
};

// One node of the path-hypothesis tree: a visit of a state. A leaf is a
// hypothesis; the path from the root to it is the robot path it claims.
struct PathNode {
  std::shared_ptr<PathNode> parent;  // null at the root
  int64_t hypothesis_id = 0;
  int64_t state_id = 0;
  int64_t step = 0;
  bool is_new = true;  // this visit created the state
  Link link;           // from the parent's visit (unused at the root)
  // Where the robot stood at this visit in the frame of its state, and how
  // well that is known: identity for the visit that created the state; for
  // a revisit, the traced pose drawn toward the state by its extent (see
  // "Where in a state" above). The frame that `link` and the children's
  // links start from is the robot's at the visit: the state's composed
  // with this offset.
  Pose2 offset;
  Eigen::Matrix3d offset_covariance = Eigen::Matrix3d::Zero();
  int32_t path_length = 1;  // visits from the root
  int32_t num_states = 1;   // states this path created (its map's size)
  // The snapshot taken at this visit (an id among the stored snapshots): the
  // state's own for the visit that created it; for a revisit, another view
  // of the state (see "Every view of a state" above). -1: none (the revisits
  // of a loaded map, whose snapshots are not saved).
  int64_t snapshot_id = -1;
  // The robot faced the other way from the state's snapshot (a turned revisit).
  bool turned() const { return std::abs(offset.theta) > M_PI / 2; }

  PathNode() = default;
  PathNode(const PathNode&) = delete;
  PathNode& operator=(const PathNode&) = delete;
  ~PathNode();  // releases long parent chains iteratively (no deep recursion)
};

struct Hypothesis {
  std::shared_ptr<PathNode> node;
  double belief = 0;
};

struct SlamParams {
  double beta = 1.0;              // eq. 5 exponent
  double new_state_ratio = 0.5;   // P(z | new) = (new_state_ratio median chi2 to the states)^-beta
  double min_chi2 = 1e-4;         // floor of the distance in eq. 5
  double gate = 11.34;            // max Mahalanobis^2 of a revisit (chi2 3 dof, 99 %)
  double place_sigma_m = 0.25;    // extent of a state, metres
  double place_sigma_rad = 0.17;  // ... and radians
  double min_belief = 0.05;       // pruning threshold
  int max_hypotheses = 20;        // bound
  // Links traced on either side of the state the path last re-visited (see
  // "Tracing through a revisit" above); 0 traces along the path only.
  int revisit_horizon = 10;
  // Global relocalization (an addition, see "Relocalization seeds" above):
  // each step, seeds in the relocalization_candidates states that look most
  // like the snapshot, each with prior relocalization_prior (the probability
  // that the robot was put down there since the last step). 0 candidates:
  // the paper's tree only.
  double relocalization_prior = 0.1;
  int relocalization_candidates = 2;
  // No seed in a state the trace reaches or, unless the view jumped (the
  // snapshot looks no more like the path's last state than a new place
  // would), among the path's last this many visits: there the trace decides.
  int relocalization_recent_visits = 4;
  // A state is seeded only if its chi2 to the snapshot is at most this
  // fraction of the new-state score's (P(z | x_k) >= P(z | new) ratio^-beta):
  // a seed that barely beats "somewhere new" is a look-alike more often
  // than the place (docs/appearance.md).
  double relocalization_match_ratio = 0.5;
  // A seed matches a state by the best of the snapshots the path took there
  // (its own and its revisits'), not by its first alone (see "Every view of
  // a state" above).
  bool relocalization_views = true;
};

// A saved map: the states of the most believed hypothesis and its path in
// time order (the first visit has no link), so that a later run can trace
// through it.
struct SavedMap {
  std::vector<std::string> cameras;
  int bins = 0;
  std::vector<State> states;
  struct Visit {
    int64_t state_id = 0;
    Link link;  // from the previous visit; ignored for the first
  };
  std::vector<Visit> path;
};

struct HypothesisInfo {
  int64_t hypothesis_id = 0;
  int64_t parent_id = -1;
  int64_t state_id = 0;
  bool is_new_state = false;
  double belief = 0;
  int32_t path_length = 0;
};

struct StepResult {
  int64_t step = 0;
  int64_t new_state_id = -1;               // the state the snapshot would be if new
  std::vector<HypothesisInfo> hypotheses;  // most believed place first (see select), then by belief
  int children = 0;                        // before pruning
  int pruned_threshold = 0;                // below min_belief
  int pruned_bound = 0;                    // beyond max_hypotheses
  int revisit_candidates = 0;              // reachable (state, hypothesis) pairs evaluated
  int relocalization_seeds = 0;            // children put down in a look-alike state
  bool lost = false;                       // no finite belief: restarted from a single new state
  const HypothesisInfo& best() const { return hypotheses.front(); }
};

// What decides whether two cameras' histograms can be compared: where the
// camera looks (its optical axis in the robot frame: x forward, y left,
// z up) and how wide it sees.
struct CameraView {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitX();
  double horizontal_fov_rad = 0;
};
// From a camera's rotation robot <- camera (OpenCV axes: z the optical
// axis), its image width and focal length in pixels.
CameraView cameraView(const Eigen::Matrix3d& robot_R_camera, int width_px, double fx_px);

// For AppearanceSlam::setTurnedCameras: turned[i] is the camera whose axis is
// camera i's turned by 180 degrees about the vertical (headings within
// 5 degrees of opposite, elevations within 5 degrees, fields of view within
// 5 %), -1 if none. A forward and a backward camera give {1, 0}.
std::vector<int> turnedCameras(const std::vector<CameraView>& cameras);

class AppearanceSlam {
 public:
  AppearanceSlam(SlamParams params, int num_cameras, int bins);

  // Starts from a saved map (before the first snapshot). The first snapshot
  // then splits into "a new state" and "each state of the map" (global
  // localisation). Throws std::invalid_argument if cameras or bins differ.
  void loadMap(const SavedMap& map, const std::vector<std::string>& cameras);

  bool initialized() const { return !hypotheses_.empty(); }
  // The first snapshot z_0 (paper section VI): one hypothesis, a new state;
  // with a loaded map, also one per map state.
  StepResult initialize(const Snapshot& z);
  // One step: action u_t executed from the last snapshot, then snapshot z.
  StepResult step(const Pose2& action, const Snapshot& z);

  const std::vector<Hypothesis>& hypotheses() const { return hypotheses_; }
  const Hypothesis& best() const { return hypotheses_.front(); }
  const State& state(int64_t id) const;
  int64_t numStatesStored() const { return static_cast<int64_t>(states_.size()); }
  int64_t stepCount() const { return step_; }

  // The map of the most believed hypothesis: its states (in creation order)
  // and path.
  SavedMap bestMap(const std::vector<std::string>& cameras) const;

  // Cameras that face each other's way: turned[i] is the camera that faces
  // where camera i faces once the robot has turned around (-1: none; e.g.
  // {1, 0} for a forward and a backward camera). With one, a state can be
  // revisited facing the other way (see "Turned around" above); empty (the
  // default) or all -1: only as it was seen.
  void setTurnedCameras(const std::vector<int>& turned);

  const SlamParams& params() const { return params_; }
  const ActionErrorModel& actionModel() const { return action_model_; }
  void setActionModel(const ActionErrorModel& model) { action_model_ = model; }

  // Mean chi-square over the cameras both have (eq. 4 per camera); the new
  // snapshot is compared with stored states through this.
  static double distance(const std::vector<Histogram>& a, const std::vector<Histogram>& b);

 private:
  struct Child {
    std::shared_ptr<PathNode> parent;
    int64_t state_id;
    bool is_new;
    Link link;
    double log_weight;
    Pose2 offset = Pose2{};
    Eigen::Matrix3d offset_covariance = Eigen::Matrix3d::Zero();
  };
  int64_t addState(const Snapshot& z);
  void scoreNewState(const Snapshot& z, int64_t new_state);
  double logNew() const;
  // The extent of a state (place_sigma): how far from its snapshot's pose
  // the robot still is "there".
  Eigen::Matrix3d placeCovariance() const;
  // log P(z | x): the robot in the state as its snapshot was taken, or
  // turned around (each camera compared with the one that then faces its way).
  double observationLog(int64_t state_id, const std::vector<Histogram>& z, bool turned = false);
  double turnedDistance(const std::vector<Histogram>& z, const std::vector<Histogram>& state) const;
  // log P(z | x) by every view a path has of its states, for the seeds
  // (relocalization_views): collectViews(path) notes, per state, the best of
  // its revisits' snapshots as seen and turned around; viewLog then gives
  // the larger of that and the state's own snapshot (observationLog).
  void collectViews(const PathNode* path, const std::vector<Histogram>& z);
  // *at (if given): where in the state the robot is if the match holds (where
  // the matching view was taken, facing as the robot does).
  double viewLog(int64_t state_id, const std::vector<Histogram>& z, bool turned,
                 Pose2* at = nullptr);
  // The larger of the two (turned only with turned cameras); *turned says which.
  double bestViewLog(int64_t state_id, const std::vector<Histogram>& z, bool* turned,
                     Pose2* at = nullptr);
  void expand(const Hypothesis& h, const Link& action, const Snapshot& z, int64_t new_state,
              std::vector<Child>* children, int* candidates, std::vector<int64_t>* reachable);
  static double maxLogWeight(const std::vector<Child>& children);  // -inf if none is finite
  // True if "somewhere new" is likelier than every mapped place among this
  // step's children (each place's children summed, as select ranks them).
  static bool newPlaceLeads(const std::vector<Child>& children);
  void seedRelocalizations(const Hypothesis& h, const Snapshot& z,
                           const std::vector<int64_t>& reachable, std::vector<Child>* children);
  StepResult select(std::vector<Child> children, int64_t new_state);

  SlamParams params_;
  ActionErrorModel action_model_;
  int num_cameras_;
  int bins_;
  std::vector<State> states_;  // by id; id -1 marks a hole (loaded maps)
  std::vector<Hypothesis> hypotheses_;
  std::shared_ptr<PathNode> loaded_path_;  // end of a loaded map's path, until the first snapshot
  int64_t step_ = 0;
  int64_t next_hypothesis_ = 0;
  double new_state_chi2_ = 1;  // the distance at which a new state scores, this step
  // Per step: chi-square of the new snapshot against each state (-1: not computed).
  std::vector<double> chi2_cache_;
  std::vector<double> chi2_turned_cache_;  // the same, the robot turned around
  std::vector<int> turned_camera_;         // see setTurnedCameras
  bool can_turn_ = false;
  // Per hypothesis walk: the generation in which a state was last seen, and
  // the best trace of the robot in its frame.
  std::vector<uint32_t> seen_;
  uint32_t generation_ = 0;
  std::vector<Eigen::Matrix3d> trace_cov_;
  std::vector<Pose2> trace_pose_;
  std::vector<const PathNode*> chain_;
  std::vector<Pose2> chain_pose_;
  std::vector<Eigen::Matrix3d> chain_cov_;
  std::vector<int64_t> candidates_;
  // collectViews' notes: valid where view_generation_ matches.
  std::vector<uint32_t> view_seen_;
  std::vector<std::array<double, 2>> view_log_;  // as seen, turned around
  std::vector<std::array<Pose2, 2>> view_at_;    // where in the state that view was taken
  uint32_t view_generation_ = 0;
};

}  // namespace vslam::appearance
