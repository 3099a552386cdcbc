#pragma once
// Test fixtures: small LCM logs written with lcm::LogFile, and helpers to read
// them back. Test data only; no estimator sees it outside tests.

#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

namespace vslam::test {

struct RecordedEvent {
  int64_t timestamp;
  std::string channel;
  std::vector<uint8_t> data;
};

// Writes `seconds` of a robot driving a circle: ODOMETRY at 50 Hz (cumulative
// pose), GROUND_TRUTH at 50 Hz and, if image_hz > 0, CAM_FORWARD_IMAGE 320x240
// gray frames with a moving pattern.
void writeDrivingLog(const std::filesystem::path& file, double seconds, double image_hz);

std::vector<RecordedEvent> readLog(const std::filesystem::path& file);
std::string readFileBytes(const std::filesystem::path& file);

// Runs a shell command, collecting stdout and stderr; returns its exit code
// (-1 if it did not exit normally).
int runCommand(const std::string& command, std::string* output);

// A per-test scratch directory, emptied if it exists; removed by the caller
// or, at the latest, when the process exits.
std::filesystem::path scratchDir(const std::string& tag);

}  // namespace vslam::test
