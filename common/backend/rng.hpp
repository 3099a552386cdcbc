#pragma once
// Counter-based random streams for the particle filter.
//
// Every random draw of particle i in filter step k comes from its own stream,
// seeded by hashing (seed, k, i, purpose). No generator state is shared
// between particles, so the result does not depend on how the particles are
// split among threads, nor on the order they run in: a fixed seed gives the
// same particle set with 1 or N threads. SplitMix64 (Steele, Lea and Flood
// 2014) is the generator: one 64-bit state, passes BigCrush, and seeding is
// free (a std::mt19937 costs ~2,500 words of initialisation per stream).

#include <cmath>
#include <cstdint>

namespace vslam::backend {

inline uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Hashes the identifying numbers of a stream into its seed.
inline uint64_t streamSeed(uint64_t seed, uint64_t step, uint64_t index, uint64_t purpose) {
  uint64_t s = seed;
  uint64_t h = splitmix64(s);
  s = h ^ step;
  h = splitmix64(s);
  s = h ^ index;
  h = splitmix64(s);
  s = h ^ purpose;
  return splitmix64(s);
}

class RandomStream {
 public:
  RandomStream(uint64_t seed, uint64_t step, uint64_t index, uint64_t purpose)
      : state_(streamSeed(seed, step, index, purpose)) {}
  explicit RandomStream(uint64_t state) : state_(state) {}

  uint64_t next() { return splitmix64(state_); }
  // Uniform in [0, 1), 53 bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  // Standard normal (Marsaglia's polar method; the spare is kept).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * uniform() - 1.0;
      v = 2.0 * uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * f;
    has_spare_ = true;
    return u * f;
  }

 private:
  uint64_t state_;
  double spare_ = 0;
  bool has_spare_ = false;
};

}  // namespace vslam::backend
