#pragma once
// Squared Euclidean distance between two 128-byte SIFT descriptors stored as
// uint8 (OpenCV's SIFT values are integers 0..255, so this is lossless). Exact
// integer arithmetic: the largest possible value, 128 * 255^2, fits in 32 bits.

#include <cstdint>
#include <opencv2/core.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace vslam::frontend {

constexpr int kDescriptorBytes = 128;

inline uint32_t squaredDistanceU8(const uint8_t* a, const uint8_t* b) {
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  __m128i acc = _mm_setzero_si128();
  for (int i = 0; i < kDescriptorBytes; i += 16) {
    const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i));
    const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i));
    // |a - b| per byte, widened to 16 bits, squared and pairwise summed to 32 bits.
    const __m128i diff = _mm_or_si128(_mm_subs_epu8(va, vb), _mm_subs_epu8(vb, va));
    const __m128i lo = _mm_unpacklo_epi8(diff, zero);
    const __m128i hi = _mm_unpackhi_epi8(diff, zero);
    acc = _mm_add_epi32(acc, _mm_madd_epi16(lo, lo));
    acc = _mm_add_epi32(acc, _mm_madd_epi16(hi, hi));
  }
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, _MM_SHUFFLE(1, 0, 3, 2)));
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, _MM_SHUFFLE(2, 3, 0, 1)));
  return static_cast<uint32_t>(_mm_cvtsi128_si32(acc));
#else
  uint32_t sum = 0;
  for (int i = 0; i < kDescriptorBytes; ++i) {
    const int d = static_cast<int>(a[i]) - static_cast<int>(b[i]);
    sum += static_cast<uint32_t>(d * d);
  }
  return sum;
#endif
}

// squaredDistanceU8(q, points + 128 i) for i in [0, n), into out[0..n): the
// same exact integers, with AVX2 where the CPU has it (checked once, at run
// time; the build itself targets baseline x86-64). The verification of
// recognize() spends most of its time here.
void squaredDistancesU8(const uint8_t* q, const uint8_t* points, int n, uint32_t* out);

// CV_32F or CV_8U descriptors (n x 128) to a continuous CV_8U matrix: float
// values are rounded and saturated to 0..255 (exact for OpenCV's SIFT, whose
// float descriptors hold integers). Throws std::invalid_argument otherwise.
cv::Mat toDescriptorsU8(const cv::Mat& descriptors);

}  // namespace vslam::frontend
