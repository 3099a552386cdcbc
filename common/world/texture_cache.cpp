#include "world/texture_cache.hpp"

#include <list>
#include <mutex>
#include <utility>

namespace vslam::world {
namespace fs = std::filesystem;

namespace {

constexpr size_t kTextureCacheBytes = size_t{256} << 20;

size_t bytesOf(const cv::Mat& m) { return m.total() * m.elemSize(); }

class TextureCache {
 public:
  std::optional<cv::Mat> find(const std::string& key) {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->first != key) continue;
      entries_.splice(entries_.begin(), entries_, it);
      return entries_.front().second;
    }
    return std::nullopt;
  }

  void insert(const std::string& key, const cv::Mat& texture) {
    if (bytesOf(texture) > kTextureCacheBytes) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    entries_.emplace_front(key, texture);
    bytes_ += bytesOf(texture);
    while (bytes_ > kTextureCacheBytes) {
      bytes_ -= bytesOf(entries_.back().second);
      entries_.pop_back();
    }
  }

 private:
  std::mutex mutex_;
  std::list<std::pair<std::string, cv::Mat>> entries_;  // most recently used first
  size_t bytes_ = 0;
};

TextureCache& cache() {
  static TextureCache instance;
  return instance;
}

}  // namespace

std::optional<std::string> textureIdentity(const std::string& reference, const fs::path& file) {
  if (file.empty()) return reference;
  std::error_code size_error, time_error, path_error;
  const auto size = fs::file_size(file, size_error);
  const auto time = fs::last_write_time(file, time_error);
  const fs::path absolute = fs::absolute(file, path_error);
  if (size_error || time_error || path_error) return std::nullopt;
  return absolute.string() + "|" + std::to_string(size) + "|" +
         std::to_string(time.time_since_epoch().count());
}

cv::Mat cachedTexture(const std::string& key, const std::function<cv::Mat()>& make) {
  if (std::optional<cv::Mat> hit = cache().find(key)) return *hit;
  cv::Mat texture = make();
  cache().insert(key, texture);
  return texture;
}

}  // namespace vslam::world
