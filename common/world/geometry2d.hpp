#pragma once
// Small 2-D polygon helpers shared by the world loader and the planning
// queries. Polygons are vertex lists, implicitly closed.

#include <Eigen/Core>
#include <array>
#include <vector>

namespace vslam::world::geo {

using Polygon = std::vector<Eigen::Vector2d>;

inline double cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// Signed area, positive for counter-clockwise polygons.
double signedArea(const Polygon& p);
// Even-odd point-in-polygon test (points on the boundary may go either way).
bool contains(const Polygon& p, const Eigen::Vector2d& q);
// Distance from q to the segment ab.
double distanceToSegment(const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                         const Eigen::Vector2d& b);
// Distance from q to the polygon's boundary.
double distanceToBoundary(const Polygon& p, const Eigen::Vector2d& q);
// Do the closed segments ab and cd intersect? `proper` only counts crossings
// in both interiors (touching at an end or overlapping collinearly does not count).
bool segmentsCross(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                   const Eigen::Vector2d& d, bool proper);
// True if no two non-adjacent edges touch and no adjacent edges fold back;
// otherwise the offending edge indices are returned through edge_i/edge_j.
bool isSimple(const Polygon& p, int* edge_i = nullptr, int* edge_j = nullptr);
bool isConvex(const Polygon& p);  // counter-clockwise input
// Area of the intersection of two simple counter-clockwise polygons.
double intersectionArea(const Polygon& a, const Polygon& b);
// Ear-clipping triangulation of a simple counter-clockwise polygon; triangles
// are counter-clockwise index triples.
std::vector<std::array<int, 3>> triangulate(const Polygon& p);

}  // namespace vslam::world::geo
