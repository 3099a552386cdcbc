#include "stages/param_docs.hpp"

#include <algorithm>
#include <stdexcept>

#include "stages/builtin_stages.hpp"
#include "stages/prefilter_config.hpp"

namespace vslam::stages {

namespace {

// The registry of a role: the stack's stages, then the sensor drivers.
const bus::StageRegistry& registryOf(const std::string& role) {
  return builtinStages().has(role) ? builtinStages() : driverStages();
}

}  // namespace

std::vector<std::string> documentedParamBlocks() {
  std::vector<std::string> out{"prefilter"};
  for (const bus::StageRegistry* registry : {&builtinStages(), &driverStages()}) {
    for (const auto& role : registry->roles()) {
      if (!registry->describeParams(role).empty()) out.push_back(role);
    }
  }
  return out;
}

std::vector<config::ParamDoc> declaredParams(const std::string& block,
                                             const config::StackConfig* stack) {
  if (block == "prefilter") {
    const backend::PrefilterParams defaults;
    if (!stack || !stack->root.has("prefilter")) return prefilterParamTable().describe(defaults);
    const backend::PrefilterParams configured = loadPrefilter(*stack);
    return prefilterParamTable().describe(defaults, &configured);
  }
  const auto blocks = documentedParamBlocks();
  if (std::find(blocks.begin(), blocks.end(), block) == blocks.end()) {
    throw std::invalid_argument("'" + block + "' declares no parameters");
  }
  if (stack) {
    for (const auto& instance : stack->instances()) {
      if (stack->roleOf(instance) != block) continue;
      const config::ConfigNode node = stack->process(instance);
      return registryOf(block).describeParams(block, &node);
    }
  }
  return registryOf(block).describeParams(block);
}

namespace {

// The next `marker` at the start of a line, from `from` on (one quoted in
// the text does not count).
size_t findMarker(const std::string& text, const std::string& marker, size_t from) {
  for (size_t at = text.find(marker, from); at != std::string::npos;
       at = text.find(marker, at + 1)) {
    if (at == 0 || text[at - 1] == '\n') return at;
  }
  return std::string::npos;
}

}  // namespace

std::string updateParamTables(const std::string& markdown, const config::StackConfig& stack,
                              const std::string& configured_header) {
  const std::string open = "<!-- params ", close = "<!-- /params -->";
  std::string out;
  size_t pos = 0;
  for (size_t start = findMarker(markdown, open, 0); start != std::string::npos;
       start = findMarker(markdown, open, pos)) {
    const size_t name_end = markdown.find(" -->", start);
    const size_t line_end = markdown.find('\n', start);
    if (name_end == std::string::npos || line_end == std::string::npos || name_end > line_end) {
      throw std::invalid_argument("a '" + open + "' marker without ' -->' on its line");
    }
    const std::string name = markdown.substr(start + open.size(), name_end - start - open.size());
    const size_t end = findMarker(markdown, close, line_end);
    if (end == std::string::npos) throw std::invalid_argument("'" + name + "' table not closed");
    out += markdown.substr(pos, line_end + 1 - pos);
    out += config::markdownTable(declaredParams(name, &stack), configured_header);
    pos = end;
  }
  return out + markdown.substr(pos);
}

}  // namespace vslam::stages
