#include "sim/home_generator.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <queue>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include "sim/motion.hpp"
#include "util/angles.hpp"
#include "world/world.hpp"

namespace vslam::sim {
namespace {

using Vec2 = Eigen::Vector2d;

// The benchmark robot (MotionParams' default radius) and the margins its
// routes keep: the planner uses grid cells free for kPlanClearance, every
// driven segment is then checked free for kSegmentClearance.
constexpr double kRobotRadius = 0.2;
constexpr double kPlanClearance = kRobotRadius + 0.1;
constexpr double kSegmentClearance = kRobotRadius + 0.05;
constexpr double kSampleStep = 0.02;  // m between the checked points of a segment
constexpr double kCell = 0.05;        // planning grid
constexpr double kOdometryRateHz = 50;
constexpr double kLayoutStep = 0.05;  // room corners, furniture and doors on a 5 cm grid
constexpr double kMinRoomSide = 2.2;
constexpr double kMinArea = 20, kMaxArea = 120;
constexpr double kWallGap = 0.02;     // furniture stands this far off its wall
constexpr double kPassage = 0.8;      // kept free in front of furniture and round tables
constexpr double kDoorKeepOut = 1.0;  // kept free in front of a door, on both sides
constexpr double kMinDuration = 90, kMaxDuration = 200;  // robot time of a scenario, s
constexpr int kAttempts = 40;

// ---- Randomness: std::mt19937_64 and std::seed_seq are specified exactly by
// the standard, the distributions are not, so values are drawn from raw bits.
class Rng {
 public:
  Rng(uint64_t seed, uint64_t stream) {
    std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32),
                      static_cast<uint32_t>(stream), static_cast<uint32_t>(stream >> 32)};
    engine_.seed(seq);
  }
  double unit() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  size_t index(size_t n) { return std::min(n - 1, static_cast<size_t>(unit() * n)); }
  bool chance(double p) { return unit() < p; }
  uint64_t bits() { return engine_(); }
  template <class T>
  const T& pick(const std::vector<T>& v) {
    return v[index(v.size())];
  }
  template <class T>
  void shuffle(std::vector<T>& v) {
    for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[index(i)]);
  }

 private:
  std::mt19937_64 engine_;
};

double roundTo(double v, double step) { return std::round(v / step) * step; }
// Millimetres: the double that reading the written text gives back, so that
// the generator's own drive simulation sees exactly what the simulator will.
double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

