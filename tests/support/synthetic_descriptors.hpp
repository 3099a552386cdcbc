#pragma once
// Synthetic SIFT-like descriptors for recognition tests and benchmarks.

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

namespace vslam::test {

// n random non-negative 128-D descriptors with SIFT's norm (~512), CV_32F.
// Independent uniform bins: every pair is about equally far apart, far easier
// to match than real SIFT; prefer SiftLikeGenerator.
inline cv::Mat randomDescriptors(int n, std::mt19937& rng) {
  cv::Mat d(n, 128, CV_32F);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < 128; ++c) d.at<float>(r, c) = u(rng);
    d.row(r) *= 512.0 / cv::norm(d.row(r));
  }
  return d;
}

// SIFT-like descriptors with SIFT's structure: a patch is 4 x 4 cells, each
// with one or two dominant gradient orientations and a magnitude; its
// descriptor is the 8-bin orientation histogram of every cell (orientations
// spread by a von Mises kernel), normalized as SIFT does (unit length, bins
// clipped at 0.2, renormalized, x 512, rounded to integers, saturated at
// 255). Patches are drawn around a few hundred prototypes (edges and corners
// at random angles and offsets, as textures repeat in a home), so the
// descriptors cluster like real ones and a vocabulary has structure to find.
// A re-observation perturbs the patch (orientation, magnitudes, clutter),
// giving match distances like SIFT across views ~20 cm apart.
class SiftLikeGenerator {
 public:
  struct Patch {
    std::array<float, 16> angle{}, angle2{}, magnitude{}, second{}, kappa{};
  };

  explicit SiftLikeGenerator(uint32_t seed, int num_prototypes = 300) : rng_(seed) {
    for (int i = 0; i < num_prototypes; ++i) prototypes_.push_back(prototype());
  }

  // A new physical point.
  Patch patch() {
    const Patch& p =
        prototypes_[std::uniform_int_distribution<size_t>(0, prototypes_.size() - 1)(rng_)];
    return perturb(p, 0.45f, 0.6f);
  }
  // The same point seen again; noise 1 ~ views 20 cm apart.
  Patch observe(const Patch& p, float noise = 1.f) {
    return perturb(p, 0.12f * noise, 0.25f * noise);
  }

  // SIFT's descriptor of a patch, 1 x 128 CV_32F (integer values 0..255).
  static cv::Mat describe(const Patch& p) {
    std::array<double, 128> h{};
    constexpr double kPi = 3.14159265358979323846;
    for (int c = 0; c < 16; ++c) {
      for (int b = 0; b < 8; ++b) {
        const double t = 2 * kPi * b / 8;
        const double v1 = std::exp(p.kappa[c] * (std::cos(t - p.angle[c]) - 1));
        const double v2 = std::exp(p.kappa[c] * (std::cos(t - p.angle2[c]) - 1));
        h[static_cast<size_t>(c * 8 + b)] = p.magnitude[c] * (v1 + p.second[c] * v2);
      }
    }
    auto normalize = [&] {
      double n = 0;
      for (double v : h) n += v * v;
      n = std::sqrt(std::max(n, 1e-12));
      for (double& v : h) v /= n;
    };
    normalize();
    for (double& v : h) v = std::min(v, 0.2);
    normalize();
    cv::Mat d(1, 128, CV_32F);
    for (int i = 0; i < 128; ++i)
      d.at<float>(0, i) =
          static_cast<float>(std::min(255.0, std::round(512.0 * h[static_cast<size_t>(i)])));
    return d;
  }

  // Descriptors of n new points, one row each.
  cv::Mat descriptors(int n, std::vector<Patch>* patches = nullptr) {
    cv::Mat d(0, 128, CV_32F);
    for (int i = 0; i < n; ++i) {
      Patch p = patch();
      d.push_back(describe(p));
      if (patches) patches->push_back(p);
    }
    return d;
  }

  std::mt19937& rng() { return rng_; }

 private:
  Patch prototype() {
    constexpr float kPi = 3.14159265f;
    std::uniform_real_distribution<float> u(0.f, 1.f);
    Patch p;
    // An edge (one orientation) or a corner (two), crossing the patch at an
    // offset; magnitude falls off with the cell's distance from the edge.
    const float a = 2 * kPi * u(rng_);
    const float b = a + kPi * (0.25f + 0.5f * u(rng_));
    const bool corner = u(rng_) < 0.4f;
    const float offset = 3.f * (u(rng_) - 0.5f);
    const float width = 0.6f + 1.5f * u(rng_);
    for (int c = 0; c < 16; ++c) {
      const float x = static_cast<float>(c % 4) - 1.5f, y = static_cast<float>(c / 4) - 1.5f;
      const float dist = -std::sin(a) * x + std::cos(a) * y - offset;
      p.angle[c] = a;
      p.angle2[c] = b;
      p.magnitude[c] = 0.15f + std::exp(-dist * dist / (2 * width * width));
      p.second[c] = corner ? 0.3f + 0.7f * u(rng_) : 0.15f * u(rng_);
      p.kappa[c] = 2.f + 4.f * u(rng_);
    }
    return p;
  }

  Patch perturb(const Patch& p, float angle_sigma, float magnitude_sigma) {
    std::normal_distribution<float> n(0.f, 1.f);
    Patch q = p;
    const float common = angle_sigma * n(rng_);  // residual orientation error of the keypoint
    for (int c = 0; c < 16; ++c) {
      q.angle[c] += common + angle_sigma * n(rng_);
      q.angle2[c] += common + angle_sigma * n(rng_);
      q.magnitude[c] *= std::exp(magnitude_sigma * n(rng_));
      q.second[c] *= std::exp(magnitude_sigma * n(rng_));
    }
    return q;
  }

  std::mt19937 rng_;
  std::vector<Patch> prototypes_;
};

}  // namespace vslam::test
