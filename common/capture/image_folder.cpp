#include "capture/image_folder.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "capture/frame_source.hpp"

namespace vslam::capture {
namespace fs = std::filesystem;

std::vector<TimestampedImage> readTimestampsFile(const fs::path& timestamps_file) {
  std::ifstream in(timestamps_file);
  if (!in) throw SourceError("source", "cannot read timestamps file " + timestamps_file.string());
  const fs::path dir = timestamps_file.parent_path();
  std::vector<TimestampedImage> out;
  std::string line;
  int line_number = 0;
  auto fail = [&](const std::string& why) {
    throw SourceError("source",
                      timestamps_file.string() + ":" + std::to_string(line_number) + ": " + why);
  };
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::string stamp, path, extra;
    if (!(fields >> stamp >> path) || (fields >> extra)) {
      fail("expected 'timestamp relative/path', got '" + line + "'");
    }
    double seconds = 0;
    try {
      size_t used = 0;
      seconds = std::stod(stamp, &used);
      if (used != stamp.size()) throw std::invalid_argument(stamp);
    } catch (const std::exception&) {
      fail("timestamp '" + stamp + "' is not a number");
    }
    if (!std::isfinite(seconds) || std::abs(seconds) > 1e11) {
      fail("timestamp '" + stamp + "' is out of range");
    }
    const fs::path relative = fs::path(path).lexically_normal();
    if (relative.is_absolute() || relative.empty() || *relative.begin() == "..") {
      fail("path '" + path + "' must be relative to the folder and stay inside it");
    }
    const Utime t = static_cast<Utime>(std::llround(seconds * 1e6));
    if (!out.empty() && t <= out.back().time_us) {
      fail("timestamp " + stamp + " is not after the previous one");
    }
    out.push_back({t, dir / relative});
  }
  if (out.empty()) {
    throw SourceError("source", timestamps_file.string() + " lists no images");
  }
  return out;
}

}  // namespace vslam::capture
