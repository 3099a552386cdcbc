// vslam-worldgen: a random home for the benchmark (common/sim/home_generator.hpp):
// writes DIR/world.yaml and DIR/scenario.yaml, checks that both load, and
// prints the home's one-line summary.
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "bus/process_main.hpp"
#include "config/config_node.hpp"
#include "sim/home_generator.hpp"
#include "sim/scenario.hpp"
#include "world/world.hpp"

namespace {

namespace fs = std::filesystem;
using namespace vslam;

void usage(std::ostream& os) {
  os << "usage: vslam-worldgen --seed S --out DIR [--kind single|sequence|kidnap|auto]\n"
        "  --seed S   a whole number; the same seed (and kind) gives byte-identical files\n"
        "  --out DIR  writes DIR/world.yaml and DIR/scenario.yaml (DIR is created)\n"
        "  --kind K   single: one route; sequence: 2-4 runs, the robot carried between\n"
        "             them; kidnap: one carry in the middle of the route; auto (default):\n"
        "             chosen by the seed, about 60% single, 20% sequence, 20% kidnap\n"
        "Prints one line: seed, kind, rooms, floor area, route, duration, odometry\n"
        "noise and biases, hard cases.\n";
}

int usageError(const std::string& message) {
  std::cerr << "vslam-worldgen: " << message << "\n";
  usage(std::cerr);
  return bus::kExitUsage;
}

std::optional<uint64_t> parseSeed(const std::string& text) {
  if (text.empty() || text.size() > 20 ||
      text.find_first_not_of("0123456789") != std::string::npos) {
    return std::nullopt;
  }
  errno = 0;
  const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
  if (errno == ERANGE) return std::nullopt;
  return static_cast<uint64_t>(v);
}

bool writeFile(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  out.close();
  return static_cast<bool>(out);
}

}  // namespace

int main(int argc, char** argv) {
  std::optional<uint64_t> seed;
  std::string out_dir, kind_name = "auto";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      usage(std::cout);
      return bus::kExitOk;
    }
    if (arg != "--seed" && arg != "--out" && arg != "--kind") {
      return usageError("unknown argument '" + arg + "'");
    }
    if (i + 1 >= argc) return usageError(arg + " needs a value");
    const std::string value = argv[++i];
    if (arg == "--seed") {
      seed = parseSeed(value);
      if (!seed) return usageError("--seed expects a whole number >= 0, got '" + value + "'");
    } else if (arg == "--out") {
      out_dir = value;
    } else {
      kind_name = value;
    }
  }
  if (!seed) return usageError("--seed is required");
  if (out_dir.empty()) return usageError("--out is required");
  sim::HomeKind kind = sim::autoHomeKind(*seed);
  if (kind_name != "auto" && !sim::parseHomeKind(kind_name, &kind)) {
    return usageError("--kind expects single, sequence, kidnap or auto, got '" + kind_name + "'");
  }

  try {
    const sim::GeneratedHome home = sim::generateHome(*seed, kind);
    const fs::path dir(out_dir);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      std::cerr << "vslam-worldgen: cannot create " << dir << ": " << ec.message() << "\n";
      return bus::kExitFailure;
    }
    if (!writeFile(dir / "world.yaml", home.world_yaml) ||
        !writeFile(dir / "scenario.yaml", home.scenario_yaml)) {
      std::cerr << "vslam-worldgen: cannot write to " << dir << "\n";
      return bus::kExitFailure;
    }
    // What the simulator will read must load (textures, geometry, keys).
    world::World::loadFile(dir / "world.yaml");
    sim::Scenario::load(config::ConfigNode::loadFile(dir / "scenario.yaml"));
    std::cout << home.summary.line() << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "vslam-worldgen: seed " << *seed << ": " << e.what() << "\n";
    return bus::kExitFailure;
  }
  return bus::kExitOk;
}