// Fixed decimals without trailing zeros.
std::string num(double v, int decimals = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

std::string signedNum(double v, int decimals) { return (v >= 0 ? "+" : "") + num(v, decimals); }

std::string joined(const std::vector<std::string>& parts, const char* sep) {
  std::string s;
  for (const auto& p : parts) s += (s.empty() ? "" : sep) + p;
  return s;
}

// ---- Geometry: every room is an axis-aligned rectangle.
struct Rect {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  double w() const { return x1 - x0; }
  double h() const { return y1 - y0; }
  double area() const { return w() * h(); }
  Vec2 centre() const { return {0.5 * (x0 + x1), 0.5 * (y0 + y1)}; }
  static Rect around(const Vec2& p, const Vec2& q) {
    return {std::min(p.x(), q.x()), std::min(p.y(), q.y()), std::max(p.x(), q.x()),
            std::max(p.y(), q.y())};
  }
  Rect grown(double d) const { return {x0 - d, y0 - d, x1 + d, y1 + d}; }
  bool intersects(const Rect& o) const {
    return x0 < o.x1 - 1e-9 && o.x0 < x1 - 1e-9 && y0 < o.y1 - 1e-9 && o.y0 < y1 - 1e-9;
  }
  bool within(const Rect& o) const {
    return x0 >= o.x0 - 1e-9 && y0 >= o.y0 - 1e-9 && x1 <= o.x1 + 1e-9 && y1 <= o.y1 + 1e-9;
  }
};

// Edge e of a room, counter-clockwise from the south-west corner: 0 south,
// 1 east, 2 north, 3 west; `n` points into the room.
struct Wall {
  Vec2 a, t, n;
  double length = 0;
  double facingDeg() const { return std::round(radToDeg(std::atan2(n.y(), n.x()))); }
  Vec2 at(double s, double out) const { return a + s * t + out * n; }
};

Wall wallOf(const Rect& r, int edge) {
  const std::array<Vec2, 4> c = {Vec2(r.x0, r.y0), Vec2(r.x1, r.y0), Vec2(r.x1, r.y1),
                                 Vec2(r.x0, r.y1)};
  Wall w;
  w.a = c[static_cast<size_t>(edge)];
  const Vec2 d = c[static_cast<size_t>((edge + 1) % 4)] - w.a;
  w.length = d.norm();
  w.t = d / w.length;
  w.n = Vec2(-w.t.y(), w.t.x());
  return w;
}

// ---- Materials
struct Material {
  std::string texture;  // reference; empty: uniform `albedo`
  double scale_m = 1;
  int rotate_deg = 0;
  std::vector<int> crop;
  std::optional<bool> mirror;
  double albedo = 0.75;
  double gain = 1;
};

std::string materialYaml(const Material& m) {
  std::string s = "{";
  if (m.texture.empty()) {
    s += "albedo: " + num(m.albedo, 2);
  } else {
    s += "texture: \"" + m.texture + "\", scale_m: " + num(m.scale_m, 2);
    if (m.rotate_deg != 0) s += ", rotate_deg: " + std::to_string(m.rotate_deg);
    if (!m.crop.empty()) {
      s += ", crop: [" + std::to_string(m.crop[0]);
      for (size_t i = 1; i < m.crop.size(); ++i) s += ", " + std::to_string(m.crop[i]);
      s += "]";
    }
    if (m.mirror) s += std::string(", mirror: ") + (*m.mirror ? "true" : "false");
  }
  if (m.gain != 1) s += ", gain: " + num(m.gain, 3);
  return s + "}";
}

// The home's materials: defined by role, written (sorted by name) once
// used, with a darker twin of each for the dim room.
class Materials {
 public:
  void define(const std::string& name, const Material& m) { defined_[name] = m; }
  const Material& get(const std::string& name) const { return defined_.at(name); }
  void setDimGain(double gain) { dim_gain_ = gain; }
  double dimGain() const { return dim_gain_; }
  std::string use(const std::string& name, bool dim) {
    const std::string used = dim ? name + "_dim" : name;
    if (!used_.count(used)) {
      Material m = defined_.at(name);
      if (dim) m.gain = roundTo(m.gain * dim_gain_, 0.001);
      used_[used] = m;
    }
    return used;
  }
  // `plain`: every material a uniform grey (for a planning world that loads no image).
  std::string yaml(bool plain) const {
    size_t width = 0;
    for (const auto& [name, m] : used_) width = std::max(width, name.size());
    std::string s = "materials:\n";
    for (const auto& [name, m] : used_) {
      s += "  " + name + ":" + std::string(width + 1 - name.size(), ' ') +
           (plain ? std::string("{albedo: 0.5}") : materialYaml(m)) + "\n";
    }
    return s;
  }

 private:
  std::map<std::string, Material> defined_;
  std::map<std::string, Material> used_;
  double dim_gain_ = 1;
};

Material photo(const std::string& ref, double scale_m, double gain = 1) {
  Material m;
  m.texture = ref;
  m.scale_m = scale_m;
  m.gain = gain;
  return m;
}
Material albedo(double a) {
  Material m;
  m.albedo = a;
  return m;
}

// Wall photos of the installed pool (the references config/worlds uses),
// each mirrored on repeat so that only the deliberate wallpaper aliases.
struct WallPhoto {
  const char* name;
  const char* ref;
  double scale_m;
  int rotate_deg;
};
constexpr WallPhoto kWallPhotos[] = {
    {"mural", "opencv:graf1.png", 3.0, 0},
    {"facade", "opencv:building.jpg", 3.2, 0},
    {"old_town", "opencv:leuvenA.jpg", 3.0, 0},
    {"starry", "opencv:starry_night.jpg", 2.4, 0},
    {"fruit_paper", "opencv:fruits.jpg", 1.6, 0},
    {"aerial", "opencv:aero1.jpg", 2.8, 0},
    {"cards", "opencv:cards.png", 2.4, 0},
    {"gym", "opencv:basketball1.png", 2.4, 0},
    {"coins", "skimage:coins.png", 1.6, 0},
    {"deep_sky", "skimage:hubble_deep_field.jpg", 2.6, 0},
    {"brick", "skimage:brick.png", 1.2, 90},
    {"palace", "opencv:home.jpg", 3.0, 0},
    {"baboons", "opencv:baboon.jpg", 2.5, 0},
    {"football", "opencv:messi5.jpg", 3.2, 0},
    {"motorbike", "skimage:motorcycle_left.png", 3.0, 0},
    {"squirrel", "opencv:squirrel_cls.jpg", 3.0, 0},
    {"rocket_wall", "skimage:rocket.jpg", 3.0, 0},
    {"astronauts", "skimage:astronaut.png", 2.5, 0},
};

// Photos repeated unmirrored as periodic wallpaper.
constexpr const char* kWallpapers[] = {
    "opencv:fruits.jpg",    "skimage:coins.png", "opencv:cards.png", "opencv:smarties.png",
    "opencv:butterfly.jpg", "opencv:blox.jpg",   "opencv:graf1.png", "opencv:chicky_512.png"};

// Framed pictures: reference and height / width.
struct PicturePhoto {
  const char* ref;
  double aspect;
};
constexpr PicturePhoto kPictures[] = {
    {"skimage:chelsea.png", 300.0 / 451},
    {"skimage:coffee.png", 400.0 / 600},
    {"skimage:astronaut.png", 1.0},
    {"skimage:rocket.jpg", 427.0 / 640},
    {"skimage:camera.png", 1.0},
    {"opencv:squirrel_cls.jpg", 426.0 / 535},
    {"skimage:motorcycle_left.png", 500.0 / 741},
    {"opencv:home.jpg", 384.0 / 512},
    {"opencv:orange.jpg", 1.0},
    {"opencv:messi5.jpg", 342.0 / 548},
    {"opencv:licenseplate_motion.jpg", 482.0 / 600},
    {"opencv:apple.jpg", 1.0},
    {"opencv:chicky_512.png", 1.0},
    {"opencv:Blender_Suzanne1.jpg", 480.0 / 640},
    {"opencv:LinuxLogo.jpg", 240.0 / 320},
    {"opencv:ela_original.jpg", 770.0 / 902},
    {"opencv:pic3.png", 300.0 / 400},
    {"opencv:text_defocus.jpg", 472.0 / 697},
    {"skimage:retina.jpg", 1.0},
    {"opencv:pca_test1.jpg", 600.0 / 800},
    {"opencv:detect_blob.png", 760.0 / 541},
    {"skimage:page.png", 191.0 / 384},
};

// ---- The home
enum class RoomType { kLiving, kKitchen, kBedroom, kBathroom, kStudy, kHallway };

struct PlanRoom {
  std::string name;
  RoomType type = RoomType::kLiving;
  Rect r;
  double height = 2.5;
  std::array<std::string, 4> walls;  // material per edge: south, east, north, west
  std::string floor, ceiling;
};

// Two rooms sharing a wall: the line x = `line` (vertical) or y = `line`,
// over [lo, hi] along it; `edge_a`/`edge_b`: that wall's edge in each room.
struct Adjacency {
  int a = 0, b = 0, edge_a = 0, edge_b = 0;
  bool vertical = false;
  double line = 0, lo = 0, hi = 0;
};

struct Opening {
  Adjacency wall;
  double at = 0;  // centre along the wall line
  double width = 0, height = 0;
  bool wide = false;  // an open-plan opening rather than a door
  Vec2 point() const { return wall.vertical ? Vec2(wall.line, at) : Vec2(at, wall.line); }
};

struct BoxSpec {
  std::string name;
  Vec2 centre;
  double width = 0, depth = 0, height = 0, facing_deg = 0, elevation = 0, legs = 0;
  std::string material;
  std::vector<std::pair<std::string, std::string>> faces;
};

struct PictureSpec {
  std::string image;
  Eigen::Vector3d centre;
  double width = 0, facing_deg = 0, gain = 1;
};

// What stands in a room: footprints, and space kept free in front of them.
struct Placed {
  Rect footprint, keep_free;
  double top = 0;
};

// A piece of furniture in its own frame: u along its wall (or its long
// axis), v out from the wall; parts are boxes.
struct Part {
  std::string name;
  double u = 0, v = 0;         // centre
  double w = 0, d = 0, h = 0;  // along u, along v, up
  double elevation = 0, legs = 0;
  std::string material;
  std::vector<std::pair<std::string, std::string>> faces;
};

struct Item {
  double width = 0, depth = 0;  // against a wall: u in [-width/2, width/2], v in [0, depth]
  std::vector<Part> parts;
  bool identical_units = false;  // the cupboards hard case
  double top() const {
    double t = 0;
    for (const Part& p : parts) t = std::max(t, p.elevation + p.h);
    return t;
  }
};

struct Home {
  std::vector<PlanRoom> rooms;
  std::vector<Opening> openings;
  std::vector<std::vector<Placed>> placed;  // per room
  std::vector<std::vector<Rect>> keep_out;  // per room: in front of doors
  std::vector<BoxSpec> boxes;
  std::vector<PictureSpec> pictures;
  std::vector<std::array<std::vector<std::pair<double, double>>, 4>> hung;  // [room][edge]
  Materials materials;
  bool corridor = false, open_plan = false;
  int dim_room = -1;
  std::set<std::string> hard_cases;
  std::set<std::string> wall_refs;  // photos on walls: not also hung as pictures
  Vec2 start = Vec2::Zero();
  int start_deg = 0;

  double area() const {
    double a = 0;
    for (const PlanRoom& r : rooms) a += r.r.area();
    return a;
  }
  int roomOfType(RoomType type) const {
    for (size_t i = 0; i < rooms.size(); ++i) {
      if (rooms[i].type == type) return static_cast<int>(i);
    }
    return -1;
  }
  std::string mat(const std::string& name, int room) {
    return materials.use(name, room == dim_room);
  }
  // Door intervals [s0, s1] along edge `edge` of room `room`.
  std::vector<std::pair<double, double>> openingsOn(int room, int edge) const {
    std::vector<std::pair<double, double>> out;
    const Wall w = wallOf(rooms[static_cast<size_t>(room)].r, edge);
    for (const Opening& o : openings) {
      if (!((o.wall.a == room && o.wall.edge_a == edge) ||
            (o.wall.b == room && o.wall.edge_b == edge))) {
        continue;
      }
      const double s = (o.point() - w.a).dot(w.t);
      out.emplace_back(s - 0.5 * o.width, s + 0.5 * o.width);
    }
    return out;
  }
};

// ---- Floor plan

// Splits `r` across its longer side, both parts at least kMinRoomSide.
bool splitRect(Rng& rng, const Rect& r, Rect* a, Rect* b) {
  const bool along_x = r.w() >= r.h();
  const double len = along_x ? r.w() : r.h();
  if (len < 2 * kMinRoomSide) return false;
  const double lo = std::max(kMinRoomSide, 0.38 * len);
  const double hi = std::min(len - kMinRoomSide, 0.62 * len);
  const double cut =
      std::clamp(roundTo(rng.uniform(lo, hi), kLayoutStep), kMinRoomSide, len - kMinRoomSide);
  *a = r;
  *b = r;
  if (along_x) {
    a->x1 = b->x0 = roundTo(r.x0 + cut, kLayoutStep);
  } else {
    a->y1 = b->y0 = roundTo(r.y0 + cut, kLayoutStep);
  }
  return true;
}

// Rectangles tiling a footprint; the corridor (if any) is rects[corridor].
bool makeLayout(Rng& rng, int n, bool corridor, std::vector<Rect>* rects, int* corridor_index) {
  rects->clear();
  *corridor_index = -1;
  if (corridor) {
    // Rooms in two rows along a corridor that runs the footprint's length.
    const int k = n - 1;
    const int k1 = k / 2 + (k % 2 == 1 ? static_cast<int>(rng.index(2)) : 0), k2 = k - k1;
    double room_area = 0;
    for (int i = 0; i < k; ++i) room_area += rng.uniform(9, 20);
    const double c = roundTo(rng.uniform(1.1, 1.5), kLayoutStep);
    const double d1 = roundTo(rng.uniform(2.6, 4.2), kLayoutStep);
    const double d2 = roundTo(std::max(2.4, d1 * rng.uniform(0.8, 1.2)), kLayoutStep);
    const double length = roundTo(
        std::max(room_area / (d1 + d2), std::max(k1, k2) * rng.uniform(2.5, 3.2)), kLayoutStep);
    auto row = [&](int count, double y0, double y1) {
      std::vector<double> weights;
      double sum = 0;
      for (int i = 0; i < count; ++i) sum += weights.emplace_back(rng.uniform(0.7, 1.3));
      double x = 0, acc = 0;
      for (int i = 0; i < count; ++i) {
        acc += weights[static_cast<size_t>(i)];
        const double x1 = i + 1 == count ? length : roundTo(length * acc / sum, kLayoutStep);
        rects->push_back({x, y0, x1, y1});
        x = x1;
      }
    };
    row(k1, 0, d1);
    *corridor_index = static_cast<int>(rects->size());
    rects->push_back({0, d1, length, roundTo(d1 + c, kLayoutStep)});
    row(k2, roundTo(d1 + c, kLayoutStep), roundTo(d1 + c + d2, kLayoutStep));
  } else {
    double area = 0;
    if (n == 1) {
      area = rng.uniform(20, 36);
    } else {
      for (int i = 0; i < n; ++i) area += rng.uniform(9, 22);
    }
    const double aspect = rng.uniform(1.0, 1.6);
    const double w = roundTo(std::sqrt(area * aspect), kLayoutStep);
    const double h = roundTo(std::max(kMinRoomSide, area / w), kLayoutStep);
    rects->push_back({0, 0, w, h});
    while (static_cast<int>(rects->size()) < n) {
      // Split the largest rectangle that can be split.
      int best = -1;
      for (size_t i = 0; i < rects->size(); ++i) {
        const Rect& r = (*rects)[i];
        if (std::max(r.w(), r.h()) < 2 * kMinRoomSide) continue;
        if (best < 0 || r.area() > (*rects)[static_cast<size_t>(best)].area()) {
          best = static_cast<int>(i);
        }
      }
      if (best < 0) return false;
      Rect a, b;
      splitRect(rng, (*rects)[static_cast<size_t>(best)], &a, &b);
      (*rects)[static_cast<size_t>(best)] = a;
      rects->push_back(b);
    }
  }
  double total = 0;
  for (size_t i = 0; i < rects->size(); ++i) {
    const Rect& r = (*rects)[i];
    if (static_cast<int>(i) != *corridor_index && std::min(r.w(), r.h()) < kMinRoomSide - 1e-9) {
      return false;
    }
    total += r.area();
  }
  if (total < kMinArea || total > kMaxArea) return false;
  if (rng.chance(0.5)) {  // either orientation
    for (Rect& r : *rects) r = {r.y0, r.x0, r.y1, r.x1};
  }
  return true;
}

std::vector<Adjacency> adjacencies(const std::vector<PlanRoom>& rooms) {
  std::vector<Adjacency> out;
  constexpr double kMinShared = 1.4;  // a 0.9 m door with 25 cm to each corner
  for (size_t i = 0; i < rooms.size(); ++i) {
    for (size_t j = i + 1; j < rooms.size(); ++j) {
      const Rect &a = rooms[i].r, &b = rooms[j].r;
      Adjacency adj;
      adj.a = static_cast<int>(i);
      adj.b = static_cast<int>(j);
      bool touching = true;
      if (std::abs(a.x1 - b.x0) < 1e-6 || std::abs(a.x0 - b.x1) < 1e-6) {
        const bool east = std::abs(a.x1 - b.x0) < 1e-6;
        adj.vertical = true;
        adj.line = east ? a.x1 : a.x0;
        adj.edge_a = east ? 1 : 3;
        adj.edge_b = east ? 3 : 1;
        adj.lo = std::max(a.y0, b.y0);
        adj.hi = std::min(a.y1, b.y1);
      } else if (std::abs(a.y1 - b.y0) < 1e-6 || std::abs(a.y0 - b.y1) < 1e-6) {
        const bool north = std::abs(a.y1 - b.y0) < 1e-6;
        adj.line = north ? a.y1 : a.y0;
        adj.edge_a = north ? 2 : 0;
        adj.edge_b = north ? 0 : 2;
        adj.lo = std::max(a.x0, b.x0);
        adj.hi = std::min(a.x1, b.x1);
      } else {
        touching = false;
      }
      if (touching && adj.hi - adj.lo >= kMinShared - 1e-9) out.push_back(adj);
    }
  }
  return out;
}

bool isPrivate(RoomType t) { return t == RoomType::kBedroom || t == RoomType::kBathroom; }

// Doors forming a random spanning tree over the shared walls (the corridor
// serves the rooms along it), sometimes one more door closing a cycle, and
// sometimes a wide open-plan opening between two living areas.
bool connectRooms(Rng& rng, Home& home) {
  const std::vector<Adjacency> adj = adjacencies(home.rooms);
  const size_t n = home.rooms.size();
  std::vector<bool> connected(n, false);
  int root = home.roomOfType(RoomType::kHallway);
  if (root < 0) root = home.roomOfType(RoomType::kLiving);
  connected[static_cast<size_t>(root)] = true;
  std::vector<bool> used(adj.size(), false);
  auto addOpening = [&](size_t k, bool allow_wide) {
    used[k] = true;
    const Adjacency& a = adj[k];
    Opening o;
    o.wall = a;
    const double shared = a.hi - a.lo;
    const PlanRoom &ra = home.rooms[static_cast<size_t>(a.a)],
                   &rb = home.rooms[static_cast<size_t>(a.b)];
    if (allow_wide && shared >= 2.6 && !isPrivate(ra.type) && !isPrivate(rb.type) &&
        rng.chance(0.6)) {
      o.wide = true;
      o.width = roundTo(rng.uniform(2.0, std::min(3.0, shared - 0.5)), kLayoutStep);
      o.height = roundTo(std::min(ra.height, rb.height) - rng.uniform(0.2, 0.35), 0.01);
      home.open_plan = true;
    } else {
      o.width = roundTo(rng.uniform(0.8, std::min(1.0, shared - 0.5)), kLayoutStep);
      o.height = roundTo(rng.uniform(2.0, 2.1), 0.01);
    }
    const double lo = a.lo + 0.5 * o.width + 0.25, hi = a.hi - 0.5 * o.width - 0.25;
    o.at = std::clamp(roundTo(rng.uniform(lo, hi), 0.01), lo, hi);
    home.openings.push_back(o);
  };
  for (size_t added = 1; added < n; ++added) {
    std::vector<size_t> frontier, via_hall;
    for (size_t k = 0; k < adj.size(); ++k) {
      const bool ca = connected[static_cast<size_t>(adj[k].a)];
      const bool cb = connected[static_cast<size_t>(adj[k].b)];
      if (ca == cb) continue;
      frontier.push_back(k);
      const int hall = home.roomOfType(RoomType::kHallway);
      if (adj[k].a == hall || adj[k].b == hall) via_hall.push_back(k);
    }
    if (frontier.empty()) return false;
    const size_t k =
        !via_hall.empty() && rng.chance(0.85) ? rng.pick(via_hall) : rng.pick(frontier);
    connected[static_cast<size_t>(adj[k].a)] = connected[static_cast<size_t>(adj[k].b)] = true;
    addOpening(k, /*allow_wide=*/!home.open_plan);
  }
  std::vector<size_t> spare;
  for (size_t k = 0; k < adj.size(); ++k) {
    if (!used[k]) spare.push_back(k);
  }
  if (!spare.empty() && rng.chance(0.35)) addOpening(rng.pick(spare), !home.open_plan);
  // Keep-out zones: in front of each opening, in both rooms.
  home.keep_out.assign(n, {});
  for (const Opening& o : home.openings) {
    const Vec2 p = o.point();
    const double half = 0.5 * o.width + 0.3;
    const Vec2 along = o.wall.vertical ? Vec2(0, 1) : Vec2(1, 0);
    const Vec2 across = o.wall.vertical ? Vec2(1, 0) : Vec2(0, 1);
    const Rect zone = Rect::around(p - half * along - kDoorKeepOut * across,
                                   p + half * along + kDoorKeepOut * across);
    home.keep_out[static_cast<size_t>(o.wall.a)].push_back(zone);
    home.keep_out[static_cast<size_t>(o.wall.b)].push_back(zone);
  }
  return true;
}

// Types of the rooms between the living room (the largest) and the
// bathroom (the smallest, if the home has one), for `count` rooms besides a
// hallway.
std::vector<RoomType> middleRooms(Rng& rng, size_t count, bool* bathroom) {
  using T = RoomType;
  *bathroom = count >= 3;
  switch (count) {
    case 1:
      return {};
    case 2:
      return {T::kBedroom};
    case 3:
      if (rng.chance(0.5)) {
        *bathroom = false;
        return {T::kKitchen, T::kBedroom};
      }
      return {T::kBedroom};
    case 4:
      return {T::kKitchen, T::kBedroom};
    case 5:
      return {T::kKitchen, T::kBedroom, T::kBedroom};
    default:
      return {T::kKitchen, T::kBedroom, T::kBedroom, T::kStudy};
  }
}

// Room types by size: the largest is the living room, the smallest the
// bathroom, the corridor the hallway.
void nameRooms(Rng& rng, const std::vector<Rect>& rects, int corridor, Home& home) {
  std::vector<int> order;
  for (size_t i = 0; i < rects.size(); ++i) {
    if (static_cast<int>(i) != corridor) order.push_back(static_cast<int>(i));
  }
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return rects[static_cast<size_t>(a)].area() > rects[static_cast<size_t>(b)].area();
  });
  bool bathroom = false;
  std::vector<RoomType> middle = middleRooms(rng, order.size(), &bathroom);
  rng.shuffle(middle);
  home.rooms.assign(rects.size(), PlanRoom());
  int bedrooms = 0;
  for (size_t rank = 0; rank < order.size(); ++rank) {
    PlanRoom& room = home.rooms[static_cast<size_t>(order[rank])];
    if (rank == 0) {
      room.type = RoomType::kLiving;
    } else if (bathroom && rank + 1 == order.size()) {
      room.type = RoomType::kBathroom;
    } else {
      room.type = middle[rank - 1];
    }
  }
  const int total_bedrooms =
      static_cast<int>(std::count(middle.begin(), middle.end(), RoomType::kBedroom));
  for (size_t i = 0; i < rects.size(); ++i) {
    PlanRoom& room = home.rooms[i];
    room.r = rects[i];
    if (static_cast<int>(i) == corridor) room.type = RoomType::kHallway;
    const bool low = room.type == RoomType::kHallway || room.type == RoomType::kBathroom;
    room.height = roundTo(low ? rng.uniform(2.4, 2.5) : rng.uniform(2.4, 2.7), kLayoutStep);
    switch (room.type) {
      case RoomType::kLiving:
        room.name = "living";
        break;
      case RoomType::kKitchen:
        room.name = "kitchen";
        break;
      case RoomType::kBedroom:
        room.name = total_bedrooms > 1 ? "bedroom_" + std::to_string(++bedrooms) : "bedroom";
        break;
      case RoomType::kBathroom:
        room.name = "bathroom";
        break;
      case RoomType::kStudy:
        room.name = "study";
        break;
      case RoomType::kHallway:
        room.name = "hallway";
        break;
    }
  }
}

