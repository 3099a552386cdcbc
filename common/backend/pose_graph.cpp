#include "backend/pose_graph.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vslam::backend {
namespace {

// e = (a (+) z)^-1 (+) b, whitened: the error of b against a moved by z.
struct RelativePoseCost {
  RelativePoseCost(const Pose2& z, double sigma_xy, double sigma_theta)
      : z_(z), inv_xy_(1.0 / sigma_xy), inv_theta_(1.0 / sigma_theta) {}

  template <typename T>
  bool operator()(const T* const a, const T* const b, T* residual) const {
    using std::atan2;
    using std::cos;
    using std::sin;
    const T ca = cos(a[2]), sa = sin(a[2]);
    const T px = a[0] + ca * T(z_.x) - sa * T(z_.y);
    const T py = a[1] + sa * T(z_.x) + ca * T(z_.y);
    const T pt = a[2] + T(z_.theta);
    const T dx = b[0] - px, dy = b[1] - py, dt = b[2] - pt;
    const T cp = cos(pt), sp = sin(pt);
    residual[0] = (cp * dx + sp * dy) * T(inv_xy_);
    residual[1] = (-sp * dx + cp * dy) * T(inv_xy_);
    residual[2] = atan2(sin(dt), cos(dt)) * T(inv_theta_);
    return true;
  }

  static ceres::CostFunction* create(const Pose2& z, double sigma_xy, double sigma_theta) {
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 3, 3, 3>(
        new RelativePoseCost(z, sigma_xy, sigma_theta));
  }

 private:
  Pose2 z_;
  double inv_xy_, inv_theta_;
};

// The same with a's frame first moved by an offset (the landmark's frame in
// its creation node's, PoseGraphParams::landmark_frame_sigma_*):
// e = (a (+) o (+) z)^-1 (+) b.
struct OffsetRelativePoseCost {
  OffsetRelativePoseCost(const Pose2& z, double sigma_xy, double sigma_theta)
      : relative_(z, sigma_xy, sigma_theta) {}

  template <typename T>
  bool operator()(const T* const a, const T* const o, const T* const b, T* residual) const {
    using std::cos;
    using std::sin;
    const T ca = cos(a[2]), sa = sin(a[2]);
    const T frame[3] = {a[0] + ca * o[0] - sa * o[1], a[1] + sa * o[0] + ca * o[1], a[2] + o[2]};
    return relative_(frame, b, residual);
  }

  static ceres::CostFunction* create(const Pose2& z, double sigma_xy, double sigma_theta) {
    return new ceres::AutoDiffCostFunction<OffsetRelativePoseCost, 3, 3, 3, 3>(
        new OffsetRelativePoseCost(z, sigma_xy, sigma_theta));
  }

 private:
  RelativePoseCost relative_;
};

// A pose prior: e = x - p (theta wrapped), whitened.
struct PosePriorCost {
  PosePriorCost(const Pose2& p, double sigma_xy, double sigma_theta)
      : p_(p), inv_xy_(1.0 / sigma_xy), inv_theta_(1.0 / sigma_theta) {}

  template <typename T>
  bool operator()(const T* const x, T* residual) const {
    using std::atan2;
    using std::cos;
    using std::sin;
    const T dt = x[2] - T(p_.theta);
    residual[0] = (x[0] - T(p_.x)) * T(inv_xy_);
    residual[1] = (x[1] - T(p_.y)) * T(inv_xy_);
    residual[2] = atan2(sin(dt), cos(dt)) * T(inv_theta_);
    return true;
  }

 private:
  Pose2 p_;
  double inv_xy_, inv_theta_;
};

void setPose(double* x, const Pose2& p) {
  x[0] = p.x;
  x[1] = p.y;
  x[2] = p.theta;
}

ceres::SparseLinearAlgebraLibraryType sparseLibrary() {
  return ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)
             ? ceres::SUITE_SPARSE
             : ceres::EIGEN_SPARSE;
}

}  // namespace

