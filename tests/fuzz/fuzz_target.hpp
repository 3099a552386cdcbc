#pragma once
// What every fuzz target of tests/fuzz defines. Built with clang and
// -fsanitize=fuzzer (scripts/fuzz) a target is a libFuzzer program; in the
// normal build it is linked with fuzz_driver.cpp, which feeds it its seeds
// and a few thousand deterministic mutations of them, as a CTest test.
//
// A target must not crash, hang, leak or trip a sanitizer on any input:
// bad input is an exception of the kind the code documents (caught by the
// target) or a false return, never anything else.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace vslam::fuzz {

// Valid inputs to start from (libFuzzer's seed corpus: scripts/fuzz writes
// them with `--write-seeds DIR` of the standalone build).
std::vector<std::string> seeds();

// A scratch directory of the target's own (vslam_fuzz_<tag>_<pid> in the
// temporary directory), made on the first call and removed when the
// process exits. One per target: later calls return the first one.
inline std::filesystem::path scratchDir(const std::string& tag) {
  struct RemovedAtExit {
    std::filesystem::path dir;
    pid_t owner = ::getpid();
    ~RemovedAtExit() {
      std::error_code ignored;
      if (::getpid() == owner) std::filesystem::remove_all(dir, ignored);
    }
  };
  static const RemovedAtExit scratch{[&] {
    auto dir = std::filesystem::temp_directory_path() /
               ("vslam_fuzz_" + tag + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    return dir;
  }()};
  return scratch.dir;
}

}  // namespace vslam::fuzz