// ---- Materials of the home, the hard cases among them
void defineMaterials(Rng& rng, Home& home) {
  Materials& m = home.materials;
  auto crop = [](Material x, std::vector<int> rect) {
    x.crop = std::move(rect);
    return x;
  };
  m.define("parquet", photo("skimage:brick.png", 1.6, 0.8));
  m.define("carpet", photo("skimage:grass.png", 1.0, 0.9));
  m.define("stone_floor", photo("skimage:gravel.png", 1.2));
  m.define("boards", crop(photo("opencv:stuff.jpg", 0.6, 0.8), {470, 0, 170, 300}));
  m.define("plaster", photo("skimage:moon.png", 2.5, 1.1));
  m.define("white", albedo(0.85));
  m.define("wood", crop(photo("opencv:stuff.jpg", 0.5, 0.8), {470, 0, 170, 300}));
  m.define("table_top", photo("opencv:stuff.jpg", 1.2));
  m.define("fabric", crop(photo("opencv:aloeL.jpg", 0.7), {0, 0, 500, 420}));
  m.define("felt", photo("skimage:grass.png", 0.7, 0.8));
  m.define("cushions", photo("opencv:baboon.jpg", 0.5));
  m.define("duvet", crop(photo("opencv:aloeL.jpg", 1.0, 1.05), {0, 0, 500, 420}));
  m.define("duvet_2", photo("opencv:butterfly.jpg", 1.4));
  m.define("quilt", photo("opencv:HappyFish.jpg", 1.0));
  m.define("books", photo("opencv:left.jpg", 1.3));
  m.define("boxes_shelf", photo("opencv:box_in_scene.png", 1.2));
  m.define("toys_shelf", photo("opencv:rubberwhale1.png", 1.4));
  m.define("circuit", photo("opencv:board.jpg", 0.9));
  m.define("wardrobe", photo("opencv:home.jpg", 1.8));
  m.define("papers", photo("skimage:text.png", 0.9));
  m.define("cabinets", photo("skimage:ihc.png", 0.9));
  m.define("fridge_door", photo("opencv:smarties.png", 0.7));
  m.define("ceramic", albedo(0.85));
  m.define("dark", albedo(0.1));
  m.define("tv_screen", photo("opencv:messi5.jpg", 1.2));
  m.define("plain_wall", albedo(roundTo(rng.uniform(0.7, 0.85), 0.01)));
  m.define("plain_floor", albedo(roundTo(rng.uniform(0.45, 0.6), 0.01)));
  // The cupboards hard case: one front for every unit of a row.
  const std::vector<std::string> fronts = {"cabinets", "wardrobe", "boxes_shelf", "circuit"};
  Material front = m.get(rng.pick(fronts));
  front.scale_m = roundTo(rng.uniform(0.5, 0.9), 0.01);
  m.define("cupboard", front);
  // Periodic wallpaper: the same photo, unmirrored, every 0.6-2 m.
  const char* paper_ref = kWallpapers[rng.index(std::size(kWallpapers))];
  Material paper = photo(paper_ref, roundTo(rng.uniform(0.6, 2.0), 0.01));
  paper.mirror = false;
  m.define("wallpaper", paper);
  // Tiles: the procedural tiles, or a photo laid small.
  Material tiles;
  if (rng.chance(0.5)) {
    tiles = photo("procedural:tiles", roundTo(rng.uniform(0.6, 1.0), 0.01));
  } else {
    const char* ref = rng.chance(0.5) ? "skimage:brick.png" : "skimage:gravel.png";
    tiles = photo(ref, roundTo(rng.uniform(0.3, 0.5), 0.01));
  }
  m.define("tiles", tiles);
  for (const WallPhoto& p : kWallPhotos) {
    Material w = photo(p.ref, roundTo(p.scale_m * rng.uniform(0.85, 1.15), 0.01));
    w.rotate_deg = p.rotate_deg;
    w.mirror = true;
    m.define(p.name, w);
  }
}

// Where this home's hard cases on walls and floors are: one plain room or a
// few plain walls, papered rooms or walls, a tiled room (and its walls).
struct HardSurfaces {
  std::vector<int> all;  // every room's index
  int plain_room = -1;
  std::set<std::pair<int, int>> plain_walls;  // (room, edge)
  std::set<int> papered;
  std::set<std::pair<int, int>> papered_walls;
  int tiled = -1;
  bool tiled_walls = false;
};

// The rooms other than the plain one.
std::vector<int> roomsNotPlain(const HardSurfaces& hard) {
  std::vector<int> candidates;
  for (int i : hard.all) {
    if (i != hard.plain_room) candidates.push_back(i);
  }
  return candidates;
}

void choosePlainWalls(Rng& rng, Home& home, HardSurfaces& hard) {
  if (!rng.chance(0.45)) return;
  const size_t n = hard.all.size();
  if (n >= 2 && rng.chance(0.5)) {
    std::vector<int> candidates;
    for (int i : hard.all) {
      if (home.rooms[static_cast<size_t>(i)].type != RoomType::kLiving) candidates.push_back(i);
    }
    hard.plain_room = rng.pick(candidates);
  } else {
    const int rooms = 1 + static_cast<int>(rng.index(std::min<size_t>(2, n)));
    for (int k = 0; k < rooms; ++k) {
      const int room = rng.pick(hard.all);
      const int walls = 1 + static_cast<int>(rng.index(2));
      for (int w = 0; w < walls; ++w)
        hard.plain_walls.insert({room, static_cast<int>(rng.index(4))});
    }
  }
  home.hard_cases.insert("plain-walls");
}

void chooseWallpaper(Rng& rng, Home& home, HardSurfaces& hard) {
  if (!rng.chance(0.5)) return;
  std::vector<int> candidates = roomsNotPlain(hard);
  rng.shuffle(candidates);
  if (candidates.size() >= 2) {
    const size_t count = std::min(candidates.size(), 2 + rng.index(2));
    hard.papered.insert(candidates.begin(), candidates.begin() + static_cast<long>(count));
  } else if (!candidates.empty()) {
    const int walls = 2 + static_cast<int>(rng.index(3));
    for (int w = 0; w < walls; ++w) hard.papered_walls.insert({candidates[0], w});
  }
  if (!hard.papered.empty() || !hard.papered_walls.empty()) {
    home.hard_cases.insert("wallpaper");
    home.wall_refs.insert(home.materials.get("wallpaper").texture);
  }
}

void chooseTiles(Rng& rng, Home& home, HardSurfaces& hard) {
  if (!rng.chance(0.5)) return;
  for (RoomType t :
       {RoomType::kBathroom, RoomType::kKitchen, RoomType::kHallway, RoomType::kLiving}) {
    if (hard.tiled < 0 && home.roomOfType(t) >= 0 && home.roomOfType(t) != hard.plain_room) {
      hard.tiled = home.roomOfType(t);
    }
  }
  hard.tiled_walls = hard.tiled >= 0 &&
                     home.rooms[static_cast<size_t>(hard.tiled)].type == RoomType::kBathroom &&
                     rng.chance(0.5);
  if (hard.tiled >= 0) home.hard_cases.insert("tiles");
}

void chooseDimRoom(Rng& rng, Home& home, const HardSurfaces& hard) {
  if (!rng.chance(0.4)) return;
  home.dim_room = rng.pick(roomsNotPlain(hard));
  home.materials.setDimGain(roundTo(rng.uniform(0.25, 0.45), 0.01));
  home.hard_cases.insert("dim-room");
}

// Photos for the walls, dealt from a shuffled deck so that few repeat.
class WallPhotoDeck {
 public:
  const WallPhoto* draw(Rng& rng) {
    if (next_ == deck_.size()) {
      deck_.clear();
      for (const WallPhoto& p : kWallPhotos) deck_.push_back(&p);
      rng.shuffle(deck_);
      next_ = 0;
    }
    return deck_[next_++];
  }

 private:
  std::vector<const WallPhoto*> deck_;
  size_t next_ = 0;
};

// The materials of room i's four walls.
std::array<std::string, 4> roomWalls(Rng& rng, Home& home, const HardSurfaces& hard, int i,
                                     WallPhotoDeck& photos) {
  std::array<std::string, 4> walls;
  if (i == hard.plain_room) {
    walls.fill("plain_wall");
  } else if (hard.papered.count(i)) {
    walls.fill("wallpaper");
  } else if (i == hard.tiled && hard.tiled_walls) {
    walls.fill("tiles");
  } else {
    const int count = 1 + static_cast<int>(rng.index(4));
    std::vector<std::string> names;
    for (int k = 0; k < count; ++k) {
      const WallPhoto* p = photos.draw(rng);
      names.push_back(p->name);
      home.wall_refs.insert(p->ref);
    }
    for (size_t e = 0; e < 4; ++e) walls[e] = names[e % names.size()];
  }
  for (int e = 0; e < 4; ++e) {
    if (hard.plain_walls.count({i, e})) walls[static_cast<size_t>(e)] = "plain_wall";
    if (hard.papered_walls.count({i, e})) walls[static_cast<size_t>(e)] = "wallpaper";
  }
  return walls;
}

