#pragma once
// The documentation's parameter tables, made from the declarations
// (config/param_table.hpp) so that they cannot drift from the code. A docs
// page marks where a table goes:
//
//   <!-- params backend -->
//   (the generated table)
//   <!-- /params -->
//
// and the test ConfigDocs.ParameterTablesAreTheDeclaredOnes fails when a
// marked table differs from the declaration; scripts/config-docs rewrites
// them.

#include <string>
#include <vector>

#include "config/param_table.hpp"
#include "config/stack_config.hpp"

namespace vslam::stages {

// Every role of builtinStages() and driverStages() that declares its keys,
// and "prefilter" (the stack's top-level block).
std::vector<std::string> documentedParamBlocks();

// The declared keys of a role (or "prefilter"), with their defaults; with a
// stack config, each row also gives the value the config sets where it
// differs (for a role: in its first instance). Throws std::invalid_argument
// for a name that declares nothing.
std::vector<config::ParamDoc> declaredParams(const std::string& block,
                                             const config::StackConfig* stack = nullptr);

// `markdown` with every marked table replaced by the declared one
// (configured values from `stack`, in a column headed `configured_header`).
// Throws std::invalid_argument for an unknown name or an unclosed marker.
std::string updateParamTables(const std::string& markdown, const config::StackConfig& stack,
                              const std::string& configured_header);

}  // namespace vslam::stages
