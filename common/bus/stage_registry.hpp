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
#include "config/param_table.hpp"
#include "config/stack_config.hpp"

namespace vslam::bus {

struct StageSetup {
  const config::StackConfig& stack;
  config::ConfigNode params;  // the processes.<instance> block
  std::string instance;
};

using StageFactory = std::function<std::unique_ptr<Stage>(const StageSetup&)>;
// The role's declared parameters with their defaults; given a block of a
// config file, also the values it sets where they differ.
using ParamDescriber =
    std::function<std::vector<config::ParamDoc>(const config::ConfigNode* block)>;

// The describer of a role whose parameters are one ParamTable (`table`
// must outlive the registry: a function-local static).
template <class Params>
ParamDescriber describeWith(const config::ParamTable<Params>& table) {
  return [&table](const config::ConfigNode* block) {
    const Params defaults;
    if (!block) return table.describe(defaults);
    Params configured;
    table.load(*block, configured);
    return table.describe(defaults, &configured, block);
  };
}

class StageRegistry {
 public:
  void add(const std::string& role, StageFactory factory, ParamDescriber params = {});
  bool has(const std::string& role) const;
  // The role's declared parameters (empty if it declared none).
  std::vector<config::ParamDoc> describeParams(const std::string& role,
                                               const config::ConfigNode* block = nullptr) const;
  std::vector<std::string> roles() const;
  // Builds the stage of `instance` from the stack config: checks the block's
  // role is known (and equals expected_role if given), runs the factory, then
  // rejects keys the factory did not read. Throws config::ConfigError.
  std::unique_ptr<Stage> create(const config::StackConfig& stack, const std::string& instance,
                                const std::string& expected_role = "") const;

 private:
  std::map<std::string, StageFactory> factories_;
  std::map<std::string, ParamDescriber> describers_;
};

}  // namespace vslam::bus