// The material of room i's floor.
std::string roomFloor(Rng& rng, const HardSurfaces& hard, int i, RoomType type) {
  if (i == hard.plain_room) return "plain_floor";
  if (i == hard.tiled) return "tiles";
  if (type == RoomType::kKitchen || type == RoomType::kBathroom) {
    return rng.chance(0.7) ? "stone_floor" : "parquet";
  }
  if (type == RoomType::kHallway) return rng.chance(0.5) ? "parquet" : "stone_floor";
  const std::vector<std::string> floors = {"parquet", "carpet", "boards"};
  return rng.pick(floors);
}

void dressRooms(Rng& rng, Home& home) {
  HardSurfaces hard;
  hard.all.resize(home.rooms.size());
  for (size_t i = 0; i < hard.all.size(); ++i) hard.all[i] = static_cast<int>(i);
  choosePlainWalls(rng, home, hard);
  chooseWallpaper(rng, home, hard);
  chooseTiles(rng, home, hard);
  chooseDimRoom(rng, home, hard);

  WallPhotoDeck photos;
  const std::string ceiling = rng.chance(0.6) ? "plaster" : "white";
  for (int i : hard.all) {
    PlanRoom& room = home.rooms[static_cast<size_t>(i)];
    const std::array<std::string, 4> walls = roomWalls(rng, home, hard, i, photos);
    const std::string floor = roomFloor(rng, hard, i, room.type);
    for (size_t e = 0; e < 4; ++e) room.walls[e] = home.mat(walls[e], i);
    room.floor = home.mat(floor, i);
    room.ceiling = home.mat(i == hard.plain_room ? "white" : ceiling, i);
  }
}

// ---- Furniture
Part part(const std::string& name, double u, double v, double w, double d, double h,
          const std::string& material) {
  Part p;
  p.name = name;
  p.u = u;
  p.v = v;
  p.w = w;
  p.d = d;
  p.h = h;
  p.material = material;
  return p;
}

class Furnisher {
 public:
  Furnisher(Rng& rng, Home& home) : rng_(rng), home_(home) {
    home_.placed.assign(home_.rooms.size(), {});
    home_.hung.assign(home_.rooms.size(), {});
  }

  void furnish(int room, bool cupboards) {
    room_ = room;
    const PlanRoom& r = home_.rooms[static_cast<size_t>(room)];
    const double short_side = std::min(r.r.w(), r.r.h());
    const bool studio = home_.rooms.size() == 1 ||
                        (home_.roomOfType(RoomType::kKitchen) < 0 && r.type == RoomType::kLiving);
    switch (r.type) {
      case RoomType::kLiving:
        againstWall(sofa());
        if (studio) againstWall(counter(cupboards));
        againstWall(tvUnit());
        if (home_.roomOfType(RoomType::kBedroom) < 0) againstWall(bed());
        againstWall(shelf("bookshelf", m("books")));
        if (studio) againstWall(fridge());
        againstWall(sideboard());
        freeStanding(table("coffee table", 1.0, 0.55, 0.45, m("table_top")));
        if (r.r.area() > 18) freeStanding(table("dining table", 1.2, 0.8, 0.75, m("table_top")));
        break;
      case RoomType::kKitchen:
        againstWall(counter(cupboards));
        againstWall(fridge());
        if (!freeStanding(table("kitchen table", 1.0, 0.7, 0.75, m("papers")))) {
          againstWall(desk("kitchen table"));
        }
        againstWall(sideboard());
        break;
      case RoomType::kBedroom:
        againstWall(bed());
        againstWall(wardrobe(cupboards));
        againstWall(small("nightstand", 0.45, 0.4, 0.55, m("circuit")));
        againstWall(desk("desk"));
        againstWall(shelf("shelf", m("toys_shelf")));
        break;
      case RoomType::kBathroom:
        againstWall(bathtub());
        againstWall(sink());
        againstWall(small("toilet", 0.4, 0.6, 0.45, m("ceramic"), /*all=*/true));
        againstWall(small("laundry basket", 0.45, 0.45, 0.6, m("felt"), /*all=*/true));
        break;
      case RoomType::kStudy:
        againstWall(desk("desk"));
        againstWall(shelf("bookshelf", m("books")));
        againstWall(small("cabinet", 0.8, 0.45, 1.0, m("cabinets")));
        againstWall(shelf("shelf", m("boxes_shelf")));
        break;
      case RoomType::kHallway:
        if (short_side >= 1.3) {
          againstWall(small("console", 0.8, 0.3, 0.8, m("boxes_shelf")));
          againstWall(small("shoe cabinet", 0.8, 0.3, 1.0, m("toys_shelf")));
        }
        break;
    }
  }

  void hangPictures(int room, std::vector<PicturePhoto>& pool) {
    room_ = room;
    const PlanRoom& r = home_.rooms[static_cast<size_t>(room)];
    int count = 1 + static_cast<int>(rng_.index(3));
    if (r.type == RoomType::kBathroom) count = static_cast<int>(rng_.index(2));
    for (int k = 0; k < count && !pool.empty(); ++k) {
      const PicturePhoto image = pool.back();
      double width = roundTo(rng_.uniform(0.5, 1.0), kLayoutStep);
      while (width * image.aspect > 0.9) width -= kLayoutStep;
      const double height = width * image.aspect;
      const double zc = roundTo(rng_.uniform(1.2, 1.5), kLayoutStep);
      for (int attempt = 0; attempt < 30; ++attempt) {
        const int edge = static_cast<int>(rng_.index(4));
        const Wall w = wallOf(r.r, edge);
        if (w.length < width + 0.4) continue;
        const double s =
            roundTo(rng_.uniform(0.5 * width + 0.2, w.length - 0.5 * width - 0.2), kLayoutStep);
        const double s0 = s - 0.5 * width, s1 = s + 0.5 * width;
        bool ok = s0 >= 0.15 && s1 <= w.length - 0.15;
        for (const auto& [d0, d1] : home_.openingsOn(room, edge)) {
          ok = ok && (s1 < d0 - 0.15 || s0 > d1 + 0.15);
        }
        for (const auto& [p0, p1] :
             home_.hung[static_cast<size_t>(room)][static_cast<size_t>(edge)]) {
          ok = ok && (s1 < p0 - 0.3 || s0 > p1 + 0.3);
        }
        const Rect strip = Rect::around(w.at(s0, 0), w.at(s1, 0.1));
        for (const Placed& p : home_.placed[static_cast<size_t>(room)]) {
          ok = ok && !(p.footprint.intersects(strip) && p.top > zc - 0.5 * height - 0.05);
        }
        if (!ok) continue;
        PictureSpec pic;
        pic.image = image.ref;
        const Vec2 c = w.at(s, 0);
        pic.centre = Eigen::Vector3d(c.x(), c.y(), zc);
        pic.width = width;
        pic.facing_deg = w.facingDeg();
        pic.gain = room == home_.dim_room ? home_.materials.dimGain() : 1.0;
        home_.pictures.push_back(pic);
        home_.hung[static_cast<size_t>(room)][static_cast<size_t>(edge)].emplace_back(s0, s1);
        pool.pop_back();
        break;
      }
    }
  }

 private:
  std::string m(const std::string& name) { return home_.mat(name, room_); }

  Item sofa() {
    const double w = roundTo(rng_.uniform(1.6, 2.2), kLayoutStep);
    const std::string cloth = m(rng_.chance(0.6) ? "fabric" : "felt");
    Item it;
    it.width = w;
    it.depth = 0.9;
    it.parts = {part("sofa seat", 0, 0.45, w, 0.9, 0.42, cloth),
                part("sofa back", 0, 0.1, w, 0.2, 0.85, cloth),
                part("sofa arm", -0.5 * w + 0.09, 0.45, 0.18, 0.9, 0.62, cloth),
                part("sofa arm", 0.5 * w - 0.09, 0.45, 0.18, 0.9, 0.62, cloth)};
    if (rng_.chance(0.6)) {
      Part cushion = part("cushion", roundTo(rng_.uniform(-0.3, 0.3) * w, 0.01), 0.3, 0.45, 0.15,
                          0.4, m("cushions"));
      cushion.elevation = 0.42;
      it.parts.push_back(cushion);
    }
    return it;
  }
  Item tvUnit() {
    const double w = roundTo(rng_.uniform(1.3, 1.8), kLayoutStep);
    Item it;
    it.width = w;
    it.depth = 0.45;
    Part cabinet = part("tv cabinet", 0, 0.225, w, 0.45, 0.5, m("wood"));
    cabinet.faces = {{"front", m("boxes_shelf")}};
    Part tv = part("tv", 0, 0.1, roundTo(0.75 * w, 0.01), 0.08, 0.65, m("dark"));
    tv.elevation = 0.5;
    tv.faces = {{"front", m("tv_screen")}};
    it.parts = {cabinet, tv};
    return it;
  }
  Item shelf(const std::string& name, const std::string& front) {
    const double w = roundTo(rng_.uniform(1.0, 1.6), kLayoutStep);
    const double h = roundTo(rng_.uniform(1.7, 2.0), kLayoutStep);
    Item it;
    it.width = w;
    it.depth = 0.35;
    Part p = part(name, 0, 0.175, w, 0.35, h, m("wood"));
    p.faces = {{"front", front}};
    it.parts = {p};
    return it;
  }
  Item sideboard() {
    const double w = roundTo(rng_.uniform(0.9, 1.4), kLayoutStep);
    Item it;
    it.width = w;
    it.depth = 0.42;
    Part p = part("sideboard", 0, 0.21, w, 0.42, 0.9, m("wood"));
    p.faces = {{"front", m(rng_.chance(0.5) ? "circuit" : "boxes_shelf")}};
    it.parts = {p};
    return it;
  }
  Item small(const std::string& name, double w, double d, double h, const std::string& front,
             bool all = false) {
    Item it;
    it.width = w;
    it.depth = d;
    Part p = part(name, 0, 0.5 * d, w, d, h, all ? front : m("wood"));
    if (!all) p.faces = {{"front", front}};
    it.parts = {p};
    return it;
  }
  // A kitchen counter with wall cabinets above: as separate identical units
  // (the cupboards hard case) or as one long box each.
  Item counter(bool identical) {
    const int units = 3 + static_cast<int>(rng_.index(3));
    const double unit = 0.6;
    Item it;
    it.width = units * unit;
    it.depth = 0.6;
    if (identical) {
      it.identical_units = true;
      for (int i = 0; i < units; ++i) {
        const double u = (i - 0.5 * (units - 1)) * unit;
        Part base = part("cupboard", u, 0.3, unit - 0.01, 0.6, 0.9, m("wood"));
        base.faces = {{"front", m("cupboard")}, {"top", m("table_top")}};
        Part high = part("wall cupboard", u, 0.175, unit - 0.01, 0.35, 0.7, m("wood"));
        high.elevation = 1.5;
        high.faces = {{"front", m("cupboard")}};
        it.parts.push_back(base);
        it.parts.push_back(high);
      }
    } else {
      Part base = part("counter", 0, 0.3, it.width, 0.6, 0.9, m("cabinets"));
      base.faces = {{"top", m("table_top")}};
      Part high = part("wall cabinets", 0, 0.175, it.width, 0.35, 0.7, m("cabinets"));
      high.elevation = 1.5;
      it.parts = {base, high};
    }
    return it;
  }
  Item fridge() { return small("fridge", 0.7, 0.7, 1.8, m("fridge_door")); }
  Item bed() {
    const double w = roundTo(rng_.uniform(1.2, 1.8), kLayoutStep);
    const std::vector<std::string> covers = {"duvet", "duvet_2", "quilt"};
    Item it;
    it.width = w + 0.1;
    it.depth = 2.08;
    it.parts = {part("bed", 0, 1.08, w, 2.0, 0.5, m(rng_.pick(covers))),
                part("headboard", 0, 0.04, w + 0.1, 0.08, 1.0, m("wood"))};
    return it;
  }
  Item wardrobe(bool identical) {
    Item it;
    it.depth = 0.6;
    if (identical) {
      // Identical doors side by side.
      const int units = 2 + static_cast<int>(rng_.index(2));
      it.width = units * 0.7;
      it.identical_units = true;
      for (int i = 0; i < units; ++i) {
        Part door =
            part("wardrobe door", (i - 0.5 * (units - 1)) * 0.7, 0.3, 0.69, 0.6, 2.1, m("wood"));
        door.faces = {{"front", m("cupboard")}};
        it.parts.push_back(door);
      }
    } else {
      it.width = roundTo(rng_.uniform(1.2, 2.0), kLayoutStep);
      Part p = part("wardrobe", 0, 0.3, it.width, 0.6, 2.1, m("wood"));
      p.faces = {{"front", m("wardrobe")}};
      it.parts = {p};
    }
    return it;
  }
  Item desk(const std::string& name) {
    const double w = roundTo(rng_.uniform(1.0, 1.3), kLayoutStep);
    Item it;
    it.width = w;
    it.depth = 0.6;
    Part p = part(name, 0, 0.3, w, 0.6, 0.75, m("wood"));
    p.legs = 0.05;
    p.faces = {{"top", m(rng_.chance(0.5) ? "papers" : "circuit")}};
    it.parts = {p};
    return it;
  }
  Item bathtub() { return small("bathtub", 1.8, 0.75, 0.55, m("ceramic"), /*all=*/true); }
  Item sink() {
    Item it = small("sink cabinet", 0.8, 0.45, 0.85, m("wood"), /*all=*/true);
    it.parts[0].faces = {{"top", m("ceramic")}};
    return it;
  }
  // Centred on the origin, long axis along u.
  Item table(const std::string& name, double w, double d, double h, const std::string& top) {
    Item it;
    it.width = w;
    it.depth = d;
    Part p = part(name, 0, 0, w, d, h, m("wood"));
    p.legs = 0.05;
    p.faces = {{"top", top}};
    it.parts = {p};
    return it;
  }

