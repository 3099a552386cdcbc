#pragma once
#include <cstddef>
#include <string>

namespace vslam {

// Levenshtein distance, for "did you mean ...?" suggestions on misspelt keys.
size_t editDistance(const std::string& a, const std::string& b);

}  // namespace vslam
