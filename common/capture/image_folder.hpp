#pragma once
// An image folder with a TUM rgb.txt-style timestamps file: lines
// "timestamp relative/path.png" (seconds, any epoch), '#' comments and blank
// lines ignored. The file is outside input: every line is checked.

#include <filesystem>
#include <string>
#include <vector>

#include "util/time.hpp"

namespace vslam::capture {

struct TimestampedImage {
  Utime time_us = 0;           // from the file, microseconds on its epoch
  std::filesystem::path file;  // absolute or relative to the working directory
};

// Reads `timestamps_file`; paths are relative to its directory. Throws
// SourceError("source") naming the file and line: a missing or empty file,
// a line without two fields, a timestamp that is not a finite number or not
// after the previous one, an absolute path or one leaving the folder.
std::vector<TimestampedImage> readTimestampsFile(const std::filesystem::path& timestamps_file);

}  // namespace vslam::capture
