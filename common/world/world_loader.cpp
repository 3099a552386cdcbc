// World file loader: YAML -> World (docs/world-format.md). Every error is a
// config::ConfigError naming the file, the key path and "line N".
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "config/config_node.hpp"
#include "util/strings.hpp"
#include "world/geometry2d.hpp"
#include "world/texture_cache.hpp"
#include "world/world.hpp"

namespace vslam::world {
namespace fs = std::filesystem;
using config::ConfigError;

namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kMinEdgeM = 0.01;         // shortest polygon edge
constexpr double kOnWallTolM = 0.01;       // a door this close to a wall line is on it
constexpr double kPictureOffsetM = 0.005;  // pictures float this far off their wall
constexpr double kTableTopM = 0.04;        // top thickness of a box with legs
// Uniform grey levels of a textureless room (0..1), unless the material gives one.
constexpr float kPlainWall = 0.75f, kPlainFloor = 0.55f, kPlainCeiling = 0.85f;

struct Doc {
  std::string file;
  fs::path base_dir;
};

std::string fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// A YAML node with where it came from, for messages "file: key: line N: problem".
class Yn {
 public:
  Yn(const Doc* doc, YAML::Node node, std::string path, int fallback_line)
      : doc_(doc), node_(std::move(node)), path_(std::move(path)), fallback_line_(fallback_line) {}

  const std::string& path() const { return path_; }
  const YAML::Node& node() const { return node_; }
  int line() const {
    const YAML::Mark m = node_.Mark();
    return m.is_null() || m.line < 0 ? fallback_line_ : m.line + 1;
  }
  [[noreturn]] void fail(const std::string& problem) const { failAt(path_, line(), problem); }
  [[noreturn]] void failAt(const std::string& path, int line, const std::string& problem) const {
    throw ConfigError(doc_->file, path, "line " + std::to_string(line) + ": " + problem);
  }

  bool isMap() const { return node_.IsMap(); }
  bool isScalar() const { return node_.IsScalar(); }
  bool isSequence() const { return node_.IsSequence(); }

  void expectMap(const char* what) const {
    if (!node_.IsMap()) fail(std::string("expected ") + what + " (a mapping), got " + typeName());
  }

  // Checks that every key is one of `allowed` and none repeats.
  void allowKeys(const std::vector<std::string>& allowed) const {
    expectMap("a mapping");
    std::set<std::string> seen;
    for (auto it = node_.begin(); it != node_.end(); ++it) {
      const YAML::Node k = it->first;
      const int kline = k.Mark().is_null() ? line() : k.Mark().line + 1;
      if (!k.IsScalar()) failAt(path_, kline, "keys must be plain words");
      const std::string key = k.as<std::string>();
      const std::string kpath = childPath(key);
      if (!seen.insert(key).second) failAt(kpath, kline, "key '" + key + "' appears twice");
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string best;
        size_t best_d = 3;
        for (const auto& a : allowed) {
          const size_t d = editDistance(key, a);
          if (d < best_d) best_d = d, best = a;
        }
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        failAt(kpath, kline,
               "unknown key '" + key + "'" +
                   (best.empty() ? "" : " (did you mean '" + best + "'?)") +
                   "; allowed here: " + list);
      }
    }
  }

  bool has(const std::string& key) const { return node_.IsMap() && node_[key].IsDefined(); }

  Yn child(const std::string& key) const {
    if (!node_.IsMap()) fail("expected a mapping with key '" + key + "', got " + typeName());
    const YAML::Node c = node_[key];
    if (!c.IsDefined()) failAt(childPath(key), line(), "missing required key '" + key + "'");
    return Yn(doc_, c, childPath(key), line());
  }
  std::optional<Yn> optional(const std::string& key) const {
    if (!has(key)) return std::nullopt;
    return child(key);
  }

  std::vector<Yn> list(size_t min_size, const char* what) const {
    if (!node_.IsSequence())
      fail(std::string("expected a list of ") + what + ", got " + typeName());
    if (node_.size() < min_size) {
      fail("expected at least " + std::to_string(min_size) + " " + what + ", got " +
           std::to_string(node_.size()));
    }
    std::vector<Yn> out;
    for (size_t i = 0; i < node_.size(); ++i) {
      out.emplace_back(doc_, node_[i], path_ + "[" + std::to_string(i) + "]", line());
    }
    return out;
  }

