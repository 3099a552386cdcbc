#pragma once
// Maps a role name ("deadreckon", "frontend", "backend", ...) to a factory
// that reads the stage's parameter block and builds it. Process mains and
// vslam-replay build stages through the same registry, so a stage is
// configured identically live and in replay.

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bus/stage.hpp"
#include "config/stack_config.hpp"

namespace vslam::bus {

struct StageSetup {
  const config::StackConfig& stack;
  config::ConfigNode params;  // the processes.<instance> block
  std::string instance;
};

using StageFactory = std::function<std::unique_ptr<Stage>(const StageSetup&)>;

class StageRegistry {
 public:
  void add(const std::string& role, StageFactory factory);
  bool has(const std::string& role) const;
  std::vector<std::string> roles() const;
  // Builds the stage of `instance` from the stack config: checks the block's
  // role is known (and equals expected_role if given), runs the factory, then
  // rejects keys the factory did not read. Throws config::ConfigError.
  std::unique_ptr<Stage> create(const config::StackConfig& stack, const std::string& instance,
                                const std::string& expected_role = "") const;

 private:
  std::map<std::string, StageFactory> factories_;
};

}  // namespace vslam::bus
