#include "landmark_db/landmark_database.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "util/angles.hpp"

namespace vslam::landmark_db {
namespace {

constexpr double kPoseWriteThresholdM = 0.01;  // smaller position changes are not written

bool finite(const std::vector<float>& v) {
  return std::all_of(v.begin(), v.end(), [](float f) { return std::isfinite(f); });
}

}  // namespace

std::string LandmarkStructure::validate() const {
  if (num_points <= 0) return "no points";
  if (num_points > kMaxLandmarkPoints) {
    return std::to_string(num_points) + " points, more than the " +
           std::to_string(kMaxLandmarkPoints) + " a landmark may have";
  }
  if (descriptor_size <= 0 || descriptor_size > 1024) {
    return "descriptor size " + std::to_string(descriptor_size);
  }
  const size_t n = static_cast<size_t>(num_points);
  if (points.size() != 3 * n || keypoints.size() != 2 * n || scales.size() != n ||
      orientations.size() != n || descriptors.size() != n * static_cast<size_t>(descriptor_size)) {
    return "array sizes disagree with num_points " + std::to_string(num_points);
  }
  if (!finite(points) || !finite(keypoints) || !finite(scales) || !finite(orientations)) {
    return "non-finite point or feature values";
  }
  return "";
}

uint64_t LandmarkStructure::fingerprint() const {
  uint64_t h = 1469598103934665603ULL;
  for (uint8_t c : descriptors) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

const char* toString(ChangeOp op) {
  switch (op) {
    case ChangeOp::kCreated:
      return "created";
    case ChangeOp::kUpdated:
      return "updated";
    case ChangeOp::kRemoved:
      return "removed";
    case ChangeOp::kEvicted:
      return "evicted";
    case ChangeOp::kLoaded:
      return "loaded";
  }
  return "?";
}

double sharedDescriptorFraction(const LandmarkStructure& a, const LandmarkStructure& b,
                                double ratio) {
  const LandmarkStructure& small = a.num_points <= b.num_points ? a : b;
  const LandmarkStructure& large = a.num_points <= b.num_points ? b : a;
  if (small.num_points <= 0 || large.num_points < 2 ||
      small.descriptor_size != large.descriptor_size) {
    return 0;
  }
  const size_t d = static_cast<size_t>(small.descriptor_size);
  const double r2 = ratio * ratio;
  int shared = 0;
  for (int i = 0; i < small.num_points; ++i) {
    const uint8_t* p = &small.descriptors[static_cast<size_t>(i) * d];
    int64_t best = std::numeric_limits<int64_t>::max(), second = best;
    for (int j = 0; j < large.num_points; ++j) {
      const uint8_t* q = &large.descriptors[static_cast<size_t>(j) * d];
      int64_t dist = 0;
      for (size_t k = 0; k < d; ++k) {
        const int64_t e = static_cast<int64_t>(p[k]) - static_cast<int64_t>(q[k]);
        dist += e * e;
      }
      if (dist < best) {
        second = best;
        best = dist;
      } else if (dist < second) {
        second = dist;
      }
    }
    if (static_cast<double>(best) < r2 * static_cast<double>(second)) ++shared;
  }
  return static_cast<double>(shared) / static_cast<double>(small.num_points);
}

LandmarkDatabase::LandmarkDatabase(std::unique_ptr<LandmarkStore> store, DatabaseParams params)
    : store_(std::move(store)), params_(std::move(params)) {
  revision_ = store_->revision();
  for (auto& i : store_->loadAllInfo()) infos_.emplace(i.id, std::move(i));
  updateActive(true, false);
}

const LandmarkInfo* LandmarkDatabase::info(int64_t id) const {
  const auto it = infos_.find(id);
  return it == infos_.end() ? nullptr : &it->second;
}

StructurePtr LandmarkDatabase::structure(int64_t id) const {
  const auto it = active_.find(id);
  return it == active_.end() ? nullptr : it->second.structure;
}

std::vector<int64_t> LandmarkDatabase::activeIds() const {
  std::vector<int64_t> ids;
  ids.reserve(active_.size());
  for (const auto& [id, a] : active_) ids.push_back(id);
  return ids;
}

std::vector<int64_t> LandmarkDatabase::activeChangedSince(int64_t revision) const {
  std::vector<int64_t> ids;
  for (const auto& [id, a] : active_) {
    const auto it = infos_.find(id);
    const int64_t last = std::max(a.revision, it == infos_.end() ? 0 : it->second.revision);
    if (last > revision) ids.push_back(id);
  }
  return ids;
}

size_t LandmarkDatabase::heldBytes() const {
  size_t bytes = infos_.size() * (sizeof(LandmarkInfo) + 64);
  for (const auto& [id, a] : active_) bytes += a.structure->bytes();
  return bytes;
}

size_t LandmarkDatabase::budgetBytes() const {
  return static_cast<size_t>(params_.segmentation.memory_budget_mb * 1024 * 1024);
}

void LandmarkDatabase::activate(int64_t id, StructurePtr st, int64_t revision) {
  const auto it = infos_.find(id);
  if (it == infos_.end() || active_.count(id) > 0) return;
  active_[id] = {std::move(st), revision};
  active_replica_bytes_ += replicaBytes(it->second.num_points);
}

void LandmarkDatabase::deactivate(int64_t id) {
  const auto it = active_.find(id);
  if (it == active_.end()) return;
  const auto info_it = infos_.find(id);
  if (info_it != infos_.end()) active_replica_bytes_ -= replicaBytes(info_it->second.num_points);
  active_.erase(it);
}

ProposalResult LandmarkDatabase::propose(LandmarkInfo info, LandmarkStructure structure,
                                         const std::optional<Pose2>& map_T_odom) {
  ProposalResult r;
  if (info.camera.empty()) {
    r.reason = "no camera name";
    return r;
  }
  if (!info.created_odom.isFinite()) {
    r.reason = "non-finite creation pose";
    return r;
  }
  r.reason = structure.validate();
  if (!r.reason.empty()) return r;
  info.fingerprint = structure.fingerprint();
  if (const auto known = store_->findProposal(info.camera, info.proposal_id, info.fingerprint)) {
    r.outcome = ProposalOutcome::kAlreadyKnown;
    r.id = *known;
    return r;
  }
  if (!params_.allow_new_landmarks) {
    r.outcome = ProposalOutcome::kRefused;
    r.reason = "the map is open for localization only (allow_new_landmarks: false)";
    return r;
  }
  info.id = store_->nextId();
  info.version = 1;
  info.num_points = structure.num_points;
  info.stats = {};
  if (map_T_odom && map_T_odom->isFinite()) {
    info.pose_source = PoseSource::kProvisional;
    info.map_pose = map_T_odom->compose(info.created_odom);
  } else {
    info.pose_source = PoseSource::kOdometry;
    info.map_pose = {};
  }
  const int64_t revision = revision_ + 1;
  info.revision = revision;
  store_->insert(info, structure, revision);  // throws: nothing changed
  revision_ = revision;
  const int64_t id = info.id;
  infos_.emplace(id, std::move(info));
  activate(id, std::make_shared<const LandmarkStructure>(std::move(structure)), revision);
  r.outcome = ProposalOutcome::kCreated;
  r.id = id;
  r.changes.push_back({ChangeOp::kCreated, id, revision});
  if (active_replica_bytes_ > budgetBytes()) {
    auto more = updateActiveSet(true);
    r.changes.insert(r.changes.end(), more.begin(), more.end());
  }
  return r;
}

LandmarkDatabase::RevisionResult LandmarkDatabase::revise(int64_t id, const std::string& camera,
                                                          int64_t proposal_id,
                                                          std::vector<float> points) {
  RevisionResult r;
  if (!params_.allow_new_landmarks) {
    r.reason = "the map is open for localization only (allow_new_landmarks: false)";
    return r;
  }
  const auto it = infos_.find(id);
  if (it == infos_.end()) {
    r.reason = "no landmark " + std::to_string(id);
    return r;
  }
  LandmarkInfo& info = it->second;
  if (info.camera != camera || info.proposal_id != proposal_id) {
    r.reason = "landmark " + std::to_string(id) + " was not proposed by " + camera + " as " +
               std::to_string(proposal_id);
    return r;
  }
  if (points.size() != 3 * static_cast<size_t>(info.num_points)) {
    r.reason = std::to_string(points.size() / 3) + " points for landmark " + std::to_string(id) +
               " of " + std::to_string(info.num_points);
    return r;
  }
  for (float v : points) {
    if (!std::isfinite(v)) {
      r.reason = "non-finite points";
      return r;
    }
  }
  const int64_t revision = revision_ + 1;
  store_->updatePoints(id, points, info.version + 1, revision);  // throws: nothing changed
  revision_ = revision;
  ++info.version;
  info.revision = revision;
  const auto active = active_.find(id);
  if (active != active_.end()) {
    auto refined = std::make_shared<LandmarkStructure>(*active->second.structure);
    refined->points = std::move(points);
    active->second.structure = std::move(refined);
    active->second.revision = revision;
  }
  r.changes.push_back({ChangeOp::kUpdated, id, revision, false});
  return r;
}

bool LandmarkDatabase::recordMeasurement(int64_t id, Utime utime) {
  const auto it = infos_.find(id);
  if (it == infos_.end()) return false;
  ++it->second.stats.num_recognitions;
  it->second.stats.last_seen_utime = std::max(it->second.stats.last_seen_utime, utime);
  dirty_.insert(id);
  return true;
}

bool LandmarkDatabase::recordVerdict(int64_t id, bool accepted, Utime utime) {
  const auto it = infos_.find(id);
  if (it == infos_.end()) return false;
  ++(accepted ? it->second.stats.num_accepted : it->second.stats.num_rejected);
  it->second.stats.last_seen_utime = std::max(it->second.stats.last_seen_utime, utime);
  dirty_.insert(id);
  return true;
}

int LandmarkDatabase::setMapPoses(const std::vector<std::pair<int64_t, Pose2>>& poses) {
  int known = 0;
  for (const auto& [id, pose] : poses) {
    const auto it = infos_.find(id);
    if (it == infos_.end() || !pose.isFinite()) continue;
    ++known;
    LandmarkInfo& i = it->second;
    const bool moved =
        i.pose_source != PoseSource::kMap ||
        std::hypot(i.map_pose.x - pose.x, i.map_pose.y - pose.y) > kPoseWriteThresholdM;
    i.pose_source = PoseSource::kMap;
    i.map_pose = pose;
    if (moved) pose_dirty_.insert(id);
  }
  return known;
}

std::vector<Change> LandmarkDatabase::flush() {
  std::vector<Change> changes;
  std::vector<LandmarkInfo> rows;
  for (int64_t id : dirty_) {
    auto it = infos_.find(id);
    if (it == infos_.end()) continue;
    LandmarkInfo& i = it->second;
    ++i.version;
    i.revision = ++revision_;
    changes.push_back({ChangeOp::kUpdated, id, i.revision, true});
    rows.push_back(i);
  }
  for (int64_t id : pose_dirty_) {
    if (dirty_.count(id) > 0) continue;
    auto it = infos_.find(id);
    if (it != infos_.end()) rows.push_back(it->second);
  }
  dirty_.clear();
  pose_dirty_.clear();
  if (!rows.empty()) store_->updateInfos(rows, revision_);
  if (robot_estimate_dirty_) {
    store_->saveRobotPose(robot_estimate_);
    robot_estimate_dirty_ = false;
  }
  return changes;
}

void LandmarkDatabase::noteRobotEstimate(const RobotPoseRecord& estimate, bool kidnapped) {
  if (kidnapped) {
    // (An estimate not yet written keeps the flag set already.)
    robot_estimate_dirty_ = robot_estimate_dirty_ || store_->robotPose().has_value();
    robot_estimate_.reset();
    return;
  }
  robot_estimate_ = estimate;
  robot_estimate_dirty_ = true;
}

RegionKey LandmarkDatabase::regionOf(const Pose2& p) const {
  const double s = params_.segmentation.region_size_m;
  return {static_cast<int64_t>(std::floor(p.x / s)), static_cast<int64_t>(std::floor(p.y / s))};
}

std::vector<RegionSummary> LandmarkDatabase::regions() const {
  std::map<RegionKey, RegionSummary> out;
  const double s = params_.segmentation.region_size_m;
  for (const auto& [id, i] : infos_) {
    const RegionKey k = regionOf(i.position());
    RegionSummary& r = out[k];
    r.key = k;
    r.centre_x = (static_cast<double>(k.ix) + 0.5) * s;
    r.centre_y = (static_cast<double>(k.iy) + 0.5) * s;
    ++r.landmarks;
    r.replica_bytes += replicaBytes(i.num_points);
    r.active = r.active || active_.count(id) > 0;
  }
  std::vector<RegionSummary> v;
  for (auto& [k, r] : out) v.push_back(r);
  return v;
}

void LandmarkDatabase::setRobotPose(const Pose2& map_pose) {
  if (map_pose.isFinite()) robot_ = map_pose;
}

std::vector<Change> LandmarkDatabase::updateActive(bool force, bool publish) {
  const auto& seg = params_.segmentation;
  const size_t budget = budgetBytes();
  const bool moved = robot_ && (!evaluated_at_ || std::hypot(robot_->x - evaluated_at_->x,
                                                             robot_->y - evaluated_at_->y) >=
                                                      seg.reevaluate_distance_m);
  if (!force && !moved && active_replica_bytes_ <= budget) return {};
  evaluated_at_ = robot_;

  // Candidates in order of preference: nearest region first (newest
  // landmark first inside a region); without a robot pose, newest first.
  struct Candidate {
    double distance;
    Utime created;
    int64_t id;
  };
  std::vector<Candidate> candidates;
  candidates.reserve(infos_.size());
  for (const auto& [id, i] : infos_) {
    double distance = 0;
    if (robot_) {
      const RegionKey k = regionOf(i.position());
      const double cx = (static_cast<double>(k.ix) + 0.5) * seg.region_size_m;
      const double cy = (static_cast<double>(k.iy) + 0.5) * seg.region_size_m;
      distance = std::hypot(cx - robot_->x, cy - robot_->y);
      if (distance > seg.active_radius_m) continue;
    }
    candidates.push_back({distance, i.created_utime, id});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.distance != b.distance) return a.distance < b.distance;
    if (a.created != b.created) return a.created > b.created;
    return a.id > b.id;
  });
  std::set<int64_t> wanted;
  size_t bytes = 0;
  for (const auto& c : candidates) {
    const size_t b = replicaBytes(infos_.at(c.id).num_points);
    if (bytes + b > budget) break;
    bytes += b;
    wanted.insert(c.id);
  }

