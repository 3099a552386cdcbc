// Renders views of a world file to PNG: for the docs' example frames and for
// checking a world by eye.
//
//   world_preview WORLD OUT_PREFIX x,y,yaw_deg[,height_m[,pitch_deg]] ... [--color]
//                 [--calib FILE] [--noise SIGMA] [--top]
// writes OUT_PREFIX<i>.png per pose; --top also writes OUT_PREFIXplan.png, a
// floor plan (walls, obstacles, routes, free space for a 0.15 m radius).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "world/renderer.hpp"
#include "world/world.hpp"

using namespace vslam::world;

namespace {

void drawPlan(const World& w, const std::string& file) {
  const Eigen::AlignedBox2d b = w.bounds();
  const double ppm = 40.0, margin = 0.5;
  const int width = static_cast<int>((b.sizes().x() + 2 * margin) * ppm);
  const int height = static_cast<int>((b.sizes().y() + 2 * margin) * ppm);
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(40, 40, 40));
  auto px = [&](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>((p.x() - b.min().x() + margin) * ppm),
                     static_cast<int>(height - (p.y() - b.min().y() + margin) * ppm));
  };
  for (int y = 0; y < height; y += 2) {
    for (int x = 0; x < width; x += 2) {
      const double wx = x / ppm + b.min().x() - margin,
                   wy = (height - y) / ppm + b.min().y() - margin;
      if (w.isFree(wx, wy, 0.15)) cv::rectangle(img, {x, y}, {x + 1, y + 1}, {90, 140, 90}, -1);
    }
  }
  for (const auto& o : w.obstacles) {
    for (size_t i = 0; i < o.size(); ++i)
      cv::line(img, px(o[i]), px(o[(i + 1) % o.size()]), {0, 140, 255}, 1);
  }
  for (const auto& s : w.walls) cv::line(img, px(s.a), px(s.b), {255, 255, 255}, 2);
  for (const auto& r : w.routes) {
    for (size_t i = 0; i + 1 < r.waypoints.size() + (r.closed ? 1 : 0); ++i) {
      cv::line(img, px(r.waypoints[i]), px(r.waypoints[(i + 1) % r.waypoints.size()]),
               {255, 80, 80}, 1);
    }
  }
  for (const auto& r : w.rooms) {
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (const auto& v : r.polygon) c += v / static_cast<double>(r.polygon.size());
    cv::putText(img, r.name, px(c), cv::FONT_HERSHEY_SIMPLEX, 0.4, {255, 255, 0}, 1);
  }
  cv::imwrite(file, img);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: world_preview WORLD OUT_PREFIX x,y,yaw_deg[,height[,pitch_deg]] ... "
                 "[--color] [--calib FILE] [--noise SIGMA] [--top]\n";
    return 2;
  }
  try {
    const World world = World::loadFile(argv[1]);
    const std::string prefix = argv[2];
    CameraModel cam{320, 240, 277.13, 277.13, 160, 120, {-0.05, 0.01, 0, 0, 0}};
    bool color = false, top = false;
    double noise = 0.0;
    std::vector<std::vector<double>> poses;
    for (int i = 3; i < argc; ++i) {
      if (!std::strcmp(argv[i], "--color")) {
        color = true;
      } else if (!std::strcmp(argv[i], "--top")) {
        top = true;
      } else if (!std::strcmp(argv[i], "--calib") && i + 1 < argc) {
        cam = CameraModel::fromCalibrationFile(argv[++i]);
      } else if (!std::strcmp(argv[i], "--noise") && i + 1 < argc) {
        noise = std::stod(argv[++i]);
      } else {
        std::vector<double> v;
        std::stringstream ss(argv[i]);
        std::string item;
        while (std::getline(ss, item, ',')) v.push_back(std::stod(item));
        if (v.size() < 3) throw std::runtime_error(std::string("bad pose ") + argv[i]);
        poses.push_back(v);
      }
    }
    if (top) drawPlan(world, prefix + "plan.png");
    Renderer renderer(world, cam);
    cv::Mat img;
    RenderEffects fx;
    fx.noise_sigma = noise;
    for (size_t i = 0; i < poses.size(); ++i) {
      const auto& p = poses[i];
      const double h = p.size() > 3 ? p[3] : 0.3, pitch = p.size() > 4 ? p[4] : 0.0;
      const auto pose = levelCameraPose({p[0], p[1], h}, p[2] * M_PI / 180, pitch * M_PI / 180);
      const auto t0 = std::chrono::steady_clock::now();
      renderer.render(pose, {}, fx, color, img);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      const std::string file = prefix + std::to_string(i) + ".png";
      cv::imwrite(file, img);
      std::printf("%s  (%.2f ms, room '%s', free %d)\n", file.c_str(), ms,
                  world.roomAt(p[0], p[1]).c_str(), world.isFree(p[0], p[1], 0.15));
    }
  } catch (const std::exception& e) {
    std::cerr << "world_preview: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