  std::string text() const {
    if (!node_.IsScalar()) fail("expected a word or text, got " + typeName());
    const std::string s = node_.as<std::string>();
    if (s.empty()) fail("expected non-empty text");
    return s;
  }

  double number(double min = -HUGE_VAL, double max = HUGE_VAL, bool min_open = false) const {
    if (!node_.IsScalar()) fail("expected a number, got " + typeName());
    const std::string s = node_.as<std::string>();
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) {
      fail("expected a number, got '" + s + "'");
    }
    if (v < min || v > max || (min_open && v == min)) {
      std::string range;
      if (std::isinf(max)) {
        range = (min_open ? "> " : ">= ") + fmt(min);
      } else if (std::isinf(min)) {
        range = "<= " + fmt(max);
      } else {
        range = "in [" + fmt(min) + ", " + fmt(max) + "]";
      }
      fail("expected a number " + range + ", got " + s);
    }
    return v;
  }
  double positive() const { return number(0.0, HUGE_VAL, true); }

  bool boolean() const {
    if (node_.IsScalar()) {
      const std::string s = node_.as<std::string>();
      if (s == "true") return true;
      if (s == "false") return false;
    }
    fail("expected true or false");
  }

  Eigen::Vector2d vec2() const {
    const auto v = numbers(2);
    return {v[0], v[1]};
  }
  Eigen::Vector3d vec3() const {
    const auto v = numbers(3);
    return {v[0], v[1], v[2]};
  }
  std::vector<double> numbers(size_t n) const {
    if (!node_.IsSequence() || node_.size() != n) {
      fail("expected a list of " + std::to_string(n) + " numbers, got " + typeName());
    }
    std::vector<double> out;
    for (const Yn& e : list(n, "numbers")) out.push_back(e.number());
    return out;
  }

 private:
  std::string childPath(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }
  std::string typeName() const {
    switch (node_.Type()) {
      case YAML::NodeType::Null:
        return "nothing";
      case YAML::NodeType::Scalar:
        return "'" + node_.as<std::string>() + "'";
      case YAML::NodeType::Sequence:
        return "a list";
      case YAML::NodeType::Map:
        return "a mapping";
      default:
        return "nothing";
    }
  }

  const Doc* doc_;
  YAML::Node node_;
  std::string path_;
  int fallback_line_;
};

struct Material {
  int texture = -1;
  double scale_m = 1.0;
  double height_m = 1.0;  // of one texture image on the surface
  float albedo = 0.5f;
  float gain = 1.0f;
  bool uniform() const { return texture < 0; }
};

struct Interval {
  double a0, a1, height;
};

class Loader {
 public:
  explicit Loader(Doc doc) : doc_(std::move(doc)) {}

  World load(const YAML::Node& root_node) {
    world_.file = doc_.file;
    const Yn root(&doc_, root_node, "", 1);
    if (!root.isMap()) root.fail("a world file is a mapping with at least 'rooms'");
    root.allowKeys({"description", "exposure", "materials", "rooms", "doors", "boxes", "solids",
                    "pictures", "routes", "start"});
    if (auto d = root.optional("description")) d->text();
    if (auto e = root.optional("exposure")) world_.exposure = e->positive();
    if (auto m = root.optional("materials")) parseMaterials(*m);

    const Yn rooms = root.child("rooms");
    std::vector<Yn> room_nodes = rooms.list(1, "rooms");
    for (const Yn& r : room_nodes) parseRoom(r);
    checkRoomsDisjoint(room_nodes);

    edge_doors_.assign(world_.rooms.size(), {});
    for (size_t i = 0; i < world_.rooms.size(); ++i) {
      edge_doors_[i].assign(world_.rooms[i].polygon.size(), {});
    }
    if (auto d = root.optional("doors")) {
      for (const Yn& door : d->list(0, "doors")) parseDoor(door);
    }
    for (size_t i = 0; i < world_.rooms.size(); ++i) buildRoom(static_cast<int>(i));

    if (auto b = root.optional("boxes")) {
      for (const Yn& box : b->list(0, "boxes")) parseBox(box);
    }
    if (auto s = root.optional("solids")) {
      for (const Yn& solid : s->list(0, "solids")) parseSolid(solid);
    }
    if (auto p = root.optional("pictures")) {
      for (const Yn& pic : p->list(0, "pictures")) parsePicture(pic);
    }
    if (auto r = root.optional("routes")) {
      for (const Yn& route : r->list(0, "routes")) parseRoute(route);
    }
    if (auto s = root.optional("start")) {
      const auto v = s->numbers(3);
      if (world_.roomIndexAt(v[0], v[1]) < 0) s->fail("the start position is outside every room");
      world_.has_start = true;
      world_.start = {v[0], v[1], v[2] * kDegToRad};
    }
    return std::move(world_);
  }

