#include "bus/stage_registry.hpp"

#include <stdexcept>

namespace vslam::bus {

void StageRegistry::add(const std::string& role, StageFactory factory, ParamDescriber params) {
  if (!factories_.emplace(role, std::move(factory)).second) {
    throw std::logic_error("stage role '" + role + "' registered twice");
  }
  if (params) describers_.emplace(role, std::move(params));
}

std::vector<config::ParamDoc> StageRegistry::describeParams(const std::string& role,
                                                            const config::ConfigNode* block) const {
  auto it = describers_.find(role);
  if (it == describers_.end()) return {};
  return it->second(block);
}

bool StageRegistry::has(const std::string& role) const { return factories_.count(role) > 0; }

std::vector<std::string> StageRegistry::roles() const {
  std::vector<std::string> out;
  for (const auto& kv : factories_) out.push_back(kv.first);
  return out;
}

std::unique_ptr<Stage> StageRegistry::create(const config::StackConfig& stack,
                                             const std::string& instance,
                                             const std::string& expected_role) const {
  config::ConfigNode params = stack.process(instance);
  const std::string role = params.getString("role");
  if (!expected_role.empty() && role != expected_role) {
    throw params.error("role", "this program runs role '" + expected_role + "', but instance '" +
                                   instance + "' has role '" + role + "'");
  }
  auto it = factories_.find(role);
  if (it == factories_.end()) {
    std::string known;
    for (const auto& r : roles()) known += (known.empty() ? "" : ", ") + r;
    throw params.error("role", "unknown role '" + role + "'; known roles: " + known);
  }
  auto stage = it->second(StageSetup{stack, params, instance});
  params.requireAllKeysUsed();
  return stage;
}

}  // namespace vslam::bus