void PoseGraphParams::validate() const {
  auto bad = [](const std::string& field) {
    throw std::invalid_argument("pose graph: " + field + " out of range");
  };
  if (!(sigma_translation > 0)) bad("sigma_translation");
  if (!(sigma_rotation > 0)) bad("sigma_rotation");
  if (!(measurement_sigma_xy_m > 0)) bad("measurement_sigma_xy_m");
  if (!(measurement_sigma_xy_per_m >= 0)) bad("measurement_sigma_xy_per_m");
  if (!(measurement_sigma_theta_rad > 0)) bad("measurement_sigma_theta_rad");
  if (!(measurement_sigma_theta_rad_per_m >= 0)) bad("measurement_sigma_theta_rad_per_m");
  if (!(max_measurement_distance_m > 0)) bad("max_measurement_distance_m");
  if (!(landmark_frame_sigma_xy_m >= 0)) bad("landmark_frame_sigma_xy_m");
  if (!(landmark_frame_sigma_theta_rad >= 0)) bad("landmark_frame_sigma_theta_rad");
  if ((landmark_frame_sigma_xy_m > 0) != (landmark_frame_sigma_theta_rad > 0))
    bad("landmark_frame_sigma_xy_m and landmark_frame_sigma_theta_rad (both 0 or both > 0)");
  if (!(robust_sigmas > 0)) bad("robust_sigmas");
  if (max_iterations < 1) bad("max_iterations");
  if (!(odometry_gate_mahalanobis_sq >= 0)) bad("odometry_gate_mahalanobis_sq");
  if (min_agreeing < 0) bad("min_agreeing");
  if (!(segment_prior_sigma_xy_m > 0)) bad("segment_prior_sigma_xy_m");
  if (!(segment_prior_sigma_theta_rad > 0)) bad("segment_prior_sigma_theta_rad");
  if (recent_nodes < 2) bad("recent_nodes");
  if (old_measurements_per_landmark < 0) bad("old_measurements_per_landmark");
}

PoseGraph::PoseGraph(PoseGraphParams params) : params_((params.validate(), params)) {}

int PoseGraph::segmentAt(int64_t utime) const {
  int k = static_cast<int>(segment_start_.size()) - 1;
  while (k > 0 && utime < segment_start_[static_cast<size_t>(k)]) --k;
  return k;
}

void PoseGraph::breakOdometry(int64_t utime) {
  if (utime < segment_start_.back())
    throw std::invalid_argument("pose graph: odometry break before the previous one");
  if (utime == segment_start_.back()) return;
  segment_start_.push_back(utime);
}

int PoseGraph::addNode(int64_t utime, const OdometryAt& odometry, const Pose2& guess) {
  const int segment = segmentAt(utime);
  const auto key = std::make_pair(segment, utime);
  const auto found = by_time_.find(key);
  if (found != by_time_.end()) return found->second;

  Node n;
  n.utime = utime;
  n.segment = segment;
  n.odometry = odometry;
  // Start where the odometry from a neighbour of the same segment puts it.
  const auto next = by_time_.lower_bound(key);
  Pose2 start = guess;
  if (next != by_time_.begin() && std::prev(next)->first.first == segment) {
    const Node& a = nodes_[static_cast<size_t>(std::prev(next)->second)];
    start = Pose2{a.x[0], a.x[1], a.x[2]}.compose(a.odometry.pose.between(odometry.pose));
  } else if (next != by_time_.end() && next->first.first == segment) {
    const Node& b = nodes_[static_cast<size_t>(next->second)];
    start = Pose2{b.x[0], b.x[1], b.x[2]}.compose(odometry.pose.between(b.odometry.pose).inverse());
  }
  setPose(n.x, start);
  n.guess = start;
  n.alive = true;
  int id = 0;
  if (free_ids_.empty()) {
    id = static_cast<int>(nodes_.size());
    nodes_.push_back(n);
  } else {
    id = free_ids_.back();
    free_ids_.pop_back();
    nodes_[static_cast<size_t>(id)] = n;
  }
  by_time_.emplace(key, id);
  return id;
}

