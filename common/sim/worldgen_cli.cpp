#include "sim/worldgen_cli.hpp"

#include <CLI/CLI.hpp>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <iostream>

#include "config/config_node.hpp"
#include "sim/home_generator.hpp"
#include "sim/scenario.hpp"
#include "util/command_line.hpp"
#include "world/world.hpp"

namespace vslam::sim {
namespace {

namespace fs = std::filesystem;

bool writeFile(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  out.close();
  return static_cast<bool>(out);
}

}  // namespace

int runWorldgenCli(const std::vector<std::string>& args) {
  uint64_t seed = 0;
  std::string out_dir, kind_name = "auto";
  CLI::App app{
      "vslam-worldgen: a random home for the benchmark. Prints one line: seed, kind,\n"
      "rooms, floor area, route, duration, odometry noise and biases, hard cases.",
      "vslam-worldgen"};
  app.add_option("--seed", seed,
                 "a whole number; the same seed (and kind) gives byte-identical files")
      ->required()
      // Digits that fit: the unsigned conversion would wrap "-3" round and
      // saturate a number too large.
      ->check([](const std::string& text) -> std::string {
        uint64_t v = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, v);
        return !text.empty() && ec == std::errc() && ptr == end
                   ? ""
                   : "expects a whole number from 0 to 2^64-1, got '" + text + "'";
      });
  app.add_option("--out", out_dir, "writes DIR/world.yaml and DIR/scenario.yaml (DIR is created)")
      ->required();
  app.add_option("--kind", kind_name,
                 "single: one route; sequence: 2-4 runs, the robot carried between them; "
                 "kidnap: one carry in the middle of the route; auto: chosen by the seed, "
                 "about 60% single, 20% sequence, 20% kidnap")
      ->check(CLI::IsMember({"single", "sequence", "kidnap", "auto"}))
      ->capture_default_str();
  if (const auto code = parseCommandLine(app, "vslam-worldgen", args, std::cout, std::cerr)) {
    return *code;
  }
  HomeKind kind = autoHomeKind(seed);
  if (kind_name != "auto") parseHomeKind(kind_name, &kind);

  try {
    const GeneratedHome home = generateHome(seed, kind);
    const fs::path dir(out_dir);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      std::cerr << "vslam-worldgen: cannot create " << dir << ": " << ec.message() << "\n";
      return kExitFailure;
    }
    if (!writeFile(dir / "world.yaml", home.world_yaml) ||
        !writeFile(dir / "scenario.yaml", home.scenario_yaml)) {
      std::cerr << "vslam-worldgen: cannot write to " << dir << "\n";
      return kExitFailure;
    }
    // What the simulator will read must load (textures, geometry, keys).
    world::World::loadFile(dir / "world.yaml");
    Scenario::load(config::ConfigNode::loadFile(dir / "scenario.yaml"));
    std::cout << home.summary.line() << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "vslam-worldgen: seed " << seed << ": " << e.what() << "\n";
    return kExitFailure;
  }
  return kExitOk;
}

}  // namespace vslam::sim
