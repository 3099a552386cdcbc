#include "eval/json_report.hpp"

#include <cmath>
#include <fstream>

#include "eval/errors.hpp"
#include "eval/output_file.hpp"

namespace vslam::eval {

Json jsonNumber(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

void writeJsonFile(const std::filesystem::path& file, const Json& json) {
  createParentFolder(file);
  std::ofstream out(file);
  if (!out) throw DataError(file.string() + ": cannot open for writing");
  // Strings come from outside (paths, channel names): bytes that are not
  // UTF-8 are written as U+FFFD rather than failing the report.
  out << json.dump(2, ' ', false, Json::error_handler_t::replace) << "\n";
  out.close();
  if (!out) throw DataError(file.string() + ": write failed");
}

}  // namespace vslam::eval