void PoseGraph::prune() {
  if (by_time_.size() <= static_cast<size_t>(params_.recent_nodes)) return;
  // Nodes before `cutoff` (in (segment, time) order, which is time order)
  // are old.
  auto cutoff = by_time_.end();
  std::advance(cutoff, -params_.recent_nodes);
  const std::pair<int, int64_t> old_before = cutoff->first;
  auto isOld = [&](int node) {
    const Node& n = nodes_[static_cast<size_t>(node)];
    return std::make_pair(n.segment, n.utime) < old_before;
  };

  // Of each landmark's old measurements, ones spread over its history stay:
  // measurements of one pass are correlated (one stretch of odometry), those
  // of different passes are not. The measurement whose neighbours in time
  // are closest goes first; the oldest and the newest stay.
  std::unordered_map<int64_t, std::vector<size_t>> old_by_landmark;
  for (size_t i = 0; i < measurements_.size(); ++i)
    if (isOld(measurements_[i].node)) old_by_landmark[measurements_[i].landmark_id].push_back(i);
  std::vector<char> drop(measurements_.size(), 0);
  const auto keep = static_cast<size_t>(params_.old_measurements_per_landmark);
  auto timeOf = [&](size_t m) { return nodes_[static_cast<size_t>(measurements_[m].node)].utime; };
  for (auto& [id, indices] : old_by_landmark) {
    if (indices.size() <= keep) continue;
    std::sort(indices.begin(), indices.end(),
              [&](size_t a, size_t b) { return timeOf(a) < timeOf(b); });
    if (keep < 2) {
      for (size_t k = 0; k + keep < indices.size(); ++k) drop[indices[k]] = 1;
      continue;
    }
    while (indices.size() > keep) {
      size_t worst = 1;
      int64_t narrowest = std::numeric_limits<int64_t>::max();
      for (size_t k = 1; k + 1 < indices.size(); ++k) {
        const int64_t span = timeOf(indices[k + 1]) - timeOf(indices[k - 1]);
        if (span < narrowest) narrowest = span, worst = k;
      }
      drop[indices[worst]] = 1;
      indices.erase(indices.begin() + static_cast<std::ptrdiff_t>(worst));
    }
  }
  std::vector<char> measured(nodes_.size(), 0);
  size_t kept = 0;
  for (size_t i = 0; i < measurements_.size(); ++i) {
    if (drop[i]) continue;
    measured[static_cast<size_t>(measurements_[i].node)] = 1;
    measurements_[kept++] = measurements_[i];
  }
  measurements_removed_ += static_cast<int64_t>(measurements_.size() - kept);
  measurements_.resize(kept);

  // Old nodes with nothing left on them go; the odometry edge is then
  // between their neighbours. A segment's first node carries the segment's
  // prior: the next node inherits it, moved by the odometry between them.
  const auto origin = by_time_.begin();
  for (auto it = std::next(origin); it != cutoff;) {
    const int id = it->second;
    Node& n = nodes_[static_cast<size_t>(id)];
    if (n.landmarks > 0 || measured[static_cast<size_t>(id)]) {
      ++it;
      continue;
    }
    const bool first_of_segment = std::prev(it)->first.first != n.segment;
    const auto next = std::next(it);
    if (first_of_segment && next != by_time_.end() && next->first.first == n.segment) {
      Node& successor = nodes_[static_cast<size_t>(next->second)];
      successor.guess = n.guess.compose(n.odometry.pose.between(successor.odometry.pose));
    }
    n.alive = false;
    free_ids_.push_back(id);
    ++nodes_removed_;
    it = by_time_.erase(it);
  }
}

void PoseGraph::addLandmark(int64_t landmark_id, int node) {
  if (node < 0 || static_cast<size_t>(node) >= nodes_.size() ||
      !nodes_[static_cast<size_t>(node)].alive)
    throw std::invalid_argument("pose graph: landmark at an unknown node");
  if (landmarks_.emplace(landmark_id, Landmark{node}).second)
    ++nodes_[static_cast<size_t>(node)].landmarks;
}