  bool clearOf(const Rect& footprint, const Rect& keep_free, const Rect& room) const {
    if (!footprint.within(room) || !keep_free.within(room)) return false;
    for (const Rect& k : home_.keep_out[static_cast<size_t>(room_)]) {
      if (footprint.intersects(k)) return false;
    }
    for (const Placed& p : home_.placed[static_cast<size_t>(room_)]) {
      if (footprint.intersects(p.footprint) || footprint.intersects(p.keep_free) ||
          keep_free.intersects(p.footprint)) {
        return false;
      }
    }
    return true;
  }

  void emit(const Item& item, const Vec2& origin, const Vec2& t, const Vec2& n, double wall_gap) {
    const double facing = std::round(radToDeg(std::atan2(n.y(), n.x())));
    for (const Part& p : item.parts) {
      BoxSpec b;
      b.name = p.name;
      b.centre = origin + p.u * t + (wall_gap + p.v) * n;
      b.width = p.w;
      b.depth = p.d;
      b.height = p.h;
      b.facing_deg = facing;
      b.elevation = p.elevation;
      b.legs = p.legs;
      b.material = p.material;
      b.faces = p.faces;
      home_.boxes.push_back(b);
    }
    if (item.identical_units) home_.hard_cases.insert("cupboards");
  }

  bool againstWall(const Item& item) {
    const Rect room = home_.rooms[static_cast<size_t>(room_)].r;
    for (int attempt = 0; attempt < 40; ++attempt) {
      const int edge = static_cast<int>(rng_.index(4));
      const Wall w = wallOf(room, edge);
      if (w.length < item.width + 0.1) continue;
      const double s = roundTo(
          rng_.uniform(0.5 * item.width + 0.05, w.length - 0.5 * item.width - 0.05), kLayoutStep);
      const double s0 = s - 0.5 * item.width, s1 = s + 0.5 * item.width;
      const Rect footprint = Rect::around(w.at(s0, kWallGap), w.at(s1, kWallGap + item.depth));
      const Rect keep_free =
          Rect::around(w.at(s0, kWallGap + item.depth), w.at(s1, kWallGap + item.depth + kPassage));
      if (!clearOf(footprint, keep_free, room)) continue;
      emit(item, w.at(s, 0), w.t, w.n, kWallGap);
      home_.placed[static_cast<size_t>(room_)].push_back({footprint, keep_free, item.top()});
      return true;
    }
    return false;
  }

  // A table standing free with a passage all round it.
  bool freeStanding(const Item& item) {
    const Rect room = home_.rooms[static_cast<size_t>(room_)].r;
    for (int attempt = 0; attempt < 30; ++attempt) {
      const bool along_x = rng_.chance(0.5);
      const Vec2 t = along_x ? Vec2(1, 0) : Vec2(0, 1);
      const Vec2 n(-t.y(), t.x());
      const double hx = 0.5 * (along_x ? item.width : item.depth);
      const double hy = 0.5 * (along_x ? item.depth : item.width);
      const double mx = hx + kPassage, my = hy + kPassage;
      if (room.w() < 2 * mx || room.h() < 2 * my) return false;
      const double cx = roundTo(rng_.uniform(room.x0 + mx, room.x1 - mx), kLayoutStep);
      const double cy = roundTo(rng_.uniform(room.y0 + my, room.y1 - my), kLayoutStep);
      const Vec2 c(cx, cy);
      const Rect footprint = Rect::around(c - Vec2(hx, hy), c + Vec2(hx, hy));
      if (!clearOf(footprint, footprint.grown(kPassage), room)) continue;
      emit(item, c, t, n, 0.0);
      home_.placed[static_cast<size_t>(room_)].push_back(
          {footprint, footprint.grown(kPassage), item.top()});
      return true;
    }
    return false;
  }

  Rng& rng_;
  Home& home_;
  int room_ = 0;
};

// ---- World file text
std::string boxYaml(const BoxSpec& b) {
  std::string s = "  - {name: " + b.name + ", centre: [" + num(b.centre.x()) + ", " +
                  num(b.centre.y()) + "], size: [" + num(b.width) + ", " + num(b.depth) + ", " +
                  num(b.height) + "], facing_deg: " + num(b.facing_deg, 0);
  if (b.elevation > 0) s += ", elevation: " + num(b.elevation);
  if (b.legs > 0) s += ", legs: " + num(b.legs);
  s += ", material: " + b.material;
  if (!b.faces.empty()) {
    std::vector<std::string> faces;
    for (const auto& [face, material] : b.faces) faces.push_back(face + ": " + material);
    s += ", faces: {" + joined(faces, ", ") + "}";
  }
  return s + "}\n";
}

std::string point(const Vec2& p) { return "[" + num(p.x()) + ", " + num(p.y()) + "]"; }

// `plain`: the floor plan only (uniform materials, no pictures), which
// loads without reading an image, for planning.
std::string worldYaml(const Home& home, const std::string& header, bool plain) {
  std::ostringstream os;
  os << header;
  os << "description: generated home, " << home.rooms.size() << " rooms, " << num(home.area(), 1)
     << " m2\n\n";
  os << home.materials.yaml(plain) << "\n";
  os << "rooms:\n";
  for (const PlanRoom& r : home.rooms) {
    os << "  - name: " << r.name << "\n";
    os << "    polygon: [" << point({r.r.x0, r.r.y0}) << ", " << point({r.r.x1, r.r.y0}) << ", "
       << point({r.r.x1, r.r.y1}) << ", " << point({r.r.x0, r.r.y1}) << "]\n";
    os << "    height: " << num(r.height) << "\n";
    os << "    walls: [" << joined(std::vector<std::string>(r.walls.begin(), r.walls.end()), ", ")
       << "]   # south, east, north, west\n";
    os << "    floor: " << r.floor << "\n";
    os << "    ceiling: " << r.ceiling << "\n";
  }
  os << "\ndoors:" << (home.openings.empty() ? " []" : "") << "\n";
  for (const Opening& o : home.openings) {
    os << "  - {at: " << point(o.point()) << ", width: " << num(o.width)
       << ", height: " << num(o.height) << "}   # "
       << home.rooms[static_cast<size_t>(o.wall.a)].name << " - "
       << home.rooms[static_cast<size_t>(o.wall.b)].name << (o.wide ? ", open plan" : "") << "\n";
  }
  os << "\n# size: [width, depth, height]; the front faces facing_deg (0 = +x, 90 = +y).\n";
  os << "boxes:" << (home.boxes.empty() ? " []" : "") << "\n";
  for (const BoxSpec& b : home.boxes) os << boxYaml(b);
  if (!plain && !home.pictures.empty()) {
    os << "\npictures:\n";
    for (const PictureSpec& p : home.pictures) {
      os << "  - {image: \"" << p.image << "\", centre: [" << num(p.centre.x()) << ", "
         << num(p.centre.y()) << ", " << num(p.centre.z()) << "], width: " << num(p.width)
         << ", facing_deg: " << num(p.facing_deg, 0);
      if (p.gain != 1) os << ", gain: " << num(p.gain, 3);
      os << "}\n";
    }
  }
  if (!plain) {
    os << "\nstart: [" << num(home.start.x()) << ", " << num(home.start.y()) << ", "
       << home.start_deg << "]\n";
  }
  return os.str();
}

