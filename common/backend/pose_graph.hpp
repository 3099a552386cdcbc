#pragma once
// Map correction for the particle filter (docs/backend.md, "Map correction"):
// a pose graph over robot poses at measurement times and the landmarks'
// creation poses, solved with Ceres.
//
// Why: the filter builds each landmark from the particles' pose when it is
// first measured and, with a few hundred particles, keeps none of the
// first lap's path hypotheses by the time the loop closes; the closure then
// corrects the pose, not the map, and later laps follow the first lap's
// drift. A pose graph keeps every constraint and, solved again as
// measurements arrive, corrects the whole map at a loop closure.
//
// Nodes are robot poses in the map frame: one at the first odometry
// reading (fixed: the map's origin), one per measurement time and one per
// landmark creation time. A landmark's pose *is* the robot pose at its
// creation (paper section 3), so a landmark is a node, not a separate
// variable. Edges:
//   odometry    between time-consecutive nodes of one odometry segment,
//               z = odom_a^-1 (+) odom_b, covariance from the motion model
//               over the path driven between them;
//   measurement y between a landmark's creation node and the node at the
//               measurement time, covariance growing with the distance from
//               the creation pose (the landmark's 3-D error is systematic),
//               Huber loss;
//   prior       on the first node of a later segment (after a kidnapping or
//               an odometry reset), weak, at the filter's estimate.
// The residual of an edge a -> b with relative pose z is
//   e = (x_a (+) z)^-1 (+) x_b,
// whitened by the edge's standard deviations.
//
// Bounded size: a robot driving for hours in one home measures the same
// landmarks over and over, and a graph keeping every measurement's node
// grows with the run (a solve at 4,461 nodes took 46 ms). Before each
// solve, the newest `recent_nodes` nodes keep all their measurements; of
// the older measurements each landmark keeps `old_measurements_per_landmark`
// spread over its history (one pass's measurements share one stretch of
// odometry; different passes' do not). An older node left with no measurement
// and no landmark is removed: its odometry edges are replaced by one
// between its neighbours, which the motion model gives over the path driven
// between them (exact for the odometry; what is lost is the dropped
// measurements' information, which repeated laps have made redundant). The
// graph then holds at most 1 + recent_nodes + landmarks x (1 +
// old_measurements_per_landmark) nodes: bounded by the map, not by the run.

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <unordered_map>
#include <vector>

#include "odometry/pose2.hpp"

namespace vslam::backend {

struct PoseGraphParams {
  // Odometry noise, as the motion model: translation m/sqrt(m), rotation
  // rad/sqrt(m driven + rad turned).
  double sigma_translation = 0.03;
  double sigma_rotation = 0.03;
  // Measurement standard deviation: sigma(d) = hypot(sigma_0, k d), d the
  // measured distance from the landmark's creation pose.
  double measurement_sigma_xy_m = 0.01;
  double measurement_sigma_xy_per_m = 0.3;
  double measurement_sigma_theta_rad = 0.6 * M_PI / 180;
  double measurement_sigma_theta_rad_per_m = 0.8 * M_PI / 180;
  // Measurements farther than this from the creation pose are left out.
  double max_measurement_distance_m = 1.5;
  // A landmark's 3-D structure, triangulated from three views a few
  // decimetres apart, has an error of its own that every measurement of it
  // shares: a badly built one is measured consistently 3-11 degrees off,
  // tens of times (generated homes 1271, 1278). Each landmark's frame is its
  // creation pose moved by an offset with this prior, so its measurements,
  // however many, tie the path no tighter than the landmark was built.
  // 0: no offset (the measurements are independent); off in the shipped
  // config, measured but not adopted (docs/backend.md, "Landmark frames").
  double landmark_frame_sigma_xy_m = 0.0;
  double landmark_frame_sigma_theta_rad = 0.0;
  // Robust loss of the measurement edges and its scale, in standard
  // deviations. Huber's influence never falls: one badly built landmark, whose
  // measurements near its creation pose are consistent with each other but
  // wrong by tens of centimetres, bent a generated home's graph by 1.1 m and
  // 20 deg in one solve (0.09 -> 0.68 m ATE, three false kidnap detections).
  // Cauchy's influence falls beyond the scale, so such edges lose weight.
  enum class RobustLoss { kHuber, kCauchy };
  RobustLoss robust_loss = RobustLoss::kCauchy;
  double robust_sigmas = 8.0;
  int max_iterations = 20;
  // A landmark's measurements are tested against the odometry between its
  // creation node and the measurement's node (same odometry segment only):
  // the squared Mahalanobis distance of their difference under the
  // odometry's covariance (this motion model) plus the measurement's. A
  // badly built landmark (structure triangulated from look-alike points:
  // measurements 0.3 m and 8-14 degrees off from the first one on) disagrees
  // with the odometry over the first metre, where the odometry is good to a
  // degree or two; its edges would bend the graph. The edges of a landmark
  // enter a solve only once `min_agreeing` of its measurements passed the
  // test, and never while as many failed it as passed (at least two).
  // odometry_gate_mahalanobis_sq 0: no test, every edge enters.
  double odometry_gate_mahalanobis_sq = 0.0;
  int min_agreeing = 1;
  // Prior of the first node of a segment other than the first.
  double segment_prior_sigma_xy_m = 0.5;
  double segment_prior_sigma_theta_rad = 10 * M_PI / 180;
  // Bounded size (above): nodes kept whole, and older measurements kept per
  // landmark.
  int recent_nodes = 1000;
  int old_measurements_per_landmark = 20;

