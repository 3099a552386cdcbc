#pragma once
// Textures decoded (and cropped, rotated, mirrored) once per process, so that
// a process loading several worlds (the tests, `fuzz_world`, the generated
// homes of one benchmark) does not decode or prepare the same image again.
// Internal to the world library.

#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

namespace vslam::world {

// What identifies a texture reference's pixels: for a file, its absolute
// path, size and modification time (an edited file is read again); for a
// procedural texture, the reference. nullopt when the file cannot be
// examined (the load itself then names the problem).
std::optional<std::string> textureIdentity(const std::string& reference,
                                           const std::filesystem::path& file);

// The texture cached under `key`, or make()'s result, cached (unless larger
// than the cache). The least recently used are dropped beyond 256 MB (a
// world's textures are a few tens of MB: the built-in `loop` holds 58). The
// pixels are shared with every other lookup of the key: read-only.
cv::Mat cachedTexture(const std::string& key, const std::function<cv::Mat()>& make);

}  // namespace vslam::world
