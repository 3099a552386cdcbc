#include "world/world.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <stdexcept>

#include "world/geometry2d.hpp"
#include "world/texture_cache.hpp"

namespace vslam::world {
namespace fs = std::filesystem;

namespace {

constexpr const char* kSkimageDir = "/usr/lib/python3/dist-packages/skimage/data/";
constexpr const char* kOpencvDir = "/usr/share/doc/opencv-doc/examples/data/";
constexpr const char* kProceduralPrefix = "procedural:";

bool startsWith(const std::string& s, const std::string& prefix) {
  return s.compare(0, prefix.size(), prefix) == 0;
}

// Deterministic hash -> [0, 1): procedural textures must be identical on
// every machine and run.
double hashUnit(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  x ^= x >> 31;
  return static_cast<double>(x >> 11) * (1.0 / 9007199254740992.0);
}

// Tileable multi-octave value noise in [0, 1], `size` x `size`.
cv::Mat valueNoise(int size, uint64_t seed) {
  cv::Mat acc(size, size, CV_64F, cv::Scalar(0.0));
  double amplitude = 1.0, total = 0.0;
  for (int period = 4; period <= size / 4; period *= 2) {
    const int cells = period;  // lattice cells across the image
    const double cell = static_cast<double>(size) / cells;
    for (int y = 0; y < size; ++y) {
      const double gy = y / cell;
      const int y0 = static_cast<int>(gy);
      const double fy = gy - y0, sy = fy * fy * (3 - 2 * fy);
      for (int x = 0; x < size; ++x) {
        const double gx = x / cell;
        const int x0 = static_cast<int>(gx);
        const double fx = gx - x0, sx = fx * fx * (3 - 2 * fx);
        auto lattice = [&](int i, int j) {
          return hashUnit(seed * 1000003ull + static_cast<uint64_t>(period) * 7919ull +
                          static_cast<uint64_t>((j % cells) * cells + (i % cells)));
        };
        const double v = (1 - sy) * ((1 - sx) * lattice(x0, y0) + sx * lattice(x0 + 1, y0)) +
                         sy * ((1 - sx) * lattice(x0, y0 + 1) + sx * lattice(x0 + 1, y0 + 1));
        acc.at<double>(y, x) += amplitude * v;
      }
    }
    total += amplitude;
    amplitude *= 0.6;
  }
  acc /= total;
  return acc;
}

cv::Mat proceduralTexture(const std::string& name) {
  constexpr int kSize = 512;
  cv::Mat bgr(kSize, kSize, CV_8UC3);
  if (name == "noise") {
    const cv::Mat n = valueNoise(kSize, 1);
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const double v = std::clamp(40.0 + 400.0 * (n.at<double>(y, x) - 0.5) + 128.0, 0.0, 255.0);
        bgr.at<cv::Vec3b>(y, x) =
            cv::Vec3b(cv::saturate_cast<uint8_t>(v * 0.92), cv::saturate_cast<uint8_t>(v * 0.97),
                      cv::saturate_cast<uint8_t>(v));
      }
    }
  } else if (name == "checker") {
    constexpr int kSquares = 8;
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const bool white = ((x * kSquares / kSize) + (y * kSquares / kSize)) % 2 == 0;
        bgr.at<cv::Vec3b>(y, x) = white ? cv::Vec3b(225, 225, 225) : cv::Vec3b(35, 35, 35);
      }
    }
  } else if (name == "tiles") {
    // 4x4 ceramic tiles with grout lines and a mottled glaze.
    const cv::Mat n = valueNoise(kSize, 2);
    constexpr int kTile = kSize / 4, kGrout = 6;
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        const bool grout = (x % kTile) < kGrout || (y % kTile) < kGrout;
        const double tile_shade = 0.85 + 0.15 * hashUnit(77 + (y / kTile) * 4 + (x / kTile));
        const double v = grout ? 95.0 : 255.0 * tile_shade * (0.8 + 0.35 * n.at<double>(y, x));
        bgr.at<cv::Vec3b>(y, x) =
            cv::Vec3b(cv::saturate_cast<uint8_t>(v), cv::saturate_cast<uint8_t>(v * 0.98),
                      cv::saturate_cast<uint8_t>(v * 0.93));
      }
    }
  } else {
    return {};
  }
  return bgr;
}

}  // namespace

std::vector<std::string> proceduralTextureNames() { return {"noise", "checker", "tiles"}; }

fs::path resolveTexturePath(const std::string& reference, const fs::path& base_dir) {
  if (startsWith(reference, kProceduralPrefix)) return {};
  if (startsWith(reference, "skimage:")) return fs::path(kSkimageDir) / reference.substr(8);
  if (startsWith(reference, "opencv:")) return fs::path(kOpencvDir) / reference.substr(7);
  const fs::path p(reference);
  return p.is_absolute() ? p : base_dir / p;
}