 private:
  // --- Textures and materials ---
  int texture(const Yn& where, const std::string& ref, int rotate_deg,
              const std::optional<Yn>& crop = std::nullopt, bool mirror = false) {
    std::vector<double> rect;
    if (crop) rect = crop->numbers(4);
    std::string key = ref + "@" + std::to_string(rotate_deg) + (mirror ? "|mirror" : "");
    for (double v : rect) key += "," + fmt(v);
    if (auto it = texture_index_.find(key); it != texture_index_.end()) return it->second;
    auto prepare = [&] {
      cv::Mat img;
      try {
        img = loadTexture(ref, doc_.base_dir);
      } catch (const std::runtime_error& e) {
        where.fail(e.what());
      }
      if (crop) {
        const cv::Rect r(static_cast<int>(rect[0]), static_cast<int>(rect[1]),
                         static_cast<int>(rect[2]), static_cast<int>(rect[3]));
        if (r.width < 2 || r.height < 2 || r.x < 0 || r.y < 0 || r.x + r.width > img.cols ||
            r.y + r.height > img.rows) {
          crop->fail("crop [x, y, width, height] must lie inside the " + std::to_string(img.cols) +
                     " x " + std::to_string(img.rows) + " image");
        }
        img = img(r).clone();
      }
      // (Never in place: img may share its pixels with the texture cache.)
      const std::map<int, cv::RotateFlags> rotations = {{90, cv::ROTATE_90_CLOCKWISE},
                                                        {180, cv::ROTATE_180},
                                                        {270, cv::ROTATE_90_COUNTERCLOCKWISE}};
      if (const auto r = rotations.find(rotate_deg); r != rotations.end()) {
        cv::Mat rotated;
        cv::rotate(img, rotated, r->second);
        img = rotated;
      }
      if (mirror) {
        // Every other copy left-right mirrored (GL_MIRRORED_REPEAT along the
        // width): the pattern repeats only every two copies, and SIFT, which
        // is not mirror-invariant, does not match a copy with its neighbours.
        cv::Mat flipped, both;
        cv::flip(img, flipped, 1);
        cv::hconcat(img, flipped, both);
        img = both;
      }
      return img;
    };
    // Prepared once per process (texture_cache.hpp).
    const std::optional<std::string> identity =
        textureIdentity(ref, resolveTexturePath(ref, doc_.base_dir));
    const cv::Mat img = identity ? cachedTexture(*identity + "@" + key, prepare) : prepare();
    world_.textures.push_back(img);
    const int index = static_cast<int>(world_.textures.size()) - 1;
    texture_index_[key] = index;
    return index;
  }

  Material inlineMaterial(const Yn& n) {
    n.allowKeys({"texture", "scale_m", "rotate_deg", "crop", "mirror", "albedo", "gain"});
    Material m;
    if (auto g = n.optional("gain")) m.gain = static_cast<float>(g->number(0.0, 10.0));
    if (n.has("texture")) {
      if (n.has("albedo")) {
        n.child("albedo").fail("a material has either a texture or a uniform albedo, not both");
      }
      const Yn ref = n.child("texture");
      int rotate = 0;
      if (auto r = n.optional("rotate_deg")) {
        const double v = r->number();
        if (v != 0 && v != 90 && v != 180 && v != 270) r->fail("expected 0, 90, 180 or 270");
        rotate = static_cast<int>(v);
      }
      bool mirror = false;
      if (auto mr = n.optional("mirror")) mirror = mr->boolean();
      m.texture = texture(ref, ref.text(), rotate, n.optional("crop"), mirror);
      m.scale_m = n.child("scale_m").positive() * (mirror ? 2.0 : 1.0);  // of the doubled image
      const cv::Mat& img = world_.textures[static_cast<size_t>(m.texture)];
      m.height_m = m.scale_m * img.rows / img.cols;
    } else if (n.has("albedo")) {
      m.albedo = static_cast<float>(n.child("albedo").number(0.0, 1.0));
      if (n.has("scale_m")) n.child("scale_m").fail("scale_m needs a texture");
      if (n.has("rotate_deg")) n.child("rotate_deg").fail("rotate_deg needs a texture");
      if (n.has("crop")) n.child("crop").fail("crop needs a texture");
      if (n.has("mirror")) n.child("mirror").fail("mirror needs a texture");
    } else {
      n.fail("a material needs 'texture' (with 'scale_m') or 'albedo'");
    }
    return m;
  }