  void validate() const;  // throws std::invalid_argument naming the bad field
};

// The odometry at a node (for the motion model's covariance between two nodes).
using vslam::OdometryAt;

struct PoseGraphSolveSummary {
  bool solved = false;  // Ceres returned a usable solution (converged or hit the iteration limit)
  int iterations = 0;
  double initial_cost = 0, final_cost = 0;
  double ms = 0;
};

class PoseGraph {
 public:
  explicit PoseGraph(PoseGraphParams params);

  // The node at `utime` (an existing one if there is a node at that time).
  // Nodes may arrive out of time order: a landmark's creation time is known
  // only after later measurements. A new node starts where the odometry from
  // its predecessor in its segment puts it; the first node of a segment
  // starts at `guess` (the first node of all is fixed there: the map origin).
  int addNode(int64_t utime, const OdometryAt& odometry, const Pose2& guess);
  // Nodes from `utime` on start a new odometry segment: no odometry edge
  // joins them to earlier nodes (the robot was moved, or the odometry
  // restarted). `utime` must not be before the previous break.
  void breakOdometry(int64_t utime);

  // The landmark's pose is node `node`'s (its creation pose).
  void addLandmark(int64_t landmark_id, int node);
  // A landmark of a saved map (a back-end started in it): its pose is given
  // and stays, and its measurements tie the nodes to the map. A graph with
  // such landmarks has no fixed node: the map fixes its frame, and its first
  // node (where the filter relocalized) gets the weak segment prior.
  void addMapLandmark(int64_t landmark_id, const Pose2& pose);
  bool hasLandmark(int64_t landmark_id) const { return landmarks_.count(landmark_id) > 0; }
  // The landmark and its measurements leave the graph (its creation node
  // stays, and goes at a prune if nothing else holds it). Returns whether
  // it was there.
  bool removeLandmark(int64_t landmark_id);
  // y: the robot at node `node` in the landmark's frame. Returns false (and
  // adds nothing) for an unknown landmark or beyond max_measurement_distance_m.
  bool addMeasurement(int64_t landmark_id, int node, const Pose2& y);

  // The odometry segment holding `utime` was placed wrong: it began at a
  // relocalization that later evidence corrected (Backend). Its nodes and
  // its prior move by `shift` (map frame: x -> shift (+) x), and the
  // measurements that tied it to landmarks made outside it (those that had
  // put it there) leave; its own landmarks move with it. Returns the number
  // of measurements removed, or nullopt (nothing changed) if the segment
  // holds the graph's fixed origin.
  std::optional<size_t> moveSegment(int64_t utime, const Pose2& shift);

