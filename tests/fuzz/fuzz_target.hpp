#pragma once
// What every fuzz target of tests/fuzz defines. Built with clang and
// -fsanitize=fuzzer (scripts/fuzz) a target is a libFuzzer program; in the
// normal build it is linked with fuzz_driver.cpp, which feeds it its seeds
// and a few thousand deterministic mutations of them, as a CTest test.
//
// A target must not crash, hang, leak or trip a sanitizer on any input:
// bad input is an exception of the kind the code documents (caught by the
// target) or a false return, never anything else.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace vslam::fuzz {

// Valid inputs to start from (libFuzzer's seed corpus: scripts/fuzz writes
// them with `--write-seeds DIR` of the standalone build).
std::vector<std::string> seeds();

}  // namespace vslam::fuzz