  void parseMaterials(const Yn& n) {
    n.expectMap("named materials");
    for (auto it = n.node().begin(); it != n.node().end(); ++it) {
      const YAML::Node key = it->first;
      const std::string name = key.as<std::string>();
      if (materials_.count(name)) {
        n.failAt(n.path() + "." + name, key.Mark().line + 1, "material defined twice");
      }
      materials_[name] = inlineMaterial(n.child(name));
    }
  }

  // A material: the name of one in `materials`, or an inline mapping.
  Material material(const Yn& n) {
    if (n.isScalar()) {
      const std::string name = n.text();
      auto it = materials_.find(name);
      if (it == materials_.end()) {
        std::string known;
        for (const auto& kv : materials_) known += (known.empty() ? "" : ", ") + kv.first;
        n.fail("unknown material '" + name + "'" +
               (known.empty() ? std::string(" (no 'materials' defined)") : "; known: " + known));
      }
      return it->second;
    }
    if (n.isMap()) return inlineMaterial(n);
    n.fail("expected a material name or a mapping {texture, scale_m} / {albedo}");
  }

  // --- Polygons ---
  geo::Polygon polygon(const Yn& n) {
    geo::Polygon p;
    for (const Yn& v : n.list(3, "[x, y] vertices")) p.push_back(v.vec2());
    for (size_t i = 0; i < p.size(); ++i) {
      if ((p[(i + 1) % p.size()] - p[i]).norm() < kMinEdgeM) {
        n.fail("degenerate polygon: vertices " + std::to_string(i) + " and " +
               std::to_string((i + 1) % p.size()) + " coincide (edges must be >= 1 cm)");
      }
    }
    int ei = -1, ej = -1;
    if (!geo::isSimple(p, &ei, &ej)) {
      n.fail("degenerate polygon: edges " + std::to_string(ei) + " and " + std::to_string(ej) +
             " intersect (the outline must not cross itself)");
    }
    const double area = geo::signedArea(p);
    if (std::abs(area) < 1e-4) n.fail("degenerate polygon: zero area");
    if (area < 0) std::reverse(p.begin(), p.end());
    return p;
  }

  // --- Rooms ---
  void parseRoom(const Yn& n) {
    n.allowKeys({"name", "polygon", "height", "walls", "floor", "ceiling", "textureless"});
    Room room;
    room.name = n.child("name").text();
    for (const Room& other : world_.rooms) {
      if (other.name == room.name) n.child("name").fail("room name '" + room.name + "' used twice");
    }
    const Yn poly = n.child("polygon");
    geo::Polygon given;
    for (const Yn& v : poly.list(3, "[x, y] vertices")) given.push_back(v.vec2());
    room.polygon = polygon(poly);
    const bool reversed = geo::signedArea(given) < 0;
    room.height_m = n.child("height").positive();
    if (auto t = n.optional("textureless")) room.textureless = t->boolean();

    RoomMaterials mats;
    const Yn walls = n.child("walls");
    const size_t edges = room.polygon.size();
    if (walls.isSequence()) {
      const std::vector<Yn> per_edge = walls.list(edges, "wall materials (one per polygon edge)");
      if (per_edge.size() != edges) {
        walls.fail("expected one wall material per polygon edge (" + std::to_string(edges) +
                   "), got " + std::to_string(per_edge.size()));
      }
      for (const Yn& m : per_edge) mats.walls.push_back(material(m));
      if (reversed) {
        // Edge i of the given (clockwise) outline is edge n-2-i of the reversed one.
        std::vector<Material> r(edges);
        for (size_t i = 0; i < edges; ++i) r[(2 * edges - 2 - i) % edges] = mats.walls[i];
        mats.walls = r;
      }
    } else {
      mats.walls.assign(edges, material(walls));
    }
    mats.floor = material(n.child("floor"));
    mats.ceiling = material(n.child("ceiling"));
    if (room.textureless) {
      for (Material& m : mats.walls) m = plain(m, kPlainWall);
      mats.floor = plain(mats.floor, kPlainFloor);
      mats.ceiling = plain(mats.ceiling, kPlainCeiling);
    }
    world_.rooms.push_back(room);
    room_materials_.push_back(mats);
  }