  std::vector<Change> changes;
  std::vector<int64_t> evict;
  for (const auto& [id, a] : active_) {
    if (wanted.count(id) == 0) evict.push_back(id);
  }
  for (int64_t id : evict) {
    deactivate(id);
    changes.push_back({ChangeOp::kEvicted, id, ++revision_});
  }
  for (int64_t id : wanted) {
    if (active_.count(id) > 0) continue;
    auto st = store_->loadStructure(id);
    if (!st) continue;
    if (!publish) {
      activate(id, std::make_shared<const LandmarkStructure>(std::move(*st)),
               infos_.at(id).revision);
      continue;
    }
    const int64_t rev = ++revision_;
    activate(id, std::make_shared<const LandmarkStructure>(std::move(*st)), rev);
    changes.push_back({ChangeOp::kLoaded, id, rev});
  }
  if (!changes.empty() && !store_->inMemory()) store_->setRevision(revision_);
  return changes;
}

bool LandmarkDatabase::duplicates(const LandmarkInfo& a, const LandmarkInfo& b) const {
  const Pose2& pa = a.position();
  const Pose2& pb = b.position();
  if (std::hypot(pa.x - pb.x, pa.y - pb.y) > params_.prune.duplicate_distance_m) return false;
  const auto yaw = [&](const std::string& camera) {
    const auto it = params_.camera_yaw.find(camera);
    return it == params_.camera_yaw.end() ? 0.0 : it->second;
  };
  const double heading_a = pa.theta + yaw(a.camera);
  const double heading_b = pb.theta + yaw(b.camera);
  if (std::abs(wrapAngle(heading_a - heading_b)) >
      params_.prune.duplicate_angle_deg * M_PI / 180.0) {
    return false;
  }
  return true;
}

