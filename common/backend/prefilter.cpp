#include "backend/prefilter.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vslam::backend {

const char* toString(MeasurementStatus s) {
  switch (s) {
    case MeasurementStatus::kUnfiltered:
      return "unfiltered";
    case MeasurementStatus::kAccepted:
      return "accepted";
    case MeasurementStatus::kRejectedProjErr:
      return "rejected: ProjErrRMS";
    case MeasurementStatus::kRejectedNumPoints:
      return "rejected: NPoints";
    case MeasurementStatus::kRejectedSlope:
      return "rejected: Slope";
    case MeasurementStatus::kRejectedInvalid:
      return "rejected: invalid";
  }
  return "unknown";
}

const char* metricName(MeasurementStatus s) {
  switch (s) {
    case MeasurementStatus::kUnfiltered:
      return "unfiltered";
    case MeasurementStatus::kAccepted:
      return "accepted";
    case MeasurementStatus::kRejectedProjErr:
      return "rejected_proj_err";
    case MeasurementStatus::kRejectedNumPoints:
      return "rejected_num_points";
    case MeasurementStatus::kRejectedSlope:
      return "rejected_slope";
    case MeasurementStatus::kRejectedInvalid:
      return "rejected_invalid";
  }
  return "unknown";
}

void PrefilterParams::validate() const {
  if (!(max_proj_err_rms_px > 0) || !std::isfinite(max_proj_err_rms_px))
    throw std::invalid_argument("prefilter: max_proj_err_rms_px must be positive and finite");
  if (min_num_points < 0) throw std::invalid_argument("prefilter: min_num_points must be >= 0");
  if (!(max_slope >= 0) || std::isnan(max_slope))
    throw std::invalid_argument("prefilter: max_slope must be >= 0");
}

MeasurementStatus prefilter(const PrefilterInput& m, const PrefilterParams& params) {
  // Slope may be +inf (tilted 90 degrees or more): a slope rejection, not invalid.
  if (!m.relative.isFinite() || !std::isfinite(m.proj_err_rms_px) || std::isnan(m.slope) ||
      m.num_points < 0 || m.proj_err_rms_px < 0 || m.slope < 0)
    return MeasurementStatus::kRejectedInvalid;
  if (m.proj_err_rms_px > params.max_proj_err_rms_px) return MeasurementStatus::kRejectedProjErr;
  if (m.num_points < params.min_num_points) return MeasurementStatus::kRejectedNumPoints;
  if (m.slope > params.max_slope) return MeasurementStatus::kRejectedSlope;
  return MeasurementStatus::kAccepted;
}

}  // namespace vslam::backend