// ---- Planning on a grid over World::isFree
class GridPlanner {
 public:
  explicit GridPlanner(const world::World& world) : world_(world) {
    const Eigen::AlignedBox2d b = world.bounds();
    origin_ = b.min();
    nx_ = static_cast<int>(std::ceil(b.sizes().x() / kCell));
    ny_ = static_cast<int>(std::ceil(b.sizes().y() / kCell));
    cv::Mat mask(ny_, nx_, CV_8U);
    room_.resize(size());
    for (int y = 0; y < ny_; ++y) {
      for (int x = 0; x < nx_; ++x) {
        const Vec2 c = centre(y * nx_ + x);
        mask.at<uint8_t>(y, x) = world.isFree(c.x(), c.y(), kPlanClearance) ? 255 : 0;
        room_[static_cast<size_t>(y * nx_ + x)] = world.roomIndexAt(c.x(), c.y());
      }
    }
    // Clearance beyond kPlanClearance: routes keep to the middle of rooms.
    cv::Mat dist;
    cv::distanceTransform(mask, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    extra_.resize(size());
    free_.resize(size());
    for (int y = 0; y < ny_; ++y) {
      for (int x = 0; x < nx_; ++x) {
        const size_t i = static_cast<size_t>(y * nx_ + x);
        free_[i] = mask.at<uint8_t>(y, x) != 0;
        extra_[i] = free_[i] ? static_cast<double>(dist.at<float>(y, x)) * kCell : 0.0;
      }
    }
    // The largest 8-connected free region is where the robot drives.
    component_.assign(size(), -1);
    int best = -1;
    size_t best_size = 0;
    for (size_t i = 0; i < size(); ++i) {
      if (!free_[i] || component_[i] >= 0) continue;
      const int id = static_cast<int>(i);
      size_t count = 0;
      std::vector<int> stack = {id};
      component_[i] = id;
      while (!stack.empty()) {
        const int c = stack.back();
        stack.pop_back();
        ++count;
        forNeighbours(c, [&](int nb, double) {
          if (component_[static_cast<size_t>(nb)] < 0) {
            component_[static_cast<size_t>(nb)] = id;
            stack.push_back(nb);
          }
        });
      }
      if (count > best_size) best_size = count, best = id;
    }
    main_ = best;
  }

  size_t size() const { return static_cast<size_t>(nx_) * static_cast<size_t>(ny_); }
  Vec2 centre(int i) const {
    return {mm(origin_.x() + (i % nx_ + 0.5) * kCell), mm(origin_.y() + (i / nx_ + 0.5) * kCell)};
  }
  int cellAt(const Vec2& p) const {
    const int x =
        std::clamp(static_cast<int>(std::floor((p.x() - origin_.x()) / kCell)), 0, nx_ - 1);
    const int y =
        std::clamp(static_cast<int>(std::floor((p.y() - origin_.y()) / kCell)), 0, ny_ - 1);
    return y * nx_ + x;
  }
  bool drivable(int i) const { return main_ >= 0 && component_[static_cast<size_t>(i)] == main_; }
  int roomOf(int i) const { return room_[static_cast<size_t>(i)]; }
  double extra(int i) const { return extra_[static_cast<size_t>(i)]; }

  // Share of each room's floor the robot can reach.
  std::vector<double> drivableShare(size_t rooms) const {
    std::vector<double> all(rooms, 0), reach(rooms, 0);
    for (size_t i = 0; i < size(); ++i) {
      if (room_[i] < 0) continue;
      all[static_cast<size_t>(room_[i])] += 1;
      if (drivable(static_cast<int>(i))) reach[static_cast<size_t>(room_[i])] += 1;
    }
    for (size_t r = 0; r < rooms; ++r) reach[r] = all[r] > 0 ? reach[r] / all[r] : 0;
    return reach;
  }

  // A random drivable cell of `room` (-1: any), preferring ones with
  // `want_extra` of clearance to spare and at least `min_dist` from `away`.
  std::optional<int> randomCell(Rng& rng, int room, double want_extra, const Vec2& away,
                                double min_dist) const {
    std::vector<int> good, ok;
    for (size_t i = 0; i < size(); ++i) {
      const int c = static_cast<int>(i);
      if (!drivable(c) || (room >= 0 && room_[i] != room)) continue;
      if ((centre(c) - away).norm() < min_dist) continue;
      (extra_[i] >= want_extra ? good : ok).push_back(c);
    }
    if (!good.empty()) return rng.pick(good);
    if (!ok.empty()) return rng.pick(ok);
    return std::nullopt;
  }

  // A drivable cell within `radius` of p, the nearest one.
  std::optional<int> nearestDrivable(const Vec2& p, double radius) const {
    const int c = cellAt(p);
    const int r = static_cast<int>(std::ceil(radius / kCell));
    std::optional<int> best;
    double best_d = radius;
    for (int dy = -r; dy <= r; ++dy) {
      for (int dx = -r; dx <= r; ++dx) {
        const int x = c % nx_ + dx, y = c / nx_ + dy;
        if (x < 0 || y < 0 || x >= nx_ || y >= ny_) continue;
        const int i = y * nx_ + x;
        const double d = (centre(i) - p).norm();
        if (drivable(i) && d <= best_d) best_d = d, best = i;
      }
    }
    return best;
  }

  // Waypoints from cell a to cell b (both drivable): A* on the grid, with
  // a cost for passing near obstacles, then shortcuts where the straight line
  // keeps clear; every segment verified with World::isFree.
  std::vector<Vec2> path(int a, int b) const {
    const std::vector<int> cells = search(a, b);
    std::vector<size_t> keep = {0};
    size_t i = 0;
    while (i + 1 < cells.size()) {
      size_t best = i + 1;
      double narrowest = std::min(extra(cells[i]), extra(cells[i + 1]));
      for (size_t j = i + 2; j < cells.size() && j < best + 20; ++j) {
        narrowest = std::min(narrowest, extra(cells[j]));
        // As much room as the grid path had (up to 15 cm), less a cell and a
        // half: a straight line crosses cells the stepped path went round.
        if (lineClear(centre(cells[i]), centre(cells[j]),
                      std::min(0.15, narrowest) - 1.5 * kCell)) {
          best = j;
        }
      }
      keep.push_back(best);
      i = best;
    }
    std::vector<Vec2> out = {centre(cells.front())};
    for (size_t k = 1; k < keep.size(); ++k) appendVerified(cells, keep[k - 1], keep[k], &out);
    // A short hop (where the stepped path met its goal) costs a turn on the
    // spot: drop its corner where the straight line is free too.
    for (size_t k = 1; k + 1 < out.size();) {
      const bool hop = std::min((out[k] - out[k - 1]).norm(), (out[k + 1] - out[k]).norm()) < 0.3;
      if (hop && segmentFree(out[k - 1], out[k + 1], kSegmentClearance)) {
        out.erase(out.begin() + static_cast<long>(k));
      } else {
        ++k;
      }
    }
    return out;
  }

  // Is a disc of `radius` free all along a -> b, sampled every kSampleStep?
  bool segmentFree(const Vec2& a, const Vec2& b, double radius) const {
    const double len = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(len / kSampleStep)));
    for (int k = 0; k <= steps; ++k) {
      const Vec2 p = a + (b - a) * (static_cast<double>(k) / steps);
      if (!world_.isFree(p.x(), p.y(), radius)) return false;
    }
    return true;
  }

 private:
  template <class F>
  void forNeighbours(int c, F&& f) const {
    const int x = c % nx_, y = c / nx_;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if ((dx == 0 && dy == 0) || x + dx < 0 || y + dy < 0 || x + dx >= nx_ || y + dy >= ny_) {
          continue;
        }
        const int nb = c + dy * nx_ + dx;
        if (!free_[static_cast<size_t>(nb)]) continue;
        // Diagonal steps only where both cells beside them are free.
        if (dx != 0 && dy != 0 &&
            (!free_[static_cast<size_t>(c + dx)] || !free_[static_cast<size_t>(c + dy * nx_)])) {
          continue;
        }
        f(nb, dx != 0 && dy != 0 ? M_SQRT2 : 1.0);
      }
    }
  }

  std::vector<int> search(int a, int b) const {
    std::vector<double> g(size(), HUGE_VAL);
    std::vector<int> parent(size(), -1);
    using Entry = std::pair<double, int>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
    const Vec2 goal = centre(b);
    auto h = [&](int c) {
      const Vec2 d = (centre(c) - goal).cwiseAbs();
      return d.maxCoeff() + (M_SQRT2 - 1) * d.minCoeff();
    };
    g[static_cast<size_t>(a)] = 0;
    open.push({h(a), a});
    while (!open.empty()) {
      // Not a structured binding: clang 14 (scripts/fuzz) cannot capture one.
      const double f = open.top().first;
      const int c = open.top().second;
      open.pop();
      if (c == b) break;
      if (f > g[static_cast<size_t>(c)] + h(c) + 1e-9) continue;
      forNeighbours(c, [&](int nb, double step) {
        const double near = std::max(0.0, 1.0 - extra(nb) / 0.3);
        const double cost = g[static_cast<size_t>(c)] + step * kCell * (1.0 + 2.0 * near);
        if (cost < g[static_cast<size_t>(nb)]) {
          g[static_cast<size_t>(nb)] = cost;
          parent[static_cast<size_t>(nb)] = c;
          open.push({cost + h(nb), nb});
        }
      });
    }
    if (a != b && parent[static_cast<size_t>(b)] < 0) {
      throw std::logic_error("home generator: no path between drivable cells");
    }
    std::vector<int> cells = {b};
    while (cells.back() != a) cells.push_back(parent[static_cast<size_t>(cells.back())]);
    std::reverse(cells.begin(), cells.end());
    return cells;
  }

  // Grid line of sight: every sample on a free cell with `min_extra` to spare.
  bool lineClear(const Vec2& a, const Vec2& b, double min_extra) const {
    const double len = (b - a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(len / kSampleStep)));
    for (int k = 0; k <= steps; ++k) {
      const int c = cellAt(a + (b - a) * (static_cast<double>(k) / steps));
      if (!free_[static_cast<size_t>(c)] || extra(c) < min_extra - 1e-9) return false;
    }
    return true;
  }

  // Appends cells[j]'s centre, splitting i..j at the middle cell until every
  // segment is free for kSegmentClearance (neighbouring cells always are).
  void appendVerified(const std::vector<int>& cells, size_t i, size_t j,
                      std::vector<Vec2>* out) const {
    if (j > i + 1 && !segmentFree(centre(cells[i]), centre(cells[j]), kSegmentClearance)) {
      const size_t mid = (i + j) / 2;
      appendVerified(cells, i, mid, out);
      appendVerified(cells, mid, j, out);
      return;
    }
    out->push_back(centre(cells[j]));
  }

  const world::World& world_;
  Vec2 origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<bool> free_;
  std::vector<double> extra_;
  std::vector<int> room_;
  std::vector<int> component_;
  int main_ = -1;
};

// ---- Routes
double headingOf(const Vec2& from, const Vec2& to) {
  return std::atan2(to.y() - from.y(), to.x() - from.x());
}

// A run's waypoints with an estimate of its robot time (driving plus
// turning in place), from which legs are added.
class RouteBuilder {
 public:
  RouteBuilder(const GridPlanner& planner, double speed, double turn_rate)
      : planner_(&planner), speed_(speed), turn_rate_(turn_rate) {}

  void begin(int cell, double heading) {
    points_ = {planner_->centre(cell)};
    cell_ = cell;
    heading_ = heading;
    time_ = 0;
  }
  void legTo(int cell) { append(planner_->path(cell_, cell), cell); }
  // A path already planned, from the current end.
  void append(const std::vector<Vec2>& path, int end_cell) {
    for (size_t k = 1; k < path.size(); ++k) {
      const Vec2& last = points_.back();
      if ((path[k] - last).norm() < 0.01) continue;
      const double heading = headingOf(last, path[k]);
      time_ +=
          std::abs(wrapAngle(heading - heading_)) / turn_rate_ + (path[k] - last).norm() / speed_;
      heading_ = heading;
      points_.push_back(path[k]);
    }
    cell_ = end_cell;
  }
  double time() const { return time_; }
  int cell() const { return cell_; }
  const std::vector<Vec2>& points() const { return points_; }
  // Rough time to drive straight to p (paths bend, so a little more).
  double timeTo(const Vec2& p) const { return 1.3 * (p - points_.back()).norm() / speed_ + 2.0; }

 private:
  const GridPlanner* planner_;
  double speed_, turn_rate_;
  std::vector<Vec2> points_;
  int cell_ = 0;
  double heading_ = 0;
  double time_ = 0;
};

struct RoutePlan {
  std::string style;
  std::vector<Vec2> waypoints;     // the driver returns from the last to the first
  std::vector<size_t> run_starts;  // index of each later run's first waypoint
  std::vector<Pose2> carries;      // where each later run starts
};

struct Drive {
  double duration_s = 0;
  double length_m = 0;
  std::vector<double> carry_at_s;
};

// Drives the plan as the simulator will (its WaypointDriver, its step and
// its kidnapping rule) and finds each carry time: the step at which the
// driver, arrived at a run's end, turns towards the next run's start.
Drive simulateDrive(const MotionParams& motion, const RoutePlan& plan) {
  WaypointDriver driver(motion);
  const double dt = 1.0 / kOdometryRateHz;
  Pose2 pose = motion.start, step;
  Drive d;
  size_t next = 0;
  long k = 0;
  while (true) {
    ++k;
    if (k > static_cast<long>(3600 * kOdometryRateHz)) {
      throw std::logic_error("home generator: the route does not end");
    }
    if (!driver.advance(pose, dt, &step)) break;
    pose = pose.compose(step);
    d.length_m += std::hypot(step.x, step.y);
    if (next < plan.run_starts.size() && driver.target() >= plan.run_starts[next]) {
      // The simulator carries at the first step at or after at_s; half a
      // step before this one leaves no doubt about rounding.
      d.carry_at_s.push_back((static_cast<double>(k) - 0.5) * dt);
      pose = plan.carries[next++];
    }
  }
  d.duration_s = static_cast<double>(k - 1) * dt;
  return d;
}

using Runs = std::vector<std::vector<Vec2>>;  // driven stretches; carries in between

// Points every `step` along the runs' segments.
std::vector<Vec2> pointsAlong(const Runs& runs, double step) {
  std::vector<Vec2> out;
  for (const auto& run : runs) {
    for (size_t k = 0; k + 1 < run.size(); ++k) {
      const double len = (run[k + 1] - run[k]).norm();
      for (double s = 0; s < len; s += step)
        out.push_back(run[k] + (run[k + 1] - run[k]) * (s / len));
    }
    if (!run.empty()) out.push_back(run.back());
  }
  return out;
}

