#pragma once
#include <cmath>

namespace vslam {

// Wraps an angle to (-pi, pi].
inline double wrapAngle(double a) {
  if (a > -M_PI && a <= M_PI) return a;  // the usual case; std::remainder is slow
  a = std::remainder(a, 2.0 * M_PI);     // [-pi, pi]
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

inline double degToRad(double d) { return d * M_PI / 180.0; }
inline double radToDeg(double r) { return r * 180.0 / M_PI; }

}  // namespace vslam