  static Material plain(const Material& m, float albedo) {
    if (m.uniform()) return m;
    Material p;
    p.albedo = albedo;
    return p;
  }

  void checkRoomsDisjoint(const std::vector<Yn>& nodes) {
    const auto& rooms = world_.rooms;
    for (size_t i = 0; i < rooms.size(); ++i) {
      for (size_t j = 0; j < i; ++j) {
        const geo::Polygon &a = rooms[i].polygon, &b = rooms[j].polygon;
        const bool overlap = geo::intersectionArea(a, b) > 1e-6;
        if (overlap) {
          nodes[i].child("polygon").fail("room '" + rooms[i].name + "' overlaps room '" +
                                         rooms[j].name + "'");
        }
      }
    }
  }

  void parseDoor(const Yn& n) {
    n.allowKeys({"at", "width", "height"});
    const Eigen::Vector2d at = n.child("at").vec2();
    const double width = n.child("width").positive();
    double height = 2.05;
    if (auto h = n.optional("height")) height = h->positive();
    bool found = false;
    Door door;
    door.height_m = height;
    for (size_t r = 0; r < world_.rooms.size(); ++r) {
      const geo::Polygon& p = world_.rooms[r].polygon;
      for (size_t e = 0; e < p.size(); ++e) {
        const Eigen::Vector2d a = p[e], b = p[(e + 1) % p.size()];
        if (geo::distanceToSegment(at, a, b) > kOnWallTolM) continue;
        const double len = (b - a).norm();
        const Eigen::Vector2d dir = (b - a) / len;
        const double s = (at - a).dot(dir);
        const Interval iv{s - 0.5 * width, s + 0.5 * width, height};
        if (iv.a0 < -1e-9 || iv.a1 > len + 1e-9) {
          n.child("width").fail("door at (" + fmt(at.x()) + ", " + fmt(at.y()) +
                                ") extends past the end of a wall of room '" +
                                world_.rooms[r].name + "'");
        }
        for (const Interval& other : edge_doors_[r][e]) {
          if (iv.a0 < other.a1 && other.a0 < iv.a1) n.fail("door overlaps another door");
        }
        edge_doors_[r][e].push_back(iv);
        door.a = a + std::max(0.0, iv.a0) * dir;
        door.b = a + std::min(len, iv.a1) * dir;
        found = true;
      }
    }
    if (!found) {
      n.child("at").fail("door at (" + fmt(at.x()) + ", " + fmt(at.y()) +
                         ") is on no room wall (within 1 cm)");
    }
    world_.doors.push_back(door);
  }

  static Surface quad(const Eigen::Vector3d& c0, const Eigen::Vector3d& c1,
                      const Eigen::Vector3d& c2, const Eigen::Vector3d& c3, const Material& m,
                      int room) {
    Surface s;
    s.corners = {c0, c1, c2, c3};
    s.texture = m.texture;
    s.texture_scale_m = m.scale_m;
    s.albedo = m.albedo;
    s.gain = m.gain;
    s.room = room;
    return s;
  }

  // Floor (up) or ceiling (down) of a counter-clockwise outline at height z,
  // one texture frame for the whole polygon.
  void addHorizontal(const geo::Polygon& p, double z, bool up, const Material& m, int room) {
    auto at = [&](int i) { return Eigen::Vector3d(p[i].x(), p[i].y(), z); };
    std::vector<std::array<int, 4>> quads;
    if (p.size() == 4 && geo::isConvex(p)) {
      quads.push_back({0, 1, 2, 3});
    } else {
      for (const auto& t : geo::triangulate(p)) quads.push_back({t[0], t[1], t[2], t[2]});
    }
    for (const auto& q : quads) {
      Surface s = up ? quad(at(q[0]), at(q[1]), at(q[2]), at(q[3]), m, room)
                     : quad(at(q[3]), at(q[2]), at(q[1]), at(q[0]), m, room);
      s.texture_origin = Eigen::Vector3d(0, 0, z);
      s.texture_u = Eigen::Vector3d::UnitX();
      s.texture_v = up ? Eigen::Vector3d(0, -1, 0) : Eigen::Vector3d(0, 1, 0);
      world_.surfaces.push_back(s);
    }
  }

