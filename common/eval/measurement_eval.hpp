#pragma once
// Accuracy of visual measurements against ground truth (vSLAM paper section
// 4.3, Table 1).
//
// A visual measurement is the robot pose at time t expressed in the robot
// frame at the landmark's creation time t_c. Its truth is therefore
//   G(t_c)^-1 * G(t)
// with G the ground-truth planar robot pose, and its errors are the distance
// sqrt(ex^2 + ey^2) of the (dx, dy) part and |wrap(dtheta - dtheta_true)|.
// Ground truth at a stamp is interpolated linearly between the two
// neighbouring ground-truth poses (heading on the shortest arc) when they are
// at most `max_gap` seconds apart; a measurement without truth at either time
// is counted, not scored.
//
// Pure: the caller supplies each measurement's pre-filter verdict, so the
// same report serves the front-end's thresholds, a back-end's verdicts read
// from a log, or any other acceptance region.
//
// The accepted measurements' errors are also binned by the true distance
// from the creation pose (the back-end's noise model grows with it) and by
// the true change of viewing direction since the creation (the measuring
// camera's heading in the world against the creating camera's, from the
// cameras' headings on the robot). Per bin, robust standard deviations
// (1.4826 x the median absolute deviation: the spread of the good ones) and
// the share of gross errors (the aliases and badly built landmarks), so the
// back-end's measurement_sigma_* can be compared with what a log shows.

#include <cstdint>
#include <iosfwd>
#include <map>
#include <string>
#include <vector>

#include "backend/prefilter.hpp"
#include "eval/metrics.hpp"
#include "eval/trajectory.hpp"

namespace vslam::eval {

// A measurement's verdict is the pre-filter's (backend/prefilter.hpp, the
// same codes as vslam.visual_measurement_t STATUS_*); never kUnfiltered here.
using MeasurementVerdict = backend::MeasurementStatus;

struct MeasurementSample {
  double t = 0;  // seconds, image time
  std::string camera;
  int64_t landmark_id = 0;
  double dx = 0, dy = 0, dtheta = 0;  // metres, radians (robot frame at creation)
  double proj_err_rms = 0;
  int num_points = 0;
  double slope = 0;
  MeasurementVerdict verdict = MeasurementVerdict::kAccepted;
};

// The creation of a landmark: when and by which camera.
struct LandmarkCreationTime {
  double t = 0;  // seconds, time of the first view (the landmark's frame)
  std::string camera;
};

struct MeasurementEvalOptions {
  double max_gap = 0.1;  // seconds between the ground-truth poses bracketing a stamp
  // Upper edges of the xy-error bands of Table 1, centimetres; errors at or
  // above the last edge form the final "> last" row.
  std::vector<double> band_edges_cm = {10, 20, 30, 40, 50, 70, 100, 150, 200};
  // Upper edges of the bins by distance from the creation pose (metres) and
  // by change of viewing direction (degrees); the last bin is open.
  std::vector<double> distance_edges_m = {0.5, 1.0, 1.5, 2.0, 3.0};
  std::vector<double> view_change_edges_deg = {10, 20, 30, 45, 60, 90};
  // A gross error: xy error or heading error beyond these.
  double gross_xy_m = 0.3;
  double gross_heading_deg = 5.0;
};

struct ScoredMeasurement {
  std::size_t index = 0;                             // into the samples
  double true_dx = 0, true_dy = 0, true_dtheta = 0;  // G(t_c)^-1 * G(t)
  double xy_error_m = 0;                             // sqrt(ex^2 + ey^2)
  double heading_error_rad = 0;                      // |wrapped|
  double signed_heading_error_rad = 0;               // wrapped, measured - true
  double creation_distance_m = 0;                    // sqrt(true_dx^2 + true_dy^2)
  // |measuring camera's heading - creating camera's| in the world, truly;
  // NaN when either camera's heading on the robot is unknown.
  double view_change_rad = 0;
};

// Accepted measurements' errors in one bin of MeasurementEvalOptions'
// distance_edges_m or view_change_edges_deg.
struct MeasurementErrorBin {
  double low = 0, high = 0;  // [low, high); high = inf for the last bin
  int64_t count = 0;
  double robust_sigma_xy_m = 0;  // of ex and ey together; NaN when count == 0
  double robust_sigma_heading_rad = 0;
  double gross_fraction = 0;  // beyond gross_xy_m or gross_heading_deg
};

struct ErrorSummary {
  ErrorStats xy_m;         // mean, median, rmse of the xy error
  ErrorStats heading_rad;  // of the absolute heading error
};

struct MeasurementBand {
  double low_cm = 0, high_cm = 0;  // [low, high); high = inf for the last row
  int64_t accepted = 0, rejected = 0;
};

// Per landmark, for spotting a landmark that is measured consistently wrong
// (a bad structure, or a place that looks like another).
struct LandmarkMeasurementStats {
  int64_t landmark_id = 0;
  std::string camera;  // that created it
  int64_t measurements = 0, accepted = 0;
  ErrorStats xy_m;  // over its scored measurements
};

struct MeasurementReport {
  std::string input;
  std::vector<MeasurementSample> samples;
  std::vector<ScoredMeasurement> scored;
  int64_t unknown_landmark = 0;  // no creation record for the landmark id
  int64_t no_truth = 0;          // ground truth missing at t or t_c
  int64_t landmarks = 0;         // distinct landmarks measured
  int64_t landmarks_created = 0;
  std::map<MeasurementVerdict, int64_t> verdicts;  // over all samples
  std::map<std::string, int64_t> per_camera;       // measurements per camera
  double duration_s = 0;                           // first to last measurement
  ErrorSummary accepted, all;
  std::vector<MeasurementBand> bands;                  // per band (Table 1, right half)
  std::vector<LandmarkMeasurementStats> per_landmark;  // ascending id
  std::vector<MeasurementErrorBin> by_distance;        // accepted, by creation distance
  std::vector<MeasurementErrorBin> by_view_change;     // accepted, by view change (known cameras)
  MeasurementEvalOptions options;

  int64_t acceptedCount() const;
  double acceptedFraction() const;  // of all samples; NaN when there are none
};

// Throws DataError when the reference is empty. camera_heading_rad: each
// camera's optical axis heading on the robot (radians from the robot's +x),
// for the view changes; cameras not in it leave the view change unknown.
MeasurementReport evaluateMeasurements(
    const Trajectory& reference, std::vector<MeasurementSample> samples,
    const std::map<int64_t, LandmarkCreationTime>& creations,
    const MeasurementEvalOptions& options = {},
    const std::map<std::string, double>& camera_heading_rad = {});

// 1.4826 x the median absolute deviation from the median: a Gaussian's
// standard deviation, unmoved by a minority of gross errors. NaN when empty.
double robustSigma(std::vector<double> values);

// One row per measurement (scored or not): time, camera, landmark, verdict,
// statistics, measured and true relative pose, errors, creation distance and
// view change (empty when not scored; the view change also when unknown).
void writeMeasurementCsv(const std::string& path, const MeasurementReport& report);

// Prints the summary, the bins by distance and by view change, and Table 1
// (cumulative and per band).
void printMeasurementReport(std::ostream& os, const MeasurementReport& report);

}  // namespace vslam::eval