  // Prunes (bounded size, above), then solves.
  PoseGraphSolveSummary solve();
  // The pruning alone (solve() does it first). Node ids of removed nodes are
  // reused by later addNode calls; a landmark's creation node, the origin
  // and the newest recent_nodes nodes are never removed.
  void prune();
  // Takes the poses of `solved`, a copy of this graph solved (off the
  // filter's path, Backend) while this one took new nodes: the nodes of the
  // copy get its poses, and the nodes added since start where the odometry
  // from their predecessor (now moved) puts them, as addNode does. The copy
  // must have been made after this graph's last prune().
  void adoptSolution(const PoseGraph& solved);

  Pose2 nodePose(int node) const;
  int64_t nodeTime(int node) const { return nodes_.at(static_cast<size_t>(node)).utime; }
  // The odometry segment of a node, and the one holding a time.
  int nodeSegment(int node) const { return nodes_.at(static_cast<size_t>(node)).segment; }
  int segmentAt(int64_t utime) const;
  const OdometryAt& nodeOdometry(int node) const {
    return nodes_.at(static_cast<size_t>(node)).odometry;
  }
  std::optional<Pose2> landmarkPose(int64_t landmark_id) const;
  // Landmark ids in increasing order, with their current poses (those the
  // graph estimates: map landmarks stay where the map has them).
  std::vector<std::pair<int64_t, Pose2>> landmarkPoses() const;
  size_t numNodes() const { return by_time_.size(); }
  int64_t numNodesRemoved() const { return nodes_removed_; }
  int64_t numMeasurementsRemoved() const { return measurements_removed_; }
  size_t numLandmarks() const { return landmarks_.size(); }
  size_t numMeasurements() const { return measurements_.size(); }
  // Landmarks whose edges a solve would leave out now (odometry_gate_*):
  // not yet confirmed, or retired (as many measurements against the odometry
  // as with it, at least two).
  size_t numDistrustedLandmarks() const;
  bool trusted(int64_t landmark_id) const;
  bool retired(int64_t landmark_id) const;
  size_t numSegments() const { return segment_start_.size(); }
  const PoseGraphParams& params() const { return params_; }
  // The odometry edges' noise from the next solve on (odometry calibration).
  void setOdometryNoise(double sigma_translation, double sigma_rotation) {
    params_.sigma_translation = sigma_translation;
    params_.sigma_rotation = sigma_rotation;
  }

  // Standard deviations of the odometry between two readings, as the motion
  // model: along-track noise growing with the distance d, the heading's
  // random walk adding cross-track error growing with d^3.
  struct OdometrySigmas {
    double xy, theta;
  };
  OdometrySigmas odometrySigmas(const OdometryAt& a, const OdometryAt& b) const;
  // The same over a path of this length driven and turned.
  OdometrySigmas odometrySigmas(double distance_m, double rotation_rad) const;

 private:
  struct Node {
    int64_t utime = 0;
    int segment = 0;
    OdometryAt odometry;
    double x[3] = {0, 0, 0};  // estimate: x, y, theta (Ceres parameter block)
    Pose2 guess;              // for a segment's first node: its prior
    int landmarks = 0;        // created at this node
    bool alive = false;
  };
  struct Measurement {
    int64_t landmark_id;
    int creation_node;
    int node;
    Pose2 y;
  };
  struct Landmark {
    int creation_node;            // -1: a map landmark
    int agreeing = 0;             // measurements within the odometry gate
    int contradicting = 0;        // and beyond it
    double map_x[3] = {0, 0, 0};  // a map landmark's pose (a constant Ceres block)
    // Its frame in its creation node's (landmark_frame_sigma_*); kept between solves.
    double frame_offset[3] = {0, 0, 0};
  };
  bool framesHaveOffsets() const;
  Pose2 landmarkFrame(const Landmark& l) const;
  PoseGraphParams params_;
  std::vector<Node> nodes_;  // by id; removed ones (alive false) are reused
  std::vector<int> free_ids_;
  int64_t nodes_removed_ = 0, measurements_removed_ = 0;

  std::map<std::pair<int, int64_t>, int> by_time_;  // (segment, utime) -> node
  std::vector<int64_t> segment_start_{
      std::numeric_limits<int64_t>::min()};          // segment k covers [start_k, start_k+1)
  std::unordered_map<int64_t, Landmark> landmarks_;  // node-based: map_x stays put
  size_t map_landmarks_ = 0;
  std::vector<Measurement> measurements_;
};

}  // namespace vslam::backend
