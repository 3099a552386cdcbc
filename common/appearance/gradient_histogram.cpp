#include "appearance/gradient_histogram.hpp"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

namespace vslam::appearance {

int orientationBin(double angle, int bins) {
  if (angle <= -M_PI) angle = M_PI;  // -pi and pi are one direction: the last bin
  const int b = static_cast<int>(std::floor((angle + M_PI) / (2.0 * M_PI) * bins));
  return b < 0 ? 0 : b >= bins ? bins - 1 : b;
}

int histogramLength(const HistogramParams& params) {
  return params.bins * params.grid_cols * params.grid_rows;
}

Histogram gradientHistogram(const cv::Mat& gray, const HistogramParams& params) {
  if (gray.type() != CV_8UC1 || gray.rows < 3 || gray.cols < 3) {
    throw std::invalid_argument("gradientHistogram: expected an 8-bit grey image of at least 3x3");
  }
  if (params.bins < 1) throw std::invalid_argument("gradientHistogram: bins must be >= 1");
  if (params.grid_cols < 1 || params.grid_rows < 1 || params.grid_cols > gray.cols ||
      params.grid_rows > gray.rows) {
    throw std::invalid_argument("gradientHistogram: a " + std::to_string(params.grid_cols) + "x" +
                                std::to_string(params.grid_rows) + " grid does not fit a " +
                                std::to_string(gray.cols) + "x" + std::to_string(gray.rows) +
                                " image");
  }
  cv::Mat gx, gy;
  cv::Sobel(gray, gx, CV_32F, 1, 0, 3);
  cv::Sobel(gray, gy, CV_32F, 0, 1, 3);
  std::vector<double> counts(static_cast<size_t>(histogramLength(params)), 0.0);
  const float min_sq = static_cast<float>(params.min_magnitude * params.min_magnitude);
  double total = 0;
  for (int r = 1; r < gray.rows - 1; ++r) {
    const float* px = gx.ptr<float>(r);
    const float* py = gy.ptr<float>(r);
    const int row_cells = r * params.grid_rows / gray.rows * params.grid_cols;
    for (int c = 1; c < gray.cols - 1; ++c) {
      const float x = px[c], y = py[c];
      if (x * x + y * y < min_sq || (x == 0.f && y == 0.f)) continue;
      const int cell = row_cells + c * params.grid_cols / gray.cols;
      counts[static_cast<size_t>(cell * params.bins +
                                 orientationBin(std::atan2(y, x), params.bins))] += 1.0;
      total += 1.0;
    }
  }
  Histogram h(counts.size(), 0.f);
  if (total > 0) {
    for (size_t i = 0; i < counts.size(); ++i) h[i] = static_cast<float>(counts[i] / total);
  }
  return h;
}

double chiSquare(const Histogram& a, const Histogram& b) {
  if (a.size() != b.size()) throw std::invalid_argument("chiSquare: histograms differ in size");
  double sum = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    const double s = static_cast<double>(a[k]) + b[k];
    if (s <= 0) continue;
    const double d = static_cast<double>(a[k]) - b[k];
    sum += d * d / s;
  }
  return sum;
}

}  // namespace vslam::appearance