// The rooms the runs pass through, in order of first visit.
std::vector<int> roomsVisited(const GridPlanner& planner, const Runs& runs) {
  std::vector<int> rooms;
  for (const Vec2& p : pointsAlong(runs, 0.25)) {
    const int r = planner.roomOf(planner.cellAt(p));
    if (r >= 0 && std::find(rooms.begin(), rooms.end(), r) == rooms.end()) rooms.push_back(r);
  }
  return rooms;
}

class RoutePlanner {
 public:
  RoutePlanner(Rng& rng, const GridPlanner& planner, const Home& home, double speed,
               double turn_rate)
      : rng_(rng), planner_(planner), home_(home), speed_(speed), turn_rate_(turn_rate) {
    for (const Opening& o : home.openings) {
      doors_.emplace_back(o.wall.a, o.wall.b);
    }
  }

  // A closed route from the start cell back to it, about `budget_s` long.
  RouteBuilder closedRun(const std::string& style, int start, double heading, double budget_s) {
    RouteBuilder rb(planner_, speed_, turn_rate_);
    rb.begin(start, heading);
    if (style == "loop") {
      loop(rb, start, heading, budget_s);
    } else if (style == "out-and-back") {
      outAndBack(rb, start, budget_s);
    } else {
      explore(rb, budget_s, {}, start);
    }
    return rb;
  }

  // Random targets until the budget is spent, then back to `home_cell` if
  // given (>= 0): half the time in a `prefer` room (seen by earlier runs),
  // else mostly in a room not seen yet, else in another room.
  void explore(RouteBuilder& rb, double budget_s, const std::vector<int>& prefer, int home_cell) {
    const Vec2 home_at = home_cell >= 0 ? planner_.centre(home_cell) : Vec2::Zero();
    for (int leg = 0; leg < 60; ++leg) {
      const double remaining = budget_s - rb.time();
      if (remaining <= (home_cell >= 0 ? rb.timeTo(home_at) : 0.0)) break;
      const int here = planner_.roomOf(rb.cell());
      const std::vector<int> seen = roomsVisited(planner_, {rb.points()});
      std::vector<int> unseen, others;
      for (size_t r = 0; r < home_.rooms.size(); ++r) {
        const int room = static_cast<int>(r);
        if (room != here) others.push_back(room);
        if (std::find(seen.begin(), seen.end(), room) == seen.end() &&
            std::find(prefer.begin(), prefer.end(), room) == prefer.end()) {
          unseen.push_back(room);
        }
      }
      int room = here;
      if (!prefer.empty() && rng_.chance(0.5)) {
        room = rng_.pick(prefer);
      } else if (!unseen.empty() && rng_.chance(0.8)) {
        room = rng_.pick(unseen);
      } else if (!others.empty() && rng_.chance(0.8)) {
        room = rng_.pick(others);
      }
      const auto target = planner_.randomCell(rng_, room, 0.3, planner_.centre(rb.cell()), 1.0);
      if (target) rb.legTo(*target);
    }
    if (home_cell >= 0) rb.legTo(home_cell);
  }

 private:
  // Laps of a tour through the rooms (in depth-first order over the doors,
  // so through a hallway and back), as many as fit the budget.
  void loop(RouteBuilder& rb, int start, double heading, double budget_s) {
    const int start_room = planner_.roomOf(start);
    std::vector<int> order;
    std::function<void(int)> visit = [&](int r) {
      order.push_back(r);
      std::vector<int> next;
      for (const auto& [a, b] : doors_) {
        const int other = a == r ? b : b == r ? a : -1;
        if (other >= 0 && std::find(order.begin(), order.end(), other) == order.end() &&
            std::find(next.begin(), next.end(), other) == next.end()) {
          next.push_back(other);
        }
      }
      rng_.shuffle(next);
      for (int o : next) {
        if (std::find(order.begin(), order.end(), o) == order.end()) visit(o);
      }
    };
    visit(start_room);
    std::vector<int> targets;
    for (int r : order) {
      const double area = home_.rooms[static_cast<size_t>(r)].r.area();
      const int per_room = home_.rooms.size() == 1 ? 3 : area > 16 ? 2 : 1;
      for (int k = 0; k < per_room; ++k) {
        const Vec2 away =
            targets.empty() ? planner_.centre(start) : planner_.centre(targets.back());
        if (const auto c = planner_.randomCell(rng_, r, 0.25, away, 1.5)) targets.push_back(*c);
      }
    }
    // Two or three laps (so the loop closes twice), dropping the last
    // rooms (down to three targets) while a lap is too long for that; more
    // laps if they are short, one if a lap is long.
    const int want_laps = 2 + static_cast<int>(rng_.index(2));
    RouteBuilder lap(planner_, speed_, turn_rate_);
    while (true) {
      lap.begin(start, heading);
      for (int t : targets) lap.legTo(t);
      lap.legTo(start);
      if (lap.time() <= budget_s / want_laps || targets.size() <= 3) break;
      targets.pop_back();
    }
    int laps = std::max(1, static_cast<int>(std::lround(budget_s / lap.time())));
    while (laps > 1 && laps * lap.time() > budget_s + 20) --laps;
    for (int k = 0; k < laps; ++k) rb.append(lap.points(), start);
  }

  // Out to a far point of the home and back the same way, several times.
  void outAndBack(RouteBuilder& rb, int start, double budget_s) {
    for (int spoke = 0; spoke < 12 && rb.time() < budget_s; ++spoke) {
      // The farthest of a few random points (of another room when there is one).
      std::optional<int> far;
      for (int k = 0; k < 8; ++k) {
        const auto c = planner_.randomCell(rng_, -1, 0.15, planner_.centre(start), 1.0);
        if (c && (!far || (planner_.centre(*c) - planner_.centre(start)).norm() >
                              (planner_.centre(*far) - planner_.centre(start)).norm())) {
          far = c;
        }
      }
      if (!far) break;
      const std::vector<Vec2> out = planner_.path(start, *far);
      RouteBuilder probe = rb;
      probe.append(out, *far);
      probe.append({out.rbegin(), out.rend()}, start);
      if (spoke > 0 && probe.time() > budget_s + 20) break;
      rb = probe;
    }
  }

  Rng& rng_;
  const GridPlanner& planner_;
  const Home& home_;
  double speed_, turn_rate_;
  std::vector<std::pair<int, int>> doors_;
};

// ---- The home, attempt by attempt (each attempt its own random stream)
bool buildHome(uint64_t seed, int attempt, Home* out) {
  Rng rng(seed, 1000 + static_cast<uint64_t>(attempt));
  Home home;
  const std::vector<int> room_counts = {1, 2, 2, 3, 3, 3, 4, 4, 4, 5, 5, 5, 6, 6};
  const int n = rng.pick(room_counts);
  home.corridor = n >= 3 && rng.chance(0.5);
  std::vector<Rect> rects;
  int corridor = -1;
  if (!makeLayout(rng, n, home.corridor, &rects, &corridor)) return false;
  nameRooms(rng, rects, corridor, home);
  if (!connectRooms(rng, home)) return false;
  defineMaterials(rng, home);
  dressRooms(rng, home);
  // Furniture, biggest rooms first, then pictures from one shuffled pool
  // (photos already on walls left out, so a picture never aliases a wall).
  const bool cupboards = rng.chance(0.5);
  Furnisher furnisher(rng, home);
  for (size_t r = 0; r < home.rooms.size(); ++r) furnisher.furnish(static_cast<int>(r), cupboards);
  std::vector<PicturePhoto> pool;
  for (const PicturePhoto& p : kPictures) {
    if (!home.wall_refs.count(p.ref)) pool.push_back(p);
  }
  rng.shuffle(pool);
  for (size_t r = 0; r < home.rooms.size(); ++r) furnisher.hangPictures(static_cast<int>(r), pool);
  *out = std::move(home);
  return true;
}

struct Planned {
  Home home;
  std::unique_ptr<world::World> world;  // floor plan only
  std::unique_ptr<GridPlanner> planner;
  int start_cell = 0;
};

// A home whose every room the robot can reach, with a free start pose.
Planned planHome(uint64_t seed) {
  for (int attempt = 0; attempt < kAttempts; ++attempt) {
    Planned p;
    if (!buildHome(seed, attempt, &p.home)) continue;
    p.world = std::make_unique<world::World>(
        world::World::loadString(worldYaml(p.home, "", /*plain=*/true),
                                 "generated home (seed " + std::to_string(seed) + ")"));
    p.planner = std::make_unique<GridPlanner>(*p.world);
    const std::vector<double> share = p.planner->drivableShare(p.home.rooms.size());
    if (*std::min_element(share.begin(), share.end()) < 0.25) continue;
    Rng rng(seed, 1500 + static_cast<uint64_t>(attempt));
    const int living = p.home.roomOfType(RoomType::kLiving);
    const auto start = p.planner->randomCell(rng, living, 0.3, Vec2(-1e9, -1e9), 0);
    if (!start) continue;
    p.start_cell = *start;
    p.home.start = p.planner->centre(p.start_cell);
    p.home.start_deg = static_cast<int>(rng.index(360)) - 179;
    return p;
  }
  throw std::runtime_error("home generator: no valid home for seed " + std::to_string(seed) +
                           " in " + std::to_string(kAttempts) + " attempts");
}

// The world loader's conversion of `start`'s degrees.
double loaderRadians(int deg) { return deg * (M_PI / 180.0); }

// Later runs start where the robot has been (the mapped part of the home):
// on an earlier run's path, a metre or more from where the last run ended.
std::optional<int> startOnEarlierRuns(Rng& rng, const GridPlanner& planner, const Runs& runs) {
  const Vec2 last_end = runs.back().back();
  std::vector<Vec2> samples = pointsAlong(runs, 0.25);
  rng.shuffle(samples);
  // Preferably in the open, not in a doorway.
  for (const double want_extra : {0.2, 0.0}) {
    for (const Vec2& p : samples) {
      if ((p - last_end).norm() < 1.0) continue;
      const auto c = planner.nearestDrivable(p, 0.15);
      if (c && planner.extra(*c) >= want_extra && (planner.centre(*c) - last_end).norm() >= 1.0) {
        return c;
      }
    }
  }
  return std::nullopt;
}

struct ScenarioPlan {
  RoutePlan route;
  MotionParams motion;
  Drive drive;
};