bool PoseGraph::removeLandmark(int64_t landmark_id) {
  const auto it = landmarks_.find(landmark_id);
  if (it == landmarks_.end()) return false;
  if (it->second.creation_node >= 0)
    --nodes_[static_cast<size_t>(it->second.creation_node)].landmarks;
  else
    --map_landmarks_;
  landmarks_.erase(it);
  measurements_.erase(
      std::remove_if(measurements_.begin(), measurements_.end(),
                     [&](const Measurement& m) { return m.landmark_id == landmark_id; }),
      measurements_.end());
  return true;
}

std::optional<size_t> PoseGraph::moveSegment(int64_t utime, const Pose2& shift) {
  const int segment = segmentAt(utime);
  if (segment == 0 && map_landmarks_ == 0) return std::nullopt;
  for (const auto& [key, id] : by_time_) {
    if (key.first != segment) continue;
    Node& n = nodes_[static_cast<size_t>(id)];
    setPose(n.x, shift.compose(Pose2{n.x[0], n.x[1], n.x[2]}));
    n.guess = shift.compose(n.guess);
  }
  auto inSegment = [&](int node) {
    return node >= 0 && nodes_[static_cast<size_t>(node)].segment == segment;
  };
  const size_t before = measurements_.size();
  measurements_.erase(std::remove_if(measurements_.begin(), measurements_.end(),
                                     [&](const Measurement& m) {
                                       return inSegment(m.node) && !inSegment(m.creation_node);
                                     }),
                      measurements_.end());
  const size_t removed = before - measurements_.size();
  measurements_removed_ += static_cast<int64_t>(removed);
  return removed;
}

void PoseGraph::addMapLandmark(int64_t landmark_id, const Pose2& pose) {
  if (!pose.isFinite())
    throw std::invalid_argument("pose graph: a map landmark's pose is not finite");
  Landmark l{-1};
  l.agreeing = std::max(1, params_.min_agreeing);  // the map is trusted, as the filter's prior
  setPose(l.map_x, pose);
  if (landmarks_.emplace(landmark_id, l).second) ++map_landmarks_;
}

PoseGraph::OdometrySigmas PoseGraph::odometrySigmas(const OdometryAt& a,
                                                    const OdometryAt& b) const {
  return odometrySigmas(b.distance_m - a.distance_m, b.rotation_rad - a.rotation_rad);
}

PoseGraph::OdometrySigmas PoseGraph::odometrySigmas(double distance_m, double rotation_rad) const {
  const double d = std::abs(distance_m);
  const double r = std::abs(rotation_rad);
  const double st2 = params_.sigma_translation * params_.sigma_translation;
  const double sr2 = params_.sigma_rotation * params_.sigma_rotation;
  // Small floors keep a standing robot's edge well-conditioned.
  return {std::sqrt(st2 * d + sr2 * d * d * d / 3.0 + 1e-6), std::sqrt(sr2 * (d + r) + 1e-8)};
}

bool PoseGraph::addMeasurement(int64_t landmark_id, int node, const Pose2& y) {
  const auto it = landmarks_.find(landmark_id);
  if (it == landmarks_.end() || node < 0 || static_cast<size_t>(node) >= nodes_.size() ||
      !nodes_[static_cast<size_t>(node)].alive)
    return false;
  if (!y.isFinite() || std::hypot(y.x, y.y) > params_.max_measurement_distance_m) return false;
  Landmark& l = it->second;
  if (l.creation_node == node) return false;  // a measurement at the creation time says nothing
  if (l.creation_node < 0) {  // a map landmark: no creation odometry to gate it with
    measurements_.push_back({landmark_id, l.creation_node, node, y});
    return true;
  }
  const Node& a = nodes_[static_cast<size_t>(l.creation_node)];
  const Node& b = nodes_[static_cast<size_t>(node)];
  if (params_.odometry_gate_mahalanobis_sq > 0 && a.segment == b.segment) {
    const OdometrySigmas o = odometrySigmas(a.odometry, b.odometry);
    const double d = std::hypot(y.x, y.y);
    const double m_xy =
        std::hypot(params_.measurement_sigma_xy_m, params_.measurement_sigma_xy_per_m * d);
    const double m_theta = std::hypot(params_.measurement_sigma_theta_rad,
                                      params_.measurement_sigma_theta_rad_per_m * d);
    const Pose2 e = a.odometry.pose.between(b.odometry.pose).between(y);
    const double d2 = (e.x * e.x + e.y * e.y) / (o.xy * o.xy + m_xy * m_xy) +
                      e.theta * e.theta / (o.theta * o.theta + m_theta * m_theta);
    (d2 <= params_.odometry_gate_mahalanobis_sq ? l.agreeing : l.contradicting) += 1;
  }
  measurements_.push_back({landmark_id, l.creation_node, node, y});
  return true;
}

