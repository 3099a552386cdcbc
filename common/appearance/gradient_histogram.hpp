#pragma once
// The appearance of a snapshot (Lee & Sowmya, section V.B, after Kosecka et
// al.): the histogram of gradient orientations. Gradients come from the 3x3
// Sobel operator; each pixel's orientation atan2(gy, gx) in [-pi, pi] falls
// into one of k equal bins; pixels whose gradient magnitude is below a
// threshold (flat image regions, where the orientation is noise) are left
// out, as is the one-pixel image border (no full Sobel neighbourhood). The
// histogram is normalised to sum 1, so images of different sizes compare.
//
// Two histograms are compared with the chi-square distance (paper eq. 4)
//   chi2(h_i, h_j) = sum_k (h_i(k) - h_j(k))^2 / (h_i(k) + h_j(k)),
// where bins empty in both histograms contribute nothing; for normalised
// histograms it lies in [0, 2].

#include <opencv2/core.hpp>
#include <vector>

namespace vslam::appearance {

using Histogram = std::vector<float>;

struct HistogramParams {
  int bins = 36;              // k, over [-pi, pi]
  double min_magnitude = 20;  // Sobel magnitude (grey levels) below which a pixel is ignored
  // A histogram per cell of a grid over the image, concatenated (an addition
  // to the paper's one histogram per image: where the image's gradients are
  // counts as well as which way they point). 1 x 1 is the paper's.
  int grid_cols = 1;
  int grid_rows = 1;
};

// Values in a histogram: bins per cell times cells.
int histogramLength(const HistogramParams& params);

// gray: CV_8UC1, at least 3x3 and at least one pixel per grid cell. Returns
// histogramLength(params) values, cell by cell in row-major order, summing to
// 1 over the whole image (a cell weighs as many pixels as passed the
// threshold in it), or all zeros if no pixel passes the magnitude threshold
// (a blank image).
Histogram gradientHistogram(const cv::Mat& gray, const HistogramParams& params);

// Bin of an orientation in [-pi, pi]: floor((angle + pi) / (2 pi) * bins),
// with pi (and -pi, the same direction) in the last bin.
int orientationBin(double angle, int bins);

// Chi-square distance (eq. 4) of two histograms of the same size.
double chiSquare(const Histogram& a, const Histogram& b);

}  // namespace vslam::appearance
