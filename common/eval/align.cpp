#include "eval/align.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>

#include "eval/errors.hpp"

namespace vslam::eval {

std::optional<AlignMode> parseAlignMode(const std::string& word) {
  if (word == "none") return AlignMode::kNone;
  if (word == "se2") return AlignMode::kSE2;
  if (word == "se3") return AlignMode::kSE3;
  if (word == "sim3") return AlignMode::kSim3;
  if (word == "origin") return AlignMode::kOrigin;
  return std::nullopt;
}

std::string toString(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
      return "none";
    case AlignMode::kSE2:
      return "se2";
    case AlignMode::kSE3:
      return "se3";
    case AlignMode::kSim3:
      return "sim3";
    case AlignMode::kOrigin:
      return "origin";
  }
  return "?";
}

StampedPose Similarity::apply(const StampedPose& p) const {
  StampedPose out = p;
  out.position = apply(p.position);
  out.orientation = Eigen::Quaterniond(R * p.orientation.normalized().toRotationMatrix());
  return out;
}

Trajectory Similarity::apply(const Trajectory& traj) const {
  Trajectory out;
  out.name = traj.name;
  out.poses.reserve(traj.size());
  for (const auto& p : traj.poses) out.poses.push_back(apply(p));
  return out;
}

double Similarity::rotationAngle() const { return Eigen::AngleAxisd(R).angle(); }

double Similarity::yaw() const {
  const Eigen::Vector3d x = R * Eigen::Vector3d::UnitX();
  return std::atan2(x.y(), x.x());
}

Similarity alignOrigin(const StampedPose& est_first, const StampedPose& ref_first) {
  const Eigen::Isometry3d t = ref_first.isometry() * est_first.isometry().inverse();
  Similarity out;
  out.R = t.linear();
  out.t = t.translation();
  return out;
}

std::size_t minPairsFor(AlignMode mode) {
  switch (mode) {
    case AlignMode::kNone:
    case AlignMode::kOrigin:
      return 1;
    case AlignMode::kSE2:
      return 2;
    case AlignMode::kSE3:
    case AlignMode::kSim3:
      return 3;
  }
  return 1;
}

Similarity alignPositions(const std::vector<Eigen::Vector3d>& est,
                          const std::vector<Eigen::Vector3d>& ref, AlignMode mode) {
  const std::size_t n = est.size();
  if (ref.size() != n) throw DataError("alignment: estimate and reference sizes differ");
  if (n < minPairsFor(mode)) {
    throw DataError("alignment " + toString(mode) + " needs at least " +
                    std::to_string(minPairsFor(mode)) + " associated poses, have " +
                    std::to_string(n));
  }
  Similarity out;
  if (mode == AlignMode::kNone) return out;
  if (mode == AlignMode::kOrigin) {
    throw std::logic_error("origin alignment needs orientations: use alignOrigin()");
  }

  if (mode == AlignMode::kSE2) {
    // Planar Kabsch: with centred a_i (estimate) and b_i (reference) in the
    // x-y plane, sum |R(th) a_i - b_i|^2 is smallest at
    //   th = atan2(sum a_i x b_i, sum a_i . b_i)
    // and the translation maps the centroids onto each other; z is untouched.
    Eigen::Vector2d mean_a = Eigen::Vector2d::Zero(), mean_b = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      mean_a += est[i].head<2>();
      mean_b += ref[i].head<2>();
    }
    mean_a /= static_cast<double>(n);
    mean_b /= static_cast<double>(n);
    double cross = 0, dot = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d a = est[i].head<2>() - mean_a, b = ref[i].head<2>() - mean_b;
      cross += a.x() * b.y() - a.y() * b.x();
      dot += a.dot(b);
    }
    const double th = std::atan2(cross, dot);
    const Eigen::Matrix2d R2 = Eigen::Rotation2Dd(th).toRotationMatrix();
    out.R.topLeftCorner<2, 2>() = R2;
    out.t.head<2>() = mean_b - R2 * mean_a;
    return out;
  }

  Eigen::Matrix3Xd src(3, n), dst(3, n);
  for (std::size_t i = 0; i < n; ++i) {
    src.col(static_cast<Eigen::Index>(i)) = est[i];
    dst.col(static_cast<Eigen::Index>(i)) = ref[i];
  }
  const bool with_scale = mode == AlignMode::kSim3;
  if (with_scale) {
    const Eigen::Vector3d mean = src.rowwise().mean();
    const double var = (src.colwise() - mean).squaredNorm() / static_cast<double>(n);
    if (!(var > 1e-18)) {
      throw DataError("alignment sim3: the associated estimate positions are all the same " +
                      std::string("point, so no scale can be found"));
    }
  }
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, with_scale);
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  out.scale = with_scale ? std::cbrt(sR.determinant()) : 1.0;
  out.R = sR / out.scale;
  out.t = T.topRightCorner<3, 1>();
  return out;
}

}  // namespace vslam::eval