  // Vertical faces along a counter-clockwise outline, facing `inward` (room
  // walls) or outward (solids), split at door gaps. Each piece is cut on a
  // grid of the door heights so that neighbouring quads share whole edges
  // (no T-junctions to crack in the rasteriser).
  void addWalls(const geo::Polygon& p, double z0, double height, bool inward,
                const std::vector<Material>& mats, const std::vector<std::vector<Interval>>& doors,
                int room, bool planning_segments) {
    double perimeter = 0.0;
    const double top = z0 + height;
    for (size_t e = 0; e < p.size(); ++e) {
      const Eigen::Vector2d a = p[e], b = p[(e + 1) % p.size()];
      const double len = (b - a).norm();
      const Eigen::Vector2d dir = (b - a) / len;
      std::vector<Interval> cuts = doors.empty() ? std::vector<Interval>() : doors[e];
      std::sort(cuts.begin(), cuts.end(),
                [](const Interval& x, const Interval& y) { return x.a0 < y.a0; });
      std::vector<double> heights = {z0, top};
      for (const Interval& c : cuts) {
        if (z0 + c.height < top) heights.push_back(z0 + c.height);
      }
      std::sort(heights.begin(), heights.end());
      heights.erase(std::unique(heights.begin(), heights.end()), heights.end());
      // Pieces along the edge: solid runs and door gaps.
      struct Piece {
        double s0, s1, bottom;
        bool door;
      };
      std::vector<Piece> pieces;
      double s = 0.0;
      for (const Interval& c : cuts) {
        const double c0 = std::max(0.0, c.a0), c1 = std::min(len, c.a1);
        if (c0 > s) pieces.push_back({s, c0, z0, false});
        pieces.push_back({c0, c1, z0 + c.height, true});
        s = c1;
      }
      if (s < len) pieces.push_back({s, len, z0, false});

      const Eigen::Vector3d dir3(dir.x(), dir.y(), 0.0);
      const Eigen::Vector3d a3(a.x(), a.y(), 0.0);
      for (const Piece& piece : pieces) {
        if (!piece.door && planning_segments) {
          world_.walls.push_back({a + piece.s0 * dir, a + piece.s1 * dir});
        }
        for (size_t h = 0; h + 1 < heights.size(); ++h) {
          const double lo = heights[h], hi = heights[h + 1];
          if (lo < piece.bottom - 1e-9) continue;
          const Eigen::Vector3d p0 = a3 + piece.s0 * dir3, p1 = a3 + piece.s1 * dir3;
          const Eigen::Vector3d zlo(0, 0, lo), zhi(0, 0, hi);
          Surface q = inward ? quad(p1 + zlo, p0 + zlo, p0 + zhi, p1 + zhi, mats[e], room)
                             : quad(p0 + zlo, p1 + zlo, p1 + zhi, p0 + zhi, mats[e], room);
          // Columns continue along the outline (seen from the visible side);
          // the image stands on the floor, where a low camera looks.
          const Eigen::Vector3d u = inward ? -dir3 : dir3;
          q.texture_u = u;
          q.texture_v = -Eigen::Vector3d::UnitZ();
          q.texture_origin = a3 + Eigen::Vector3d(0, 0, z0 + mats[e].height_m) - perimeter * dir3;
          world_.surfaces.push_back(q);
        }
      }
      perimeter += len;
    }
  }

  void buildRoom(int index) {
    const Room& room = world_.rooms[static_cast<size_t>(index)];
    const RoomMaterials& mats = room_materials_[static_cast<size_t>(index)];
    addWalls(room.polygon, 0.0, room.height_m, /*inward=*/true, mats.walls,
             edge_doors_[static_cast<size_t>(index)], index, /*planning_segments=*/true);
    addHorizontal(room.polygon, 0.0, /*up=*/true, mats.floor, index);
    addHorizontal(room.polygon, room.height_m, /*up=*/false, mats.ceiling, index);
  }

  int roomOf(const Eigen::Vector2d& p) const { return world_.roomIndexAt(p.x(), p.y()); }

