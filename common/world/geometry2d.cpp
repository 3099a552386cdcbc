#include "world/geometry2d.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vslam::world::geo {

double signedArea(const Polygon& p) {
  double a = 0.0;
  for (size_t i = 0, n = p.size(); i < n; ++i) a += cross(p[i], p[(i + 1) % n]);
  return 0.5 * a;
}

bool contains(const Polygon& p, const Eigen::Vector2d& q) {
  bool inside = false;
  for (size_t i = 0, n = p.size(), j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = p[i];
    const Eigen::Vector2d& b = p[j];
    if ((a.y() > q.y()) != (b.y() > q.y())) {
      const double x = a.x() + (q.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (q.x() < x) inside = !inside;
    }
  }
  return inside;
}

double distanceToSegment(const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((q - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - q).norm();
}

double distanceToBoundary(const Polygon& p, const Eigen::Vector2d& q) {
  double d = std::numeric_limits<double>::infinity();
  for (size_t i = 0, n = p.size(); i < n; ++i) {
    d = std::min(d, distanceToSegment(q, p[i], p[(i + 1) % n]));
  }
  return d;
}

namespace {
int orientation(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const double v = cross(b - a, c - a);
  const double eps = 1e-12 * std::max(1.0, (b - a).squaredNorm() + (c - a).squaredNorm());
  return v > eps ? 1 : (v < -eps ? -1 : 0);
}
bool onSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& q) {
  return q.x() >= std::min(a.x(), b.x()) - 1e-12 && q.x() <= std::max(a.x(), b.x()) + 1e-12 &&
         q.y() >= std::min(a.y(), b.y()) - 1e-12 && q.y() <= std::max(a.y(), b.y()) + 1e-12;
}
}  // namespace

bool segmentsCross(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                   const Eigen::Vector2d& d, bool proper) {
  const int o1 = orientation(a, b, c), o2 = orientation(a, b, d);
  const int o3 = orientation(c, d, a), o4 = orientation(c, d, b);
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;
  if (proper) return false;
  if (o1 == 0 && onSegment(a, b, c)) return true;
  if (o2 == 0 && onSegment(a, b, d)) return true;
  if (o3 == 0 && onSegment(c, d, a)) return true;
  if (o4 == 0 && onSegment(c, d, b)) return true;
  return false;
}

bool isSimple(const Polygon& p, int* edge_i, int* edge_j) {
  const int n = static_cast<int>(p.size());
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = p[i];
    const Eigen::Vector2d& b = p[(i + 1) % n];
    for (int j = i + 1; j < n; ++j) {
      const Eigen::Vector2d& c = p[j];
      const Eigen::Vector2d& d = p[(j + 1) % n];
      const bool adjacent = (j == i + 1) || (i == 0 && j == n - 1);
      bool bad;
      if (adjacent) {
        // Adjacent edges share one vertex; they are bad only if they fold
        // back onto each other (collinear and overlapping).
        const Eigen::Vector2d shared = (j == i + 1) ? b : a;
        const Eigen::Vector2d e1 = ((j == i + 1) ? a : b) - shared;
        const Eigen::Vector2d e2 = ((j == i + 1) ? d : c) - shared;
        bad = std::abs(cross(e1, e2)) <= 1e-12 * e1.norm() * e2.norm() && e1.dot(e2) > 0.0;
      } else {
        bad = segmentsCross(a, b, c, d, /*proper=*/false);
      }
      if (bad) {
        if (edge_i) *edge_i = i;
        if (edge_j) *edge_j = j;
        return false;
      }
    }
  }
  return true;
}

bool isConvex(const Polygon& p) {
  const size_t n = p.size();
  for (size_t i = 0; i < n; ++i) {
    if (cross(p[(i + 1) % n] - p[i], p[(i + 2) % n] - p[(i + 1) % n]) < -1e-12) return false;
  }
  return true;
}

std::vector<std::array<int, 3>> triangulate(const Polygon& p) {
  std::vector<int> idx(p.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = static_cast<int>(i);
  std::vector<std::array<int, 3>> tris;
  auto isEar = [&](size_t k) {
    const size_t m = idx.size();
    const int ia = idx[(k + m - 1) % m], ib = idx[k], ic = idx[(k + 1) % m];
    const Eigen::Vector2d &a = p[ia], &b = p[ib], &c = p[ic];
    if (cross(b - a, c - b) <= 0.0) return false;  // reflex or collinear
    for (size_t j = 0; j < m; ++j) {
      const int iq = idx[j];
      if (iq == ia || iq == ib || iq == ic) continue;
      const Eigen::Vector2d& q = p[iq];
      if (cross(b - a, q - a) >= 0.0 && cross(c - b, q - b) >= 0.0 && cross(a - c, q - c) >= 0.0) {
        return false;
      }
    }
    return true;
  };
  while (idx.size() > 3) {
    bool clipped = false;
    for (size_t k = 0; k < idx.size(); ++k) {
      if (!isEar(k)) continue;
      const size_t m = idx.size();
      tris.push_back({idx[(k + m - 1) % m], idx[k], idx[(k + 1) % m]});
      idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(k));
      clipped = true;
      break;
    }
    if (!clipped) {
      // Only collinear runs are left (a degenerate remainder): drop a
      // collinear vertex, it adds no area.
      for (size_t k = 0; k < idx.size(); ++k) {
        const size_t m = idx.size();
        const Eigen::Vector2d &a = p[idx[(k + m - 1) % m]], &b = p[idx[k]],
                              &c = p[idx[(k + 1) % m]];
        if (std::abs(cross(b - a, c - b)) <= 1e-12) {
          idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(k));
          clipped = true;
          break;
        }
      }
      if (!clipped) break;
    }
  }
  if (idx.size() == 3) tris.push_back({idx[0], idx[1], idx[2]});
  return tris;
}

namespace {
// Clips a convex polygon to the left side of the directed line ab.
Polygon clipLeft(const Polygon& poly, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  Polygon out;
  const Eigen::Vector2d d = b - a;
  for (size_t i = 0, n = poly.size(); i < n; ++i) {
    const Eigen::Vector2d& p = poly[i];
    const Eigen::Vector2d& q = poly[(i + 1) % n];
    const double sp = cross(d, p - a), sq = cross(d, q - a);
    if (sp >= 0) out.push_back(p);
    if ((sp >= 0) != (sq >= 0)) out.push_back(p + (q - p) * (sp / (sp - sq)));
  }
  return out;
}
}  // namespace

double intersectionArea(const Polygon& a, const Polygon& b) {
  double area = 0.0;
  const auto ta = triangulate(a), tb = triangulate(b);
  for (const auto& x : ta) {
    for (const auto& y : tb) {
      Polygon p = {a[x[0]], a[x[1]], a[x[2]]};
      for (int k = 0; k < 3 && p.size() >= 3; ++k) p = clipLeft(p, b[y[k]], b[y[(k + 1) % 3]]);
      if (p.size() >= 3) area += signedArea(p);
    }
  }
  return area;
}

}  // namespace vslam::world::geo
