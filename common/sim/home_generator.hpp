#pragma once
// Random homes for a benchmark, so that the stack can be judged in homes
// nobody tuned it on: a seed gives a furnished multi-room world file
// (docs/world-format.md) and a scenario driving a robot round it
// (config/scenarios/*.yaml format), byte for byte the same on every run.
//
// A home has 1-6 rectangular rooms (20-120 m^2 from recursive splits of a
// footprint, sometimes a narrow corridor, sometimes a wide open-plan
// opening), doors connecting every room, photo-textured walls, floors and
// furniture against the walls, and a share of the hard cases of real homes:
// periodic wallpaper in several rooms, floor tiles, rows of identical
// cupboards, plain walls and dim rooms. The route is planned on a grid over
// World::isFree and revisits places so that loops close; odometry noise,
// biases and wheel slips are drawn per home. A `sequence` home is driven in
// 2-4 runs with the robot carried between them, a `kidnap` home has one
// carry in the middle of its route; both express the carries as the
// scenario's `disturbances: kidnap:` entries.

#include <cstdint>
#include <string>
#include <vector>

#include "sim/scenario.hpp"

namespace vslam::sim {

enum class HomeKind { kSingle, kSequence, kKidnap };

const char* homeKindName(HomeKind kind);  // "single", "sequence", "kidnap"
// Parses a name of homeKindName; false if it is none of them.
bool parseHomeKind(const std::string& name, HomeKind* kind);
// The kind a seed gets when none is asked for: about 60% single, 20%
// sequence, 20% kidnap.
HomeKind autoHomeKind(uint64_t seed);

struct HomeSummary {
  uint64_t seed = 0;
  HomeKind kind = HomeKind::kSingle;
  int rooms = 0;
  double floor_area_m2 = 0;
  std::vector<std::string> plan;  // floor-plan features: "corridor", "open-plan"
  std::string route_style;        // "loop", "out-and-back" or "explore"
  int runs = 1;                   // driven stretches between carries
  double route_length_m = 0;      // driven, carries excluded
  double duration_s = 0;          // robot time of the whole scenario
  double speed_mps = 0;
  double turn_rate_dps = 0;
  OdometryParams odometry;
  // Present hard cases: "wallpaper", "tiles", "cupboards", "plain-walls", "dim-room".
  std::vector<std::string> hard_cases;

  // One line of key=value fields, e.g. "seed=7 kind=single runs=1 rooms=4
  // area_m2=63.5 ... hard=wallpaper,tiles".
  std::string line() const;
};

struct GeneratedHome {
  std::string world_yaml;     // the text of world.yaml
  std::string scenario_yaml;  // the text of scenario.yaml, which names `world: world.yaml`
  HomeSummary summary;
};

// The home of `seed` and `kind` (deterministic: the same arguments give
// byte-identical texts). Throws std::runtime_error if no valid home came out
// of its attempts (never seen; the tests generate many seeds).
GeneratedHome generateHome(uint64_t seed, HomeKind kind);

}  // namespace vslam::sim