  // --- Furniture, solids, pictures ---
  // Faces of an upright box in BoxFace order, plus a bottom when it floats
  // (a low camera looks up at wall cabinets and table tops).
  void addBox(const Eigen::Vector2d& centre, double z0, const Eigen::Vector3d& size_xyz, double yaw,
              const std::array<Material, 6>& mats, bool bottom, int room) {
    std::vector<Surface> faces =
        makeBox(Eigen::Vector3d(centre.x(), centre.y(), z0), size_xyz, yaw, -1, 1.0);
    if (bottom) {
      Surface b = faces[kBoxTop];
      const Eigen::Vector3d h(0, 0, size_xyz.z());
      b.corners = {faces[kBoxTop].corners[3] - h, faces[kBoxTop].corners[2] - h,
                   faces[kBoxTop].corners[1] - h, faces[kBoxTop].corners[0] - h};
      faces.push_back(b);
    }
    for (size_t f = 0; f < faces.size(); ++f) {
      const Material& m = mats[f];
      faces[f].texture = m.texture;
      faces[f].texture_scale_m = m.scale_m;
      faces[f].albedo = m.albedo;
      faces[f].gain = m.gain;
      faces[f].room = room;
      world_.surfaces.push_back(faces[f]);
    }
  }

  void parseBox(const Yn& n) {
    n.allowKeys({"name", "centre", "size", "facing_deg", "elevation", "legs", "material", "faces"});
    if (auto nm = n.optional("name")) nm->text();
    const Eigen::Vector2d centre = n.child("centre").vec2();
    const Yn size_node = n.child("size");
    const Eigen::Vector3d size = size_node.vec3();
    if (size.minCoeff() <= 0.0) size_node.fail("box sizes must be > 0");
    double facing = 0.0, elevation = 0.0, legs = 0.0;
    if (auto f = n.optional("facing_deg")) facing = f->number() * kDegToRad;
    if (auto e = n.optional("elevation")) elevation = e->number(0.0);
    if (auto l = n.optional("legs")) {
      legs = l->positive();
      if (2 * legs >= std::min(size.x(), size.y()) || size.z() <= kTableTopM) {
        l->fail("legs must be thinner than half the box and the box taller than its " +
                fmt(kTableTopM) + " m top");
      }
    }
    const int room = roomOf(centre);
    if (room < 0) n.child("centre").fail("box centre is outside every room");
    if (elevation + size.z() > world_.rooms[static_cast<size_t>(room)].height_m + 1e-9) {
      size_node.fail("box reaches above the ceiling of room '" +
                     world_.rooms[static_cast<size_t>(room)].name + "'");
    }
    std::optional<Material> all;
    if (auto m = n.optional("material")) all = material(*m);
    std::array<std::optional<Material>, 6> given;
    if (auto faces = n.optional("faces")) {
      faces->allowKeys({"front", "back", "left", "right", "top", "bottom"});
      const std::array<std::pair<const char*, int>, 6> names = {{{"front", kBoxPlusX},
                                                                 {"back", kBoxMinusX},
                                                                 {"left", kBoxPlusY},
                                                                 {"right", kBoxMinusY},
                                                                 {"top", kBoxTop},
                                                                 {"bottom", 5}}};
      for (const auto& [name, face] : names) {
        if (auto f = faces->optional(name)) given[static_cast<size_t>(face)] = material(*f);
      }
    }
    std::array<Material, 6> mats;
    for (size_t f = 0; f < 6; ++f) {
      if (given[f]) {
        mats[f] = *given[f];
      } else if (all) {
        mats[f] = *all;
      } else if (f == 5 && given[kBoxTop]) {
        mats[f] = *given[kBoxTop];
      } else {
        n.fail("box needs 'material' (or all its 'faces': front, back, left, right, top)");
      }
    }
    // The front faces `facing`: box x = depth (towards the front), y = width.
    const Eigen::Vector3d size_xyz(size.y(), size.x(), size.z());
    if (legs <= 0.0) {
      addBox(centre, elevation, size_xyz, facing, mats, elevation > 0.0, room);
    } else {
      // A table: a top slab on four square legs (of the `material`, else the front's).
      const double top_z = elevation + size.z() - kTableTopM;
      addBox(centre, top_z, Eigen::Vector3d(size_xyz.x(), size_xyz.y(), kTableTopM), facing, mats,
             true, room);
      std::array<Material, 6> leg_mats;
      leg_mats.fill(all ? *all : mats[kBoxPlusX]);
      const double c = std::cos(facing), s = std::sin(facing);
      for (int i : {-1, 1}) {
        for (int j : {-1, 1}) {
          const double lx = i * (0.5 * size_xyz.x() - 0.5 * legs);
          const double ly = j * (0.5 * size_xyz.y() - 0.5 * legs);
          const Eigen::Vector2d at = centre + Eigen::Vector2d(c * lx - s * ly, s * lx + c * ly);
          addBox(at, elevation, Eigen::Vector3d(legs, legs, top_z - elevation), facing, leg_mats,
                 elevation > 0.0, room);
        }
      }
    }
    // Planning: the whole footprint is an obstacle (tables included).
    const std::vector<Surface> outline =
        makeBox(Eigen::Vector3d(centre.x(), centre.y(), 0.0), size_xyz, facing, -1, 1.0);
    geo::Polygon footprint;
    for (int i : {kBoxMinusY, kBoxPlusX, kBoxPlusY, kBoxMinusX}) {
      footprint.push_back(outline[static_cast<size_t>(i)].corners[0].head<2>());
    }
    if (geo::signedArea(footprint) < 0) std::reverse(footprint.begin(), footprint.end());
    world_.obstacles.push_back(footprint);
  }