bool PoseGraph::trusted(int64_t landmark_id) const {
  if (params_.odometry_gate_mahalanobis_sq <= 0) return true;
  const auto it = landmarks_.find(landmark_id);
  return it != landmarks_.end() && it->second.agreeing >= params_.min_agreeing &&
         !retired(landmark_id);
}

bool PoseGraph::retired(int64_t landmark_id) const {
  if (params_.odometry_gate_mahalanobis_sq <= 0) return false;
  const auto it = landmarks_.find(landmark_id);
  if (it == landmarks_.end()) return false;
  const Landmark& l = it->second;
  return l.contradicting >= 2 && l.contradicting >= l.agreeing;
}

size_t PoseGraph::numDistrustedLandmarks() const {
  size_t n = 0;
  for (const auto& [id, l] : landmarks_) n += !trusted(id);
  return n;
}

PoseGraphSolveSummary PoseGraph::solve() {
  PoseGraphSolveSummary summary;
  if (by_time_.size() < 2) return summary;
  const auto t0 = std::chrono::steady_clock::now();
  prune();
  ceres::Problem::Options problem_options;
  problem_options.enable_fast_removal = false;
  ceres::Problem problem(problem_options);
  const PoseGraphParams& p = params_;

  // Odometry edges between time-consecutive nodes of a segment; the first
  // node of segment 0 is the map origin, later segments' first nodes get a
  // weak prior where they started.
  Node* prev = nullptr;
  for (const auto& [key, id] : by_time_) {
    Node& n = nodes_[static_cast<size_t>(id)];
    problem.AddParameterBlock(n.x, 3);
    if (prev == nullptr || prev->segment != n.segment) {
      if (n.segment == 0 && map_landmarks_ == 0) {
        problem.SetParameterBlockConstant(n.x);
      } else {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<PosePriorCost, 3, 3>(new PosePriorCost(
                n.guess, p.segment_prior_sigma_xy_m, p.segment_prior_sigma_theta_rad)),
            nullptr, n.x);
      }
    } else {
      const Pose2 z = prev->odometry.pose.between(n.odometry.pose);
      const OdometrySigmas o = odometrySigmas(prev->odometry, n.odometry);
      problem.AddResidualBlock(RelativePoseCost::create(z, o.xy, o.theta), nullptr, prev->x, n.x);
    }
    prev = &n;
  }
  const bool offsets = framesHaveOffsets();
  for (const Measurement& m : measurements_) {
    if (!trusted(m.landmark_id)) continue;
    double* a = nullptr;
    double* offset = nullptr;
    if (m.creation_node >= 0) {
      a = nodes_[static_cast<size_t>(m.creation_node)].x;
      if (offsets) {
        offset = landmarks_.at(m.landmark_id).frame_offset;
        if (!problem.HasParameterBlock(offset))
          problem.AddResidualBlock(
              new ceres::AutoDiffCostFunction<PosePriorCost, 3, 3>(new PosePriorCost(
                  Pose2{}, p.landmark_frame_sigma_xy_m, p.landmark_frame_sigma_theta_rad)),
              nullptr, offset);
      }
    } else {
      a = landmarks_.at(m.landmark_id).map_x;
      problem.AddParameterBlock(a, 3);
      problem.SetParameterBlockConstant(a);
    }
    Node& b = nodes_[static_cast<size_t>(m.node)];
    const double d = std::hypot(m.y.x, m.y.y);
    const double sigma_xy = std::hypot(p.measurement_sigma_xy_m, p.measurement_sigma_xy_per_m * d);
    const double sigma_theta =
        std::hypot(p.measurement_sigma_theta_rad, p.measurement_sigma_theta_rad_per_m * d);
    ceres::LossFunction* loss = nullptr;  // owned by the problem
    if (p.robust_loss == PoseGraphParams::RobustLoss::kCauchy) {
      loss = new ceres::CauchyLoss(p.robust_sigmas);
    } else {
      loss = new ceres::HuberLoss(p.robust_sigmas);
    }
    if (offset != nullptr) {
      problem.AddResidualBlock(OffsetRelativePoseCost::create(m.y, sigma_xy, sigma_theta), loss, a,
                               offset, b.x);
    } else {
      problem.AddResidualBlock(RelativePoseCost::create(m.y, sigma_xy, sigma_theta), loss, a, b.x);
    }
  }

  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.sparse_linear_algebra_library_type = sparseLibrary();
  options.max_num_iterations = p.max_iterations;
  options.num_threads = 1;  // deterministic, and the particle filter has the cores
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary s;
  ceres::Solve(options, &problem, &s);
  summary.solved = s.IsSolutionUsable();
  summary.iterations = static_cast<int>(s.iterations.size());
  summary.initial_cost = s.initial_cost;
  summary.final_cost = s.final_cost;
  summary.ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  for (const auto& [key, id] : by_time_) {
    double* x = nodes_[static_cast<size_t>(id)].x;
    x[2] = wrapAngle(x[2]);
  }
  return summary;
}