namespace {

cv::Mat loadTextureUncached(const std::string& reference, const fs::path& file) {
  if (startsWith(reference, kProceduralPrefix)) {
    const std::string name = reference.substr(std::string(kProceduralPrefix).size());
    cv::Mat t = proceduralTexture(name);
    if (t.empty()) {
      std::string known;
      for (const auto& n : proceduralTextureNames()) known += (known.empty() ? "" : ", ") + n;
      throw std::runtime_error("unknown procedural texture '" + name + "' (known: " + known + ")");
    }
    return t;
  }
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    std::string hint;
    if (startsWith(reference, "skimage:")) hint = " (Debian package python3-skimage)";
    if (startsWith(reference, "opencv:")) hint = " (Debian package opencv-doc)";
    throw std::runtime_error("texture file not found: " + file.string() + hint);
  }
  cv::Mat img = cv::imread(file.string(), cv::IMREAD_COLOR);
  if (img.empty() || img.cols < 2 || img.rows < 2) {
    throw std::runtime_error("cannot read texture image " + file.string());
  }
  return img;
}

}  // namespace

cv::Mat loadTexture(const std::string& reference, const fs::path& base_dir) {
  const fs::path file = resolveTexturePath(reference, base_dir);
  const std::optional<std::string> identity = textureIdentity(reference, file);
  if (!identity) return loadTextureUncached(reference, file);
  return cachedTexture(*identity, [&] { return loadTextureUncached(reference, file); });
}

int World::addTexture(const std::string& reference, const fs::path& base_dir) {
  textures.push_back(loadTexture(reference, base_dir));
  return static_cast<int>(textures.size()) - 1;
}

int World::roomIndexAt(double x, double y) const {
  const Eigen::Vector2d q(x, y);
  for (size_t i = 0; i < rooms.size(); ++i) {
    if (geo::contains(rooms[i].polygon, q)) return static_cast<int>(i);
  }
  return -1;
}

std::string World::roomAt(double x, double y) const {
  const int i = roomIndexAt(x, y);
  return i < 0 ? std::string() : rooms[static_cast<size_t>(i)].name;
}

Eigen::AlignedBox2d World::bounds() const {
  Eigen::AlignedBox2d box;
  for (const Room& r : rooms) {
    for (const auto& v : r.polygon) box.extend(v);
  }
  return box;
}

bool World::isFree(double x, double y, double radius) const {
  const Eigen::Vector2d q(x, y);
  if (roomIndexAt(x, y) < 0) return false;
  for (const WallSegment& w : walls) {
    if (geo::distanceToSegment(q, w.a, w.b) < radius) return false;
  }
  for (const auto& o : obstacles) {
    if (geo::contains(o, q) || geo::distanceToBoundary(o, q) < radius) return false;
  }
  // A disc reaching into a door gap must find a room on the far side too
  // (a door in an outside wall leads nowhere the robot may go).
  for (const Door& d : doors) {
    if (geo::distanceToSegment(q, d.a, d.b) >= radius) continue;
    const Eigen::Vector2d mid = 0.5 * (d.a + d.b);
    const Eigen::Vector2d along = (d.b - d.a).normalized();
    const Eigen::Vector2d normal(-along.y(), along.x());
    constexpr double kStep = 0.02;
    if (roomIndexAt(mid.x() + kStep * normal.x(), mid.y() + kStep * normal.y()) < 0 ||
        roomIndexAt(mid.x() - kStep * normal.x(), mid.y() - kStep * normal.y()) < 0) {
      return false;
    }
  }
  return true;
}

std::vector<Surface> makeBox(const Eigen::Vector3d& centre_bottom, const Eigen::Vector3d& size,
                             double yaw, int texture, double texture_scale_m) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  const Eigen::Vector3d ax(c, s, 0), ay(-s, c, 0), az(0, 0, 1);
  const Eigen::Vector3d hx = 0.5 * size.x() * ax, hy = 0.5 * size.y() * ay, h = size.z() * az;
  const Eigen::Vector3d& b = centre_bottom;
  // Bottom corners counter-clockwise from above: (-x,-y), (+x,-y), (+x,+y), (-x,+y).
  const Eigen::Vector3d p0 = b - hx - hy, p1 = b + hx - hy, p2 = b + hx + hy, p3 = b - hx + hy;
  auto side = [&](const Eigen::Vector3d& left, const Eigen::Vector3d& right) {
    // Seen from outside: bottom-left, bottom-right, top-right, top-left.
    Surface f;
    f.corners = {left, right, right + h, left + h};
    f.texture = texture;
    f.texture_scale_m = texture_scale_m;
    return f;
  };
  std::vector<Surface> faces(5);
  faces[kBoxPlusX] = side(p1, p2);
  faces[kBoxMinusX] = side(p3, p0);
  faces[kBoxPlusY] = side(p2, p3);
  faces[kBoxMinusY] = side(p0, p1);
  // The top reads upright for someone standing at the +x face.
  Surface top;
  top.corners = {p1 + h, p2 + h, p3 + h, p0 + h};
  top.texture = texture;
  top.texture_scale_m = texture_scale_m;
  faces[kBoxTop] = top;
  return faces;
}

Eigen::Isometry3d levelCameraPose(const Eigen::Vector3d& position, double yaw, double pitch) {
  const Eigen::Vector3d z(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                          std::sin(pitch));
  const Eigen::Vector3d x(std::sin(yaw), -std::cos(yaw), 0.0);
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = position;
  return T;
}

}  // namespace vslam::world
