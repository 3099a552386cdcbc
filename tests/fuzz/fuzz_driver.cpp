// The standalone driver of a fuzz target (tests/fuzz/fuzz_target.hpp) for
// builds without libFuzzer: runs every seed, then `--runs` mutations of them
// (bit flips, boundary bytes, large counts written over 4 or 8 bytes,
// insertions, deletions, truncation, splices of two seeds), deterministic
// for a `--seed`. A crash or a sanitizer report ends the process: that is
// the test failing.
//
//   fuzz_messages [--runs N] [--seed S]     # CTest runs a few thousand
//   fuzz_messages --write-seeds DIR         # the seed corpus for scripts/fuzz
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <string>

#include "fuzz_target.hpp"

namespace {

std::string mutate(const std::vector<std::string>& seeds, std::mt19937_64& rng) {
  auto pick = [&](size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(rng); };
  std::string s = seeds.empty() ? std::string() : seeds[pick(seeds.size())];
  const int edits = 1 + static_cast<int>(pick(4));
  for (int e = 0; e < edits; ++e) {
    switch (pick(7)) {
      case 0:  // flip a bit
        if (!s.empty()) s[pick(s.size())] ^= static_cast<char>(1u << pick(8));
        break;
      case 1: {  // a boundary byte
        static const unsigned char values[] = {0x00, 0x01, 0x7f, 0x80, 0xff, '\n', ':', '-', '['};
        if (!s.empty()) s[pick(s.size())] = static_cast<char>(values[pick(sizeof(values))]);
        break;
      }
      case 2: {  // a large count over 4 or 8 bytes (the counts of LCM messages)
        static const uint64_t counts[] = {0x7fffffffULL, 0x80000000ULL, 0xffffffffULL, 500000000ULL,
                                          0x7fffffffffffffffULL};
        const uint64_t v = counts[pick(sizeof(counts) / sizeof(counts[0]))];
        const size_t width = pick(2) ? 4 : 8;
        if (s.size() >= width) {
          const size_t at = pick(s.size() - width + 1);
          for (size_t b = 0; b < width; ++b) {
            s[at + b] = static_cast<char>((v >> (8 * (width - 1 - b))) & 0xff);  // big-endian
          }
        }
        break;
      }
      case 3:  // insert random bytes
        s.insert(s.empty() ? 0 : pick(s.size() + 1),
                 std::string(1 + pick(8), static_cast<char>(pick(256))));
        break;
      case 4:  // delete a run
        if (!s.empty()) {
          const size_t at = pick(s.size());
          s.erase(at, 1 + pick(std::min<size_t>(16, s.size() - at)));
        }
        break;
      case 5:  // truncate
        if (!s.empty()) s.resize(pick(s.size()));
        break;
      default:  // splice with another seed
        if (!seeds.empty()) {
          const std::string& other = seeds[pick(seeds.size())];
          const size_t cut = s.empty() ? 0 : pick(s.size());
          const size_t from = other.empty() ? 0 : pick(other.size());
          s = s.substr(0, cut) + other.substr(from);
        }
        break;
    }
  }
  return s;
}

int run(const std::string& input) {
  return LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(input.data()), input.size());
}

}  // namespace

int main(int argc, char** argv) {
  long runs = 2000;
  uint64_t seed = 1;
  std::string write_seeds;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) {
      runs = std::atol(argv[++i]);
    } else if (a == "--seed" && i + 1 < argc) {
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (a == "--write-seeds" && i + 1 < argc) {
      write_seeds = argv[++i];
    } else {
      std::cerr << "usage: " << argv[0] << " [--runs N] [--seed S] | --write-seeds DIR\n";
      return 2;
    }
  }
  const std::vector<std::string> seeds = vslam::fuzz::seeds();
  if (!write_seeds.empty()) {
    std::filesystem::create_directories(write_seeds);
    for (size_t i = 0; i < seeds.size(); ++i) {
      std::ofstream(std::filesystem::path(write_seeds) / ("seed-" + std::to_string(i)),
                    std::ios::binary)
          << seeds[i];
    }
    std::cout << "wrote " << seeds.size() << " seeds to " << write_seeds << "\n";
    return 0;
  }
  for (const auto& s : seeds) run(s);
  std::mt19937_64 rng(seed);
  for (long r = 0; r < runs; ++r) run(mutate(seeds, rng));
  std::cout << argv[0] << ": " << seeds.size() << " seeds and " << runs
            << " mutated inputs, no crash\n";
  return 0;
}
