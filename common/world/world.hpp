#pragma once
// The simulated indoor world: textured planar surfaces (walls, floors,
// ceilings, furniture) plus the 2-D layout the simulator plans in (rooms,
// wall segments, obstacle footprints). Loaded from a YAML world file
// (docs/world-format.md) and drawn by vslam::world::Renderer.
//
// Frames: world x/y horizontal, z up, metres. Surfaces are one-sided: a
// quad is visible from the side its corners turn counter-clockwise.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vslam::world {

// One planar textured quad in the world frame. A triangle is a quad whose
// last two corners coincide.
struct Surface {
  std::array<Eigen::Vector3d, 4> corners;  // counter-clockwise seen from the visible side
  int texture = -1;                        // index into World::textures; -1 = uniform `albedo`
  double texture_scale_m = 1;              // metres per texture image width
  float albedo = 0.5f;                     // used when texture < 0, 0..1

  // --- Additions to the brief's interface (all optional) ---
  // Multiplies the texture (or albedo): a darker or brighter material.
  float gain = 1.0f;
  // Texture placement. When texture_u is zero (the default) it follows the
  // corners: the image's top-left corner lies at corners[3], its columns run
  // along corners[0] -> corners[1] and its rows from corners[3] towards
  // corners[0]; so a wall quad given bottom-left, bottom-right, top-right,
  // top-left shows the image upright, one image width every texture_scale_m
  // metres, repeated. Otherwise texture pixel (0,0) is at texture_origin and
  // columns/rows run along the unit vectors texture_u/texture_v (in the
  // plane); adjacent quads sharing a frame continue one pattern.
  Eigen::Vector3d texture_origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d texture_u = Eigen::Vector3d::Zero();
  Eigen::Vector3d texture_v = Eigen::Vector3d::Zero();
  // Index into World::rooms of the room this surface belongs to (lit by),
  // -1 for none; RenderEffects::room_exposure dims rooms by it.
  int room = -1;
};

// The 2-D floor plan of a room. `polygon` is counter-clockwise.
struct Room {
  std::string name;
  std::vector<Eigen::Vector2d> polygon;
  double height_m = 2.5;
  bool textureless = false;
};

// A wall segment for motion planning (a room edge without its door gaps).
struct WallSegment {
  Eigen::Vector2d a, b;
};

// A gap cut in the walls of the rooms it lies on.
struct Door {
  Eigen::Vector2d a, b;  // ends of the gap on the wall line
  double height_m = 2.05;
};

// A named sequence of waypoints the world was designed for (e.g. a loop).
struct Route {
  std::string name;
  std::vector<Eigen::Vector2d> waypoints;
  bool closed = false;  // drive back from the last waypoint to the first
};

struct World {
  std::vector<cv::Mat> textures;  // CV_8UC3 BGR (gray derived as needed)
  std::vector<Surface>
      surfaces;  // static geometry (walls both sides as needed, floors, ceilings, boxes)
  double exposure = 1.0;
  std::string file;  // where it came from

  // --- Floor plan, for planning and scenarios ---
  std::vector<Room> rooms;
  std::vector<WallSegment> walls;
  std::vector<Door> doors;
  // Footprints (counter-clockwise polygons) of furniture and solid pillars;
  // every box is an obstacle whatever its height above the floor.
  std::vector<std::vector<Eigen::Vector2d>> obstacles;
  std::vector<Route> routes;
  bool has_start = false;
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  // x, y (m), yaw (rad), if has_start

  // Loads a world file (docs/world-format.md). Any error (YAML syntax,
  // unknown key, wrong type, missing texture, degenerate polygon...) throws
  // vslam::config::ConfigError naming the file, the key and "line N".
  static World loadFile(const std::filesystem::path& file);
  // The same from text: `origin` names it in messages and relative texture
  // paths resolve against `base_dir`.
  static World loadString(const std::string& yaml, const std::string& origin,
                          const std::filesystem::path& base_dir = ".");

  // For motion planning: is a disc of `radius` at (x, y) inside a room and
  // clear of walls and furniture? (Door gaps are passable.)
  bool isFree(double x, double y, double radius) const;
  // Axis-aligned bounds of the floor, metres.
  Eigen::AlignedBox2d bounds() const;
  // Name of the room containing (x, y), "" if none.
  std::string roomAt(double x, double y) const;
  // Index of that room in `rooms`, -1 if none.
  int roomIndexAt(double x, double y) const;

  // Loads a texture reference ("skimage:brick.png", "opencv:graf1.png",
  // "procedural:noise", or a path relative to `base_dir`), appends it to
  // `textures` and returns its index; e.g. for the simulator's walking
  // people. Throws std::runtime_error if it cannot be loaded. Call before
  // constructing a Renderer: the renderer prepares textures once.
  int addTexture(const std::string& reference, const std::filesystem::path& base_dir = ".");
};

// Faces of an upright box, in the order makeBox returns them.
enum BoxFace { kBoxPlusX = 0, kBoxMinusX = 1, kBoxPlusY = 2, kBoxMinusY = 3, kBoxTop = 4 };

// Helper for people/furniture: the 5 visible faces (no bottom) of an upright
// box standing on `centre_bottom`; `size` = extents along the box's own x, y
// (the world's rotated by `yaw` radians about z) and its height. Faces in
// BoxFace order; each side's texture stands upright with its top-left at the
// face's top-left seen from outside.
std::vector<Surface> makeBox(const Eigen::Vector3d& centre_bottom, const Eigen::Vector3d& size,
                             double yaw, int texture, double texture_scale_m);

// Resolves a texture reference to a file: "skimage:NAME" and "opencv:NAME"
// name the sample-image folders of python3-skimage and opencv-doc; anything
// else is a path relative to `base_dir`. "procedural:..." references are not
// files (empty result).
std::filesystem::path resolveTexturePath(const std::string& reference,
                                         const std::filesystem::path& base_dir);
// Loads a texture reference as CV_8UC3 BGR (procedural ones generated);
// throws std::runtime_error naming the reference and the file. Decoded once
// per process: the pixels are shared with every other load of the same
// texture, so treat them as read-only (copy before writing).
cv::Mat loadTexture(const std::string& reference, const std::filesystem::path& base_dir);
// Names of the built-in procedural textures ("noise", "checker", ...).
std::vector<std::string> proceduralTextureNames();

// OpenCV camera frame pose (x right, y down, z forward) of a level camera at
// `position` looking along world heading `yaw` (radians, from +x towards +y),
// tilted up by `pitch` radians.
Eigen::Isometry3d levelCameraPose(const Eigen::Vector3d& position, double yaw, double pitch = 0.0);

}  // namespace vslam::world
