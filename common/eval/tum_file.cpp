#include "eval/tum_file.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "eval/errors.hpp"
#include "eval/output_file.hpp"
#include "util/log.hpp"

namespace vslam::eval {
namespace {

// Parses a whole field as a double; false if anything is left over.
bool parseNumber(const std::string& s, double* out) {
  if (s.empty()) return false;
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || errno == ERANGE) return false;
  *out = v;
  return true;
}

}  // namespace

std::vector<std::string> splitTumFields(const std::string& line) {
  std::vector<std::string> fields;
  std::string cur;
  for (const char c : line) {
    if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
      if (!cur.empty()) fields.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  if (!cur.empty()) fields.push_back(cur);
  return fields;
}

bool isTumCommentOrBlank(const std::string& line) {
  const auto first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

Trajectory parseTum(std::istream& in, const std::string& origin) {
  static const char* kNames[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  Trajectory traj;
  traj.name = origin;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (isTumCommentOrBlank(line)) continue;
    const std::string where = origin + ":" + std::to_string(line_no) + ": ";
    const auto fields = splitTumFields(line);
    if (fields.size() != 8) {
      throw DataError(where + "expected 8 fields 'timestamp tx ty tz qx qy qz qw', found " +
                      std::to_string(fields.size()));
    }
    double v[8];
    for (int i = 0; i < 8; ++i) {
      if (!parseNumber(fields[i], &v[i])) {
        throw DataError(where + kNames[i] + " '" + fields[i] + "' is not a number");
      }
      if (!std::isfinite(v[i])) {
        throw DataError(where + kNames[i] + " is " + fields[i] + " (must be finite)");
      }
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (!(q.norm() > 1e-9)) throw DataError(where + "quaternion qx qy qz qw has zero length");
    StampedPose p;
    p.t = v[0];
    p.position = {v[1], v[2], v[3]};
    p.orientation = q.normalized();
    traj.poses.push_back(p);
  }
  if (in.bad()) throw DataError(origin + ": read error");
  if (traj.poses.empty()) {
    throw DataError(origin + ": no poses (empty, or only comments; expected lines " +
                    "'timestamp tx ty tz qx qy qz qw')");
  }
  const std::size_t dropped = sortByTime(&traj);
  if (dropped > 0) {
    log::warn(origin, ": ", dropped, " line(s) repeat an earlier timestamp; kept the last of each");
  }
  return traj;
}

Trajectory readTumFile(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) throw DataError(file.string() + ": no such file");
  if (std::filesystem::is_directory(file, ec)) {
    throw DataError(file.string() + ": is a directory, expected a TUM trajectory file");
  }
  std::ifstream in(file);
  if (!in) throw DataError(file.string() + ": cannot open for reading");
  return parseTum(in, file.string());
}

void writeTumFile(const std::filesystem::path& file, const Trajectory& traj) {
  createParentFolder(file);
  std::FILE* f = std::fopen(file.string().c_str(), "w");
  if (!f) throw DataError(file.string() + ": cannot open for writing");
  std::fprintf(f, "# %s\n# timestamp tx ty tz qx qy qz qw\n", traj.name.c_str());
  for (const auto& p : traj.poses) {
    const Eigen::Quaterniond q = p.orientation.normalized();
    std::fprintf(f, "%.6f %.10g %.10g %.10g %.10g %.10g %.10g %.10g\n", p.t, p.position.x(),
                 p.position.y(), p.position.z(), q.x(), q.y(), q.z(), q.w());
  }
  const bool ok = std::ferror(f) == 0;
  if (std::fclose(f) != 0 || !ok) throw DataError(file.string() + ": write failed");
}

}  // namespace vslam::eval
