#pragma once
// Helpers for the evaluation tests: reading small LCM logs (written with
// bus::LogWriter), running the built programs, scratch folders. Without
// vslam_test_support, so these tests build on their own.

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bus/log_writer.hpp"

namespace vslam::test {

struct LoggedEvent {
  int64_t timestamp;
  std::string channel;
  std::vector<uint8_t> data;
};

inline std::vector<LoggedEvent> readLogEvents(const std::filesystem::path& file) {
  lcm::LogFile log(file.string(), "r");
  if (!log.good()) throw std::runtime_error("cannot open " + file.string());
  std::vector<LoggedEvent> out;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    const auto* d = static_cast<const uint8_t*>(ev->data);
    out.push_back({ev->timestamp, ev->channel, std::vector<uint8_t>(d, d + ev->datalen)});
  }
  return out;
}

inline std::string fileBytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A fresh scratch directory for one test; the caller removes it.
inline std::filesystem::path freshDir(const std::string& tag) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("vslam_" + tag + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

struct RunResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

inline std::string shellQuote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs a program from the build's bin/ directory and collects its output.
inline RunResult runProgram(const std::string& program, const std::vector<std::string>& args) {
  std::string cmd = shellQuote(std::string(VSLAM_BIN_DIR) + "/" + program);
  for (const auto& a : args) cmd += " " + shellQuote(a);
  cmd += " 2>&1";
  RunResult r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) throw std::runtime_error("cannot run " + cmd);
  std::array<char, 4096> buf{};
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

}  // namespace vslam::test