// Picks the speeds and the route of `kind`, and checks its duration.
std::optional<ScenarioPlan> planScenario(uint64_t seed, int attempt, HomeKind kind,
                                         const Planned& home) {
  Rng rng(seed, 2000 + static_cast<uint64_t>(attempt));
  const GridPlanner& planner = *home.planner;
  ScenarioPlan sp;
  MotionParams& motion = sp.motion;
  motion.mode = MotionMode::kWaypoints;
  // Values as the simulator will read them back from the text.
  motion.speed_mps = std::round(rng.uniform(0.2, 0.5) * 100) / 100;
  motion.turn_rate_rps = degToRad(std::round(rng.uniform(30, 90)));
  motion.start = {home.home.start.x(), home.home.start.y(), loaderRadians(home.home.start_deg)};
  RoutePlanner routes(rng, planner, home.home, motion.speed_mps, motion.turn_rate_rps);
  const std::vector<std::string> styles = {"loop", "loop", "out-and-back", "explore", "explore"};
  RoutePlan& plan = sp.route;
  const auto randomHeading = [&]() {
    return wrapAngle(degToRad(static_cast<double>(static_cast<int>(rng.index(360)) - 179)));
  };
  if (kind == HomeKind::kSequence) {
    plan.style = "explore";
    const int runs = 2 + static_cast<int>(rng.index(3));
    const double budget = rng.uniform(110, 180) / runs;
    RouteBuilder rb(planner, motion.speed_mps, motion.turn_rate_rps);
    rb.begin(home.start_cell, motion.start.theta);
    routes.explore(rb, budget, {}, -1);
    Runs driven = {rb.points()};
    plan.waypoints = rb.points();
    for (int run = 1; run < runs; ++run) {
      const auto start = startOnEarlierRuns(rng, planner, driven);
      if (!start) return std::nullopt;
      const Vec2 at = planner.centre(*start);
      plan.run_starts.push_back(plan.waypoints.size());
      plan.carries.push_back({at.x(), at.y(), randomHeading()});
      rb.begin(*start, plan.carries.back().theta);
      const bool last = run + 1 == runs;
      routes.explore(rb, budget, roomsVisited(planner, driven), last ? home.start_cell : -1);
      driven.push_back(rb.points());
      plan.waypoints.insert(plan.waypoints.end(), rb.points().begin(), rb.points().end());
    }
  } else {
    plan.style = rng.pick(styles);
    const double budget = rng.uniform(110, 175);
    RouteBuilder rb = routes.closedRun(plan.style, home.start_cell, motion.start.theta, budget);
    plan.waypoints = rb.points();
    if (kind == HomeKind::kKidnap) {
      // Cut the route at 40-60% of its length, somewhere along a segment,
      // and carry the robot to a room it has seen; from there it plans its
      // way back onto the rest of the route.
      double total = 0;
      for (size_t k = 0; k + 1 < plan.waypoints.size(); ++k) {
        total += (plan.waypoints[k + 1] - plan.waypoints[k]).norm();
      }
      double cut = rng.uniform(0.4, 0.6) * total;
      size_t seg = 0;
      for (; seg + 1 < plan.waypoints.size(); ++seg) {
        const double len = (plan.waypoints[seg + 1] - plan.waypoints[seg]).norm();
        if (cut <= len) break;
        cut -= len;
      }
      if (seg + 2 >= plan.waypoints.size()) return std::nullopt;
      const Vec2 a = plan.waypoints[seg], b = plan.waypoints[seg + 1];
      const double len = (b - a).norm();
      if (len < 0.7) return std::nullopt;
      const double s = std::clamp(cut, 0.3, len - 0.3);
      const Vec2 taken_at(mm(a.x() + (b.x() - a.x()) * s / len),
                          mm(a.y() + (b.y() - a.y()) * s / len));
      std::vector<Vec2> first(plan.waypoints.begin(),
                              plan.waypoints.begin() + static_cast<long>(seg) + 1);
      first.push_back(taken_at);
      std::vector<int> seen = roomsVisited(planner, {first});
      const int here = planner.roomOf(planner.cellAt(taken_at));
      if (seen.size() > 1) seen.erase(std::remove(seen.begin(), seen.end(), here), seen.end());
      const auto to = planner.randomCell(rng, rng.pick(seen), 0.2, taken_at, 1.5);
      if (!to) return std::nullopt;
      const int rejoin = planner.cellAt(b);
      RouteBuilder detour(planner, motion.speed_mps, motion.turn_rate_rps);
      const double heading = randomHeading();
      detour.begin(*to, heading);
      detour.legTo(rejoin);
      std::vector<Vec2> route = first;
      route.insert(route.end(), detour.points().begin(), detour.points().end());
      route.insert(route.end(), plan.waypoints.begin() + static_cast<long>(seg) + 2,
                   plan.waypoints.end());
      plan.run_starts = {first.size()};
      const Vec2 at = planner.centre(*to);
      plan.carries = {{at.x(), at.y(), heading}};
      plan.waypoints = route;
    }
  }
  // The driver closes the route: drop the final return to the start.
  if (plan.waypoints.size() > 2 && (plan.waypoints.back() - plan.waypoints.front()).norm() < 1e-9) {
    plan.waypoints.pop_back();
  }
  if (plan.waypoints.size() < 2) return std::nullopt;
  // Every driven segment free with margin (carries are not driven).
  for (size_t k = 0; k < plan.waypoints.size(); ++k) {
    const size_t next = (k + 1) % plan.waypoints.size();
    if (std::find(plan.run_starts.begin(), plan.run_starts.end(), next) != plan.run_starts.end()) {
      continue;
    }
    if (!planner.segmentFree(plan.waypoints[k], plan.waypoints[next], kSegmentClearance)) {
      return std::nullopt;
    }
  }
  motion.waypoints = plan.waypoints;
  sp.drive = simulateDrive(motion, plan);
  if (sp.drive.duration_s < kMinDuration || sp.drive.duration_s > kMaxDuration) return std::nullopt;
  return sp;
}

OdometryParams drawOdometry(uint64_t seed, double duration_s) {
  Rng rng(seed, 3000);
  OdometryParams o;
  o.rate_hz = kOdometryRateHz;
  o.sigma_translation = roundTo(rng.uniform(0.01, 0.05), 0.001);
  o.sigma_rotation = roundTo(rng.uniform(0.01, 0.04), 0.001);
  o.scale_bias = roundTo(rng.uniform(-0.02, 0.02), 0.0001);
  o.heading_bias = roundTo(rng.uniform(-0.01, 0.01), 0.0001);
  const double u = rng.unit();
  const int slips = u < 0.6 ? 0 : u < 0.85 ? 1 : 2;
  for (int k = 0; k < slips; ++k) {
    SlipEvent s;
    s.at_s = roundTo(rng.uniform(10, duration_s - 10), 0.1);
    s.duration_s = roundTo(rng.uniform(0.5, 2.0), 0.1);
    // Wheels spinning on a rug report more than the robot moves; a robot
    // pushed against furniture reports less.
    s.translation_factor =
        roundTo(rng.chance(0.5) ? rng.uniform(0.0, 0.7) : rng.uniform(1.2, 1.6), 0.01);
    s.rotation_factor = roundTo(rng.uniform(0.8, 1.2), 0.01);
    o.slips.push_back(s);
  }
  std::sort(o.slips.begin(), o.slips.end(),
            [](const SlipEvent& a, const SlipEvent& b) { return a.at_s < b.at_s; });
  return o;
}

std::string scenarioYaml(const HomeSummary& summary, const std::string& header,
                         const ScenarioPlan& sp, uint64_t scenario_seed) {
  std::ostringstream os;
  os << header;
  os << "name: home_" << summary.seed << "\n";
  os << "world: world.yaml\n";
  os << "seed: " << scenario_seed << "\n";
  os << "motion:\n";
  os << "  mode: waypoints            # from the world's start; back to the first waypoint\n";
  os << "  speed_mps: " << num(sp.motion.speed_mps, 2) << "\n";
  os << "  turn_rate_dps: " << num(summary.turn_rate_dps, 0) << "\n";
  os << "  waypoints:\n";
  const RoutePlan& plan = sp.route;
  for (size_t k = 0; k < plan.waypoints.size(); ++k) {
    const auto run = std::find(plan.run_starts.begin(), plan.run_starts.end(), k);
    if (k == 0 && !plan.run_starts.empty()) os << "    # run 1\n";
    if (run != plan.run_starts.end()) {
      os << "    # run " << (run - plan.run_starts.begin()) + 2 << ", after a carry\n";
    }
    os << "    - " << point(plan.waypoints[k]) << "\n";
  }
  const OdometryParams& o = summary.odometry;
  os << "odometry:\n";
  os << "  rate_hz: " << num(o.rate_hz, 0) << "\n";
  os << "  sigma_translation: " << num(o.sigma_translation) << "   # m / sqrt(m)\n";
  os << "  sigma_rotation: " << num(o.sigma_rotation) << "      # rad / sqrt(m + rad)\n";
  os << "  scale_bias: " << num(o.scale_bias, 4) << "\n";
  os << "  heading_bias: " << num(o.heading_bias, 4) << "        # rad / m\n";
  if (!o.slips.empty()) {
    os << "  slips:\n";
    for (const SlipEvent& s : o.slips) {
      os << "    - {at_s: " << num(s.at_s, 1) << ", duration_s: " << num(s.duration_s, 1)
         << ", translation_factor: " << num(s.translation_factor, 2)
         << ", rotation_factor: " << num(s.rotation_factor, 2) << "}\n";
    }
  }
  os << "cameras:\n";
  os << "  encoding: gray8\n";
  os << "  noise_sigma: 1.5\n";
  os << "  motion_blur: true\n";
  if (!plan.carries.empty()) {
    os << "disturbances:\n";
    os << "  kidnap:   # carried: at the end of one run to the start of the next\n";
    for (size_t k = 0; k < plan.carries.size(); ++k) {
      const Pose2& to = plan.carries[k];
      os << "    - {at_s: " << num(sp.drive.carry_at_s[k], 2) << ", to: [" << num(to.x) << ", "
         << num(to.y) << ", " << num(std::round(radToDeg(to.theta)), 0) << "]}\n";
    }
  }
  return os.str();
}

}  // namespace

const char* homeKindName(HomeKind kind) {
  switch (kind) {
    case HomeKind::kSingle:
      return "single";
    case HomeKind::kSequence:
      return "sequence";
    case HomeKind::kKidnap:
      return "kidnap";
  }
  return "?";
}

bool parseHomeKind(const std::string& name, HomeKind* kind) {
  for (HomeKind k : {HomeKind::kSingle, HomeKind::kSequence, HomeKind::kKidnap}) {
    if (name == homeKindName(k)) {
      *kind = k;
      return true;
    }
  }
  return false;
}

HomeKind autoHomeKind(uint64_t seed) {
  const double u = Rng(seed, 1).unit();
  return u < 0.6 ? HomeKind::kSingle : u < 0.8 ? HomeKind::kSequence : HomeKind::kKidnap;
}

std::string HomeSummary::line() const {
  std::ostringstream os;
  os << "seed=" << seed << " kind=" << homeKindName(kind) << " runs=" << runs << " rooms=" << rooms
     << " area_m2=" << num(floor_area_m2, 1) << " plan=" << (plan.empty() ? "-" : joined(plan, ","))
     << " route=" << route_style << " route_m=" << num(route_length_m, 1)
     << " duration_s=" << num(duration_s, 1) << " speed_mps=" << num(speed_mps, 2)
     << " turn_dps=" << num(turn_rate_dps, 0) << " sigma_t=" << num(odometry.sigma_translation)
     << " sigma_r=" << num(odometry.sigma_rotation)
     << " scale_bias=" << signedNum(odometry.scale_bias, 4)
     << " heading_bias=" << signedNum(odometry.heading_bias, 4)
     << " slips=" << odometry.slips.size()
     << " hard=" << (hard_cases.empty() ? "-" : joined(hard_cases, ","));
  return os.str();
}

GeneratedHome generateHome(uint64_t seed, HomeKind kind) {
  Planned home = planHome(seed);
  std::optional<ScenarioPlan> sp;
  for (int attempt = 0; attempt < kAttempts && !sp; ++attempt) {
    sp = planScenario(seed, attempt, kind, home);
  }
  if (!sp) {
    throw std::runtime_error("home generator: no route of " + std::to_string(kMinDuration) + "-" +
                             std::to_string(kMaxDuration) + " s for seed " + std::to_string(seed));
  }
  GeneratedHome out;
  HomeSummary& s = out.summary;
  s.seed = seed;
  s.kind = kind;
  s.rooms = static_cast<int>(home.home.rooms.size());
  s.floor_area_m2 = home.home.area();
  if (home.home.corridor) s.plan.push_back("corridor");
  if (home.home.open_plan) s.plan.push_back("open-plan");
  s.route_style = sp->route.style;
  s.runs = static_cast<int>(sp->route.run_starts.size()) + 1;
  s.route_length_m = sp->drive.length_m;
  s.duration_s = sp->drive.duration_s;
  s.speed_mps = sp->motion.speed_mps;
  s.turn_rate_dps = std::round(radToDeg(sp->motion.turn_rate_rps));
  s.odometry = drawOdometry(seed, s.duration_s);
  for (const char* h : {"wallpaper", "tiles", "cupboards", "plain-walls", "dim-room"}) {
    if (home.home.hard_cases.count(h)) s.hard_cases.push_back(h);
  }
  const std::string header = "# Generated by vslam-worldgen --seed " + std::to_string(seed) +
                             " --kind " + homeKindName(kind) +
                             " (regenerate rather than edit).\n# " + s.line() + "\n";
  out.world_yaml = worldYaml(home.home, header, /*plain=*/false);
  const uint64_t scenario_seed = Rng(seed, 4000).bits() % 1000000000ULL;
  out.scenario_yaml = scenarioYaml(s, header, *sp, scenario_seed);
  return out;
}

}  // namespace vslam::sim