std::vector<Change> LandmarkDatabase::prune(Utime now, bool dry_run) {
  const PrunePolicy& p = params_.prune;
  const Utime min_age = fromSeconds(p.min_age_s);
  std::map<int64_t, const char*> doomed;
  for (const auto& [id, i] : infos_) {
    if (now - i.created_utime < min_age) continue;
    const int verdicts = i.stats.num_accepted + i.stats.num_rejected;
    if (i.stats.num_recognitions < p.min_recognitions) {
      doomed[id] = "rarely recognized";
    } else if (verdicts >= p.min_verdicts &&
               static_cast<double>(i.stats.num_accepted) <
                   p.min_accepted_ratio * static_cast<double>(verdicts)) {
      doomed[id] = "poor accepted ratio";
    }
  }
  // Duplicates: pairs in neighbouring cells of size duplicate_distance_m.
  if (p.duplicate_distance_m > 0) {
    const double cell = p.duplicate_distance_m;
    std::map<std::pair<int64_t, int64_t>, std::vector<int64_t>> grid;
    for (const auto& [id, i] : infos_) {
      if (doomed.count(id) > 0) continue;
      const Pose2& q = i.position();
      grid[{static_cast<int64_t>(std::floor(q.x / cell)),
            static_cast<int64_t>(std::floor(q.y / cell))}]
          .push_back(id);
    }
    std::map<int64_t, StructurePtr> loaded;
    const auto get = [&](int64_t id) -> StructurePtr {
      if (auto s = structure(id)) return s;
      auto& slot = loaded[id];
      if (!slot) {
        auto st = store_->loadStructure(id);
        if (st) slot = std::make_shared<const LandmarkStructure>(std::move(*st));
      }
      return slot;
    };
    for (const auto& [key, ids] : grid) {
      for (int64_t a : ids) {
        if (doomed.count(a) > 0) continue;
        for (int64_t dx = -1; dx <= 1; ++dx) {
          for (int64_t dy = -1; dy <= 1; ++dy) {
            const auto it = grid.find({key.first + dx, key.second + dy});
            if (it == grid.end()) continue;
            for (int64_t b : it->second) {
              if (b <= a || doomed.count(a) > 0 || doomed.count(b) > 0) continue;
              const LandmarkInfo& ia = infos_.at(a);
              const LandmarkInfo& ib = infos_.at(b);
              if (!duplicates(ia, ib)) continue;
              const auto sa = get(a), sb = get(b);
              if (!sa || !sb ||
                  sharedDescriptorFraction(*sa, *sb, p.duplicate_match_ratio) <
                      p.duplicate_min_shared) {
                continue;
              }
              // Keep the one with more accepted measurements, then the older.
              const bool keep_a = ia.stats.num_accepted != ib.stats.num_accepted
                                      ? ia.stats.num_accepted > ib.stats.num_accepted
                                      : a < b;
              doomed[keep_a ? b : a] = "duplicate";
            }
          }
        }
      }
    }
  }
  std::vector<Change> changes;
  if (doomed.empty()) return changes;
  if (dry_run) {
    for (const auto& [id, why] : doomed) changes.push_back({ChangeOp::kRemoved, id, 0, false, why});
    return changes;
  }
  std::vector<int64_t> ids;
  const int64_t first = revision_;
  for (const auto& [id, why] : doomed) {
    ids.push_back(id);
    changes.push_back(
        {ChangeOp::kRemoved, id, first + static_cast<int64_t>(ids.size()), false, why});
  }
  store_->remove(ids, first + static_cast<int64_t>(ids.size()));  // throws: nothing changed
  revision_ = first + static_cast<int64_t>(ids.size());
  for (int64_t id : ids) {
    deactivate(id);
    infos_.erase(id);
    dirty_.erase(id);
    pose_dirty_.erase(id);
  }
  return changes;
}

}  // namespace vslam::landmark_db