  void parseSolid(const Yn& n) {
    n.allowKeys({"name", "polygon", "height", "material", "top"});
    if (auto nm = n.optional("name")) nm->text();
    const geo::Polygon p = polygon(n.child("polygon"));
    const double height = n.child("height").positive();
    const Material side = material(n.child("material"));
    const Material top = n.has("top") ? material(n.child("top")) : side;
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const auto& v : p) centroid += v / static_cast<double>(p.size());
    const int room = roomOf(centroid);
    addWalls(p, 0.0, height, /*inward=*/false, std::vector<Material>(p.size(), side), {}, room,
             /*planning_segments=*/false);
    addHorizontal(p, height, /*up=*/true, top, room);
    world_.obstacles.push_back(p);
  }

  void parsePicture(const Yn& n) {
    n.allowKeys({"name", "image", "centre", "width", "facing_deg", "gain"});
    if (auto nm = n.optional("name")) nm->text();
    const Yn image = n.child("image");
    const int tex = texture(image, image.text(), 0);
    const Eigen::Vector3d c = n.child("centre").vec3();
    const double width = n.child("width").positive();
    const double facing = n.child("facing_deg").number() * kDegToRad;
    float gain = 1.0f;
    if (auto g = n.optional("gain")) gain = static_cast<float>(g->number(0.0, 10.0));
    const cv::Mat& img = world_.textures[static_cast<size_t>(tex)];
    const double height = width * img.rows / img.cols;
    const Eigen::Vector3d f(std::cos(facing), std::sin(facing), 0.0);
    const Eigen::Vector3d right(-f.y(), f.x(), 0.0);  // the viewer's right
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d m = c + kPictureOffsetM * f;
    const int room = roomOf((m + 0.05 * f).head<2>());
    if (room < 0) n.child("centre").fail("picture is outside every room (or faces out of it)");
    Material mat;
    mat.texture = tex;
    mat.scale_m = width;
    mat.gain = gain;
    const double hw = 0.5 * width, hh = 0.5 * height;
    world_.surfaces.push_back(quad(m - hw * right - hh * up, m + hw * right - hh * up,
                                   m + hw * right + hh * up, m - hw * right + hh * up, mat, room));
  }

  void parseRoute(const Yn& n) {
    n.allowKeys({"name", "waypoints", "closed"});
    Route r;
    r.name = n.child("name").text();
    for (const Yn& w : n.child("waypoints").list(2, "[x, y] waypoints")) {
      r.waypoints.push_back(w.vec2());
    }
    if (auto c = n.optional("closed")) r.closed = c->boolean();
    world_.routes.push_back(r);
  }

  struct RoomMaterials {
    std::vector<Material> walls;
    Material floor, ceiling;
  };

  Doc doc_;
  World world_;
  std::map<std::string, Material> materials_;
  std::map<std::string, int> texture_index_;
  std::vector<RoomMaterials> room_materials_;
  std::vector<std::vector<std::vector<Interval>>> edge_doors_;  // [room][edge]
};

World loadDocument(const std::string& text, const std::string& origin, const fs::path& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(origin, "",
                      "line " + std::to_string(e.mark.line + 1) + ": YAML syntax error: " + e.msg);
  }
  return Loader(Doc{origin, base_dir}).load(root);
}

}  // namespace

World World::loadFile(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file.string(), "", "cannot open world file");
  std::stringstream ss;
  ss << in.rdbuf();
  return loadDocument(ss.str(), file.string(), file.parent_path());
}

World World::loadString(const std::string& yaml, const std::string& origin,
                        const fs::path& base_dir) {
  return loadDocument(yaml, origin, base_dir);
}

}  // namespace vslam::world
