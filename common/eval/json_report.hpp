#pragma once
// JSON for the evaluation reports (vslam-eval --json). ordered_json keeps
// the keys in the order they are set: the layout that scripts/accuracy,
// scripts/benchmark-homes and docs/evaluation.md show.

#include <filesystem>
#include <nlohmann/json.hpp>

namespace vslam::eval {

using Json = nlohmann::ordered_json;

// A figure of a report; null when it has no value (NaN, infinite).
Json jsonNumber(double v);

// Writes `json` to `file` indented by two; throws DataError naming the file
// if it cannot be written.
void writeJsonFile(const std::filesystem::path& file, const Json& json);

}  // namespace vslam::eval