void PoseGraph::adoptSolution(const PoseGraph& solved) {
  if (framesHaveOffsets()) {  // no per-landmark work on the update path when off
    for (auto& [id, l] : landmarks_) {
      const auto it = solved.landmarks_.find(id);
      if (it != solved.landmarks_.end() && it->second.creation_node == l.creation_node)
        std::copy(it->second.frame_offset, it->second.frame_offset + 3, l.frame_offset);
    }
  }
  const Node* prev = nullptr;
  for (const auto& [key, id] : by_time_) {
    Node& n = nodes_[static_cast<size_t>(id)];
    const auto i = static_cast<size_t>(id);
    const bool in_copy = i < solved.nodes_.size() && solved.nodes_[i].alive &&
                         solved.nodes_[i].utime == n.utime && solved.nodes_[i].segment == n.segment;
    if (in_copy) {
      std::copy(solved.nodes_[i].x, solved.nodes_[i].x + 3, n.x);
    } else if (prev != nullptr && prev->segment == n.segment) {
      setPose(n.x, Pose2{prev->x[0], prev->x[1], prev->x[2]}.compose(
                       prev->odometry.pose.between(n.odometry.pose)));
    }
    prev = &n;
  }
}

Pose2 PoseGraph::nodePose(int node) const {
  const Node& n = nodes_.at(static_cast<size_t>(node));
  return {n.x[0], n.x[1], n.x[2]};
}

std::optional<Pose2> PoseGraph::landmarkPose(int64_t landmark_id) const {
  const auto it = landmarks_.find(landmark_id);
  if (it == landmarks_.end()) return std::nullopt;
  return landmarkFrame(it->second);
}

bool PoseGraph::framesHaveOffsets() const { return params_.landmark_frame_sigma_xy_m > 0; }

Pose2 PoseGraph::landmarkFrame(const Landmark& l) const {
  if (l.creation_node < 0) return {l.map_x[0], l.map_x[1], l.map_x[2]};
  const Pose2 creation = nodePose(l.creation_node);
  if (!framesHaveOffsets()) return creation;
  return creation.compose({l.frame_offset[0], l.frame_offset[1], l.frame_offset[2]});
}

std::vector<std::pair<int64_t, Pose2>> PoseGraph::landmarkPoses() const {
  std::vector<std::pair<int64_t, Pose2>> out;
  out.reserve(landmarks_.size());
  for (const auto& [id, l] : landmarks_)
    if (l.creation_node >= 0) out.emplace_back(id, landmarkFrame(l));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

}  // namespace vslam::backend
