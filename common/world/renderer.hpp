#pragma once
// A software renderer for vslam::world::World: what a (distorted) pinhole
// camera sees, fast enough to simulate several cameras at camera rate.
//
// Per frame: surfaces are culled and clipped at the near plane, their
// coverage is rasterised into a 2x2-sample visibility buffer (surface id +
// depth, z-buffered), then every pixel is shaded once per distinct surface
// among its samples (4x MSAA: anti-aliased edges at ~1x shading cost).
// Texture coordinates come from the exact plane-to-image homography
// (perspective-correct) and are sampled trilinearly from a mip pyramid whose
// level follows the pixel footprint, so distant or oblique textures are
// prefiltered instead of aliasing. The undistorted image covers the field of
// view the distorted one needs; lens distortion is applied by a remap
// computed once per camera (exactly OpenCV's model). Exposure (saturating),
// Gaussian noise and motion blur follow.

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <vector>

#include "world/world.hpp"

namespace vslam::world {

// OpenCV pinhole + distortion (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4 [tx ty]]]]).
struct CameraModel {
  int width = 320, height = 240;
  double fx = 277.0, fy = 277.0, cx = 159.5, cy = 119.5;
  std::vector<double> distortion;

  cv::Matx33d cameraMatrix() const { return {fx, 0, cx, 0, fy, cy, 0, 0, 1}; }
  // Reads an OpenCV calibration file (image_width, image_height,
  // camera_matrix, distortion_coefficients), e.g. config/calib/*.yml.
  static CameraModel fromCalibrationFile(const std::string& file);
};

struct RenderEffects {
  double exposure = 1.0;     // multiplies the world's exposure (lights dimmed/brightened)
  double noise_sigma = 0.0;  // Gaussian sensor noise, grey levels
  uint64_t noise_seed = 0;   // deterministic noise per frame
  // Addition: per-room brightness factors indexed like World::rooms (e.g.
  // lights off in one room = 0.1); empty = all 1. Surfaces without a room
  // are unaffected; dynamic surfaces without one take the room at their centre.
  std::vector<double> room_exposure;
};

struct RendererOptions {
  double near_m = 0.001;   // near clipping plane: a camera 1 cm from a wall still sees all of it
  bool antialias = true;   // 2x2 visibility samples per pixel (edges smoothed)
  uint8_t background = 0;  // where no surface is seen
};

class Renderer {
 public:
  Renderer(const World& world, const CameraModel& camera, const RendererOptions& options = {});
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  // Renders what a camera at world_T_camera (OpenCV camera frame: x right, y
  // down, z forward) sees. `dynamic` surfaces (e.g. walking people as
  // textured upright boxes; textures index the world's) are drawn too.
  // `out` is CV_8UC1 (gray) or CV_8UC3 (bgr) as `color` says; its buffer is
  // reused across calls. Not thread-safe: one Renderer per thread.
  void render(const Eigen::Isometry3d& world_T_camera, const std::vector<Surface>& dynamic,
              const RenderEffects& effects, bool color, cv::Mat& out);
  // Motion blur: the average of renders at the given poses across the
  // exposure time (noise added once, to the average).
  void renderBlurred(const std::vector<Eigen::Isometry3d>& world_T_camera_samples,
                     const std::vector<Surface>& dynamic, const RenderEffects& effects, bool color,
                     cv::Mat& out);

  const CameraModel& camera() const;
  // The internal undistorted pinhole image: size and intrinsics (fx, fy
  // equal the camera's; the principal point moves so that the image covers
  // every distorted pixel). Equal to the camera when it has no distortion.
  cv::Size pinholeSize() const;
  cv::Matx33d pinholeMatrix() const;
  // Largest round-trip error (pixels) of the distortion map: distorting the
  // undistorted coordinates of each output pixel again with OpenCV.
  double distortionMapError() const;
  // Output pixels no ray reaches because the lens model folds over there
  // (they show the background). The constructor throws
  // std::invalid_argument if they exceed 0.5% of the image.
  size_t distortionInvalidPixels() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vslam::world
