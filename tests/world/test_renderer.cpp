// Renderer: geometry against OpenCV's projection, occlusion, clipping,
// texture prefiltering, exposure, noise, blur, and the shipped worlds as the
// estimator will see them (SIFT features).
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "world/renderer.hpp"
#include "world/world.hpp"

namespace fs = std::filesystem;
using namespace vslam::world;

namespace {

const fs::path kSource = VSLAM_SOURCE_DIR;

// The simulated 320x240 camera (config/calib/sim_320x240.yml) and a strongly
// distorted one, where ignoring any distortion term moves corners by pixels.
CameraModel simCamera() {
  return CameraModel::fromCalibrationFile((kSource / "config/calib/sim_320x240.yml").string());
}
CameraModel distortedCamera() {
  return CameraModel{320, 240, 270.0, 268.0, 163.2, 117.6, {-0.28, 0.09, 0.0015, -0.001, -0.012}};
}
// OpenCV's rational model (8 coefficients: k1 k2 p1 p2 k3 k4 k5 k6), a wide
// barrel lens.
CameraModel rationalCamera() {
  return CameraModel{
      320, 240, 250.0, 251.0, 158.0, 121.0, {0.1, 0.02, 0.001, 0.0005, 0.0, 0.3, 0.05, 0.0}};
}

Surface quad(const Eigen::Vector3d& c0, const Eigen::Vector3d& c1, const Eigen::Vector3d& c2,
             const Eigen::Vector3d& c3, float albedo, int texture = -1, double scale = 1.0) {
  Surface s;
  s.corners = {c0, c1, c2, c3};
  s.albedo = albedo;
  s.texture = texture;
  s.texture_scale_m = scale;
  return s;
}

// A vertical rectangle centred at `c`, facing `normal` (horizontal), of the
// given width and height.
Surface facingRect(const Eigen::Vector3d& c, const Eigen::Vector3d& normal, double width,
                   double height, float albedo, int texture = -1, double scale = 1.0) {
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d right = up.cross(n);  // viewer's right when looking against n
  const double w = 0.5 * width, h = 0.5 * height;
  Surface s = quad(c - w * right - h * up, c + w * right - h * up, c + w * right + h * up,
                   c - w * right + h * up, albedo, texture, scale);
  const Eigen::Vector3d nn = (s.corners[1] - s.corners[0]).cross(s.corners[3] - s.corners[0]);
  EXPECT_GT(nn.dot(n), 0.0);
  return s;
}

// Projection of world points with OpenCV for a camera at world_T_camera.
std::vector<cv::Point2f> projectCv(const std::vector<Eigen::Vector3d>& pts,
                                   const Eigen::Isometry3d& world_T_camera,
                                   const CameraModel& cam) {
  const Eigen::Isometry3d camera_T_world = world_T_camera.inverse();
  cv::Matx33d R;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) R(i, j) = camera_T_world.linear()(i, j);
  }
  cv::Vec3d rvec;
  cv::Rodrigues(R, rvec);
  const Eigen::Vector3d t = camera_T_world.translation();
  std::vector<cv::Point3d> obj;
  for (const auto& p : pts) obj.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, rvec, cv::Vec3d(t.x(), t.y(), t.z()), cam.cameraMatrix(), cam.distortion,
                    img);
  std::vector<cv::Point2f> out;
  for (const auto& p : img) out.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
  return out;
}

// Centroid of the darkness around `guess` (a dark dot on a bright ground).
cv::Point2d darkCentroid(const cv::Mat& gray, cv::Point2f guess, int half = 5) {
  const int x0 = static_cast<int>(std::lround(guess.x)),
            y0 = static_cast<int>(std::lround(guess.y));
  double bright = 0;
  for (int y = y0 - half; y <= y0 + half; ++y) {
    for (int x = x0 - half; x <= x0 + half; ++x)
      bright = std::max(bright, double(gray.at<uint8_t>(y, x)));
  }
  double sw = 0, sx = 0, sy = 0;
  for (int y = y0 - half; y <= y0 + half; ++y) {
    for (int x = x0 - half; x <= x0 + half; ++x) {
      const double w = std::max(0.0, bright - gray.at<uint8_t>(y, x) - 2.0);
      sw += w;
      sx += w * x;
      sy += w * y;
    }
  }
  return sw > 0 ? cv::Point2d(sx / sw, sy / sw) : cv::Point2d(-1e9, -1e9);
}

double meanOf(const cv::Mat& m) { return cv::mean(m)[0]; }

// A closed box room x in [0, 5], y in [0, 4], z in [0, 2.5]; each face a
// distinct pure colour (4x4 textures), so the colour seen tells the face.
World colouredRoom(std::vector<cv::Vec3b>* colours) {
  World w;
  *colours = {{40, 40, 220},  {40, 220, 40},  {220, 40, 40},
              {40, 220, 220}, {220, 40, 220}, {220, 220, 40}};
  for (const auto& c : *colours) w.textures.push_back(cv::Mat(4, 4, CV_8UC3, cv::Scalar(c)));
  const double X = 5, Y = 4, Z = 2.5;
  auto P = [](double x, double y, double z) { return Eigen::Vector3d(x, y, z); };
  // Walls facing inward: -y wall (y=0), +x wall, +y wall, -x wall; floor; ceiling.
  w.surfaces.push_back(quad(P(0, 0, 0), P(X, 0, 0), P(X, 0, Z), P(0, 0, Z), 0.5f, 0));
  w.surfaces.push_back(quad(P(X, 0, 0), P(X, Y, 0), P(X, Y, Z), P(X, 0, Z), 0.5f, 1));
  w.surfaces.push_back(quad(P(X, Y, 0), P(0, Y, 0), P(0, Y, Z), P(X, Y, Z), 0.5f, 2));
  w.surfaces.push_back(quad(P(0, Y, 0), P(0, 0, 0), P(0, 0, Z), P(0, Y, Z), 0.5f, 3));
  w.surfaces.push_back(quad(P(0, 0, 0), P(0, Y, 0), P(X, Y, 0), P(X, 0, 0), 0.5f, 4));
  w.surfaces.push_back(quad(P(0, 0, Z), P(X, 0, Z), P(X, Y, Z), P(0, Y, Z), 0.5f, 5));
  // Every face turns its visible side into the room.
  const Eigen::Vector3d inside(X / 2, Y / 2, Z / 2);
  for (Surface& s : w.surfaces) {
    const Eigen::Vector3d n = (s.corners[1] - s.corners[0]).cross(s.corners[3] - s.corners[0]);
    if (n.dot(inside - s.corners[0]) < 0) std::swap(s.corners[1], s.corners[3]);
  }
  return w;
}

// Which face of the coloured room a ray from `o` along `d` hits first.
int faceHit(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double best = 1e9;
  int face = -1;
  const double planes[6][2] = {{1, 0}, {0, 5}, {1, 4}, {0, 0}, {2, 0}, {2, 2.5}};
  const int order[6] = {0, 1, 2, 3, 4, 5};  // -y, +x, +y, -x, floor, ceiling
  for (int k = 0; k < 6; ++k) {
    const int axis = static_cast<int>(planes[k][0]);
    if (std::abs(d[axis]) < 1e-12) continue;
    const double t = (planes[k][1] - o[axis]) / d[axis];
    if (t > 1e-9 && t < best) best = t, face = order[k];
  }
  return face;
}

int closestColour(const cv::Vec3b& px, const std::vector<cv::Vec3b>& colours) {
  int best = -1;
  double best_d = 1e9;
  for (size_t i = 0; i < colours.size(); ++i) {
    // Lighting scales all channels: compare normalised colours.
    cv::Vec3d a(px[0], px[1], px[2]), b(colours[i][0], colours[i][1], colours[i][2]);
    const double d = cv::norm(a / (cv::norm(a) + 1e-9) - b / cv::norm(b));
    if (d < best_d) best_d = d, best = static_cast<int>(i);
  }
  return best;
}

}  // namespace

// A known 3-D point renders at the pixel cv::projectPoints predicts, with the
// same intrinsics and distortion: dots of a texture on an oblique wall
// (perspective-correct texturing + distortion), and small dark patches
// (rasterised geometry). Tolerance 0.3 px; ignoring the distortion would
// move the corner points by 3-10 px.
TEST(Renderer, PointsProjectWhereOpenCvSays) {
  for (const CameraModel& cam : {distortedCamera(), simCamera(), rationalCamera()}) {
    World w;
    cv::Mat tex(256, 256, CV_8UC3, cv::Scalar(225, 225, 225));
    // A dark dot centred on texel edge 128: at (0.5, 0.5) m of each 1 m tile.
    tex(cv::Rect(125, 125, 6, 6)).setTo(cv::Scalar(20, 20, 20));
    w.textures.push_back(tex);
    // Wall through (3.5, 0, 0) turned 35 degrees away from facing the camera.
    const double a = 35.0 * M_PI / 180;
    const Eigen::Vector3d n(-std::cos(a), -std::sin(a), 0.0);
    const Eigen::Vector3d o(3.5, 0.0, 1.0);
    Surface wall = facingRect(o, n, 40.0, 20.0, 0.5f, 0, 1.0);
    const Eigen::Vector3d u = Eigen::Vector3d::UnitZ().cross(n), v = -Eigen::Vector3d::UnitZ();
    wall.texture_origin = o;
    wall.texture_u = u;
    wall.texture_v = v;
    w.surfaces.push_back(wall);
    Renderer r(w, cam);
    EXPECT_LT(r.distortionMapError(), 0.01);

    const Eigen::Isometry3d pose = levelCameraPose({0, 0, 0.8}, 0.1, 0.05);
    // Dark patches ~8 px wide floating 1 cm in front of the wall, between the
    // dots (coverage is sampled 2x2 per pixel: a small patch's edges are
    // quantised to half a pixel; a larger one averages that over its rows).
    std::vector<Surface> patches;
    std::vector<Eigen::Vector3d> dots, patch_centres;
    for (int i = -8; i <= 8; ++i) {
      for (int j = -3; j <= 3; ++j) {
        dots.push_back(o + (i + 0.5) * u + (j + 0.5) * v);
        const Eigen::Vector3d pc = o + i * u + j * v + 0.01 * n;
        patch_centres.push_back(pc);
        const double size = 0.03 * (pc - pose.translation()).norm();
        patches.push_back(facingRect(pc, n, size, size, 0.03f));
      }
    }
    cv::Mat img;
    r.render(pose, patches, {}, false, img);
    ASSERT_EQ(img.type(), CV_8UC1);
    ASSERT_EQ(img.cols, cam.width);
    for (const auto& [points, what] :
         {std::pair{dots, "texture dot"}, std::pair{patch_centres, "patch"}}) {
      const auto predicted = projectCv(points, pose, cam);
      // Where the points are in view at all: OpenCV's polynomial folds
      // points far outside the field of view back into the image.
      CameraModel ideal = cam;
      ideal.distortion.clear();
      const auto undistorted = projectCv(points, pose, ideal);
      int checked = 0;
      double worst = 0;
      for (size_t k = 0; k < predicted.size(); ++k) {
        const cv::Point2f p = predicted[k], ideal_p = undistorted[k];
        if (p.x < 10 || p.y < 10 || p.x > cam.width - 11 || p.y > cam.height - 11) continue;
        if (ideal_p.x < -0.2 * cam.width || ideal_p.x > 1.2 * cam.width ||
            ideal_p.y < -0.2 * cam.height || ideal_p.y > 1.2 * cam.height) {
          continue;
        }
        const cv::Point2d c = darkCentroid(img, p, what[0] == 'p' ? 8 : 5);
        const double err = std::hypot(c.x - p.x, c.y - p.y);
        worst = std::max(worst, err);
        EXPECT_LT(err, 0.3) << what << " " << k << " predicted " << p << " rendered " << c;
        ++checked;
      }
      EXPECT_GE(checked, 12) << what;
      RecordProperty(std::string("worst_px_") + what + "_fx" + std::to_string(int(cam.fx)),
                     std::to_string(worst));
    }
  }
}

// Nearer surfaces hide farther ones, whatever the drawing order; back faces
// are not drawn.
TEST(Renderer, ZBufferHidesFartherSurfaces) {
  const CameraModel cam = simCamera();
  const Eigen::Isometry3d pose = levelCameraPose({0, 0, 1.0}, 0.0);
  const Surface wall = facingRect({4, 0, 1}, {-1, 0, 0}, 10, 4, 0.9f);
  const auto near_box = makeBox({2, 0, 0.6}, {0.5, 0.8, 0.8}, 0.2, -1, 1.0);  // spans z 0.6..1.4
  const auto far_box = makeBox({6, 0, 0.0}, {1, 3, 3}, 0.0, -1, 1.0);         // behind the wall
  std::vector<Surface> dark_near = near_box, bright_far = far_box;
  for (auto& s : dark_near) s.albedo = 0.1f;
  for (auto& s : bright_far) s.albedo = 0.3f;

  cv::Mat wall_only, a, b, c;
  {
    World w;
    w.surfaces = {wall};
    Renderer(w, cam).render(pose, {}, {}, false, wall_only);
  }
  {
    World w;  // box drawn after the wall
    w.surfaces = {wall};
    w.surfaces.insert(w.surfaces.end(), dark_near.begin(), dark_near.end());
    w.surfaces.insert(w.surfaces.end(), bright_far.begin(), bright_far.end());
    Renderer(w, cam).render(pose, {}, {}, false, a);
  }
  {
    World w;  // box drawn before the wall
    w.surfaces = dark_near;
    w.surfaces.insert(w.surfaces.end(), bright_far.begin(), bright_far.end());
    w.surfaces.push_back(wall);
    Renderer(w, cam).render(pose, {}, {}, false, b);
  }
  {
    World w;  // box as a dynamic surface
    w.surfaces = {wall};
    Renderer r(w, cam);
    std::vector<Surface> dyn = bright_far;
    dyn.insert(dyn.end(), dark_near.begin(), dark_near.end());
    r.render(pose, dyn, {}, false, c);
  }
  const auto centre = projectCv({{2, 0, 1.0}}, pose, cam)[0];
  const cv::Point ci(static_cast<int>(centre.x), static_cast<int>(centre.y));
  const uint8_t wall_value = wall_only.at<uint8_t>(ci);
  EXPECT_GT(wall_value, 150);
  for (const cv::Mat* m : {&a, &b, &c}) {
    EXPECT_LT(m->at<uint8_t>(ci), 40) << "box pixel shows the wall";
    EXPECT_EQ(m->at<uint8_t>(10, 10), wall_only.at<uint8_t>(10, 10));  // off the box: wall
    EXPECT_EQ(cv::norm(*m, a, cv::NORM_INF), 0.0);                     // order does not matter
  }
  // The far box never shows through: away from the near box every pixel is the wall's.
  cv::Mat diff;
  cv::absdiff(a, wall_only, diff);
  std::vector<Eigen::Vector3d> box_corners;
  for (const auto& s : near_box)
    box_corners.insert(box_corners.end(), s.corners.begin(), s.corners.end());
  std::vector<cv::Point2f> box_px = projectCv(box_corners, pose, cam);
  const cv::Rect box_area = cv::boundingRect(box_px) + cv::Size(3, 3) - cv::Point(1, 1);
  diff(box_area & cv::Rect(0, 0, 320, 240)).setTo(0);
  EXPECT_EQ(cv::countNonZero(diff), 0);
}

// The camera inside a closed room, anywhere (1 cm from a wall, in corners,
// tilted and rolled): no pixel is left empty, and the face the optical axis
// hits is the one seen at the centre. Exercises near-plane clipping of
// polygons that cross behind the camera.
TEST(Renderer, InsideClosedRoomNoHolesAnyPose) {
  std::vector<cv::Vec3b> colours;
  const World w = colouredRoom(&colours);
  const CameraModel cam = simCamera();
  Renderer r(w, cam);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0.01, 4.99), uy(0.01, 3.99), uz(0.02, 2.48),
      uang(-M_PI, M_PI), utilt(-0.6, 0.6);
  cv::Mat img;
  for (int k = 0; k < 150; ++k) {
    Eigen::Vector3d p(ux(rng), uy(rng), uz(rng));
    if (k % 3 == 0) p.x() = (k % 2) ? 0.01 : 4.99;  // hugging a wall
    Eigen::Isometry3d pose = levelCameraPose(p, uang(rng), utilt(rng));
    pose.linear() =
        pose.linear() * Eigen::AngleAxisd(utilt(rng), Eigen::Vector3d::UnitZ()).matrix();
    r.render(pose, {}, {}, true, img);
    std::vector<cv::Mat> ch;
    cv::split(img, ch);
    const cv::Mat empty = (ch[0] == 0) & (ch[1] == 0) & (ch[2] == 0);
    ASSERT_EQ(cv::countNonZero(empty), 0) << "holes at pose " << p.transpose();
    const int expected = faceHit(p, pose.linear().col(2));
    const cv::Vec3b centre = img.at<cv::Vec3b>(120, 160);
    // The principal point is (160, 120) for this camera; skip rays that graze an edge.
    const Eigen::Vector3d d = pose.linear().col(2);
    bool near_edge = false;
    for (double dx : {-0.02, 0.02}) {
      for (double dy : {-0.02, 0.02}) {
        const Eigen::Vector3d dd = d + dx * pose.linear().col(0) + dy * pose.linear().col(1);
        near_edge = near_edge || faceHit(p, dd) != expected;
      }
    }
    if (!near_edge) {
      EXPECT_EQ(closestColour(centre, colours), expected) << p.transpose();
    }
  }
}

// A fine checkerboard floor seen at a grazing angle: far rows must average to
// the mean grey (prefiltered), not alias into a pattern of noise, while the
// near floor keeps its contrast. Without mip-mapping the far rows show the
// checker's full 0/255 swing (row std ~60-110).
TEST(Renderer, GrazingFloorIsPrefiltered) {
  World w;
  cv::Mat checker(256, 256, CV_8UC3);
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      checker.at<cv::Vec3b>(y, x) =
          ((x / 4 + y / 4) % 2) ? cv::Vec3b(255, 255, 255) : cv::Vec3b(0, 0, 0);
    }
  }
  w.textures.push_back(checker);
  // 1 m per texture width: 4 mm texels, 1.6 cm squares.
  const Surface floor = quad({-5, -50, 0}, {100, -50, 0}, {100, 50, 0}, {-5, 50, 0}, 0.5f, 0, 1.0);
  w.surfaces.push_back(floor);
  const CameraModel cam{320, 240, 277.0, 277.0, 159.5, 119.5, {}};
  Renderer r(w, cam);
  const Eigen::Isometry3d pose = levelCameraPose({0, 0, 0.3}, 0.3);
  cv::Mat img, flat;
  r.render(pose, {}, {}, false, img);
  World wf = w;
  wf.surfaces[0].texture = -1;
  wf.surfaces[0].albedo = 0.5f;
  Renderer(wf, cam).render(pose, {}, {}, false, flat);
  const double mean_flat = meanOf(flat.row(200));
  // Row y sees the floor at distance 0.3 * 277 / (y - 119.5).
  for (int y = 124; y < 240; ++y) {
    cv::Scalar mean, std;
    cv::meanStdDev(img.row(y), mean, std);
    const double distance = 0.3 * 277.0 / (y - 119.5);
    if (distance > 3.0) {
      EXPECT_LT(std[0], 8.0) << "row " << y << " at " << distance << " m aliases";
      EXPECT_NEAR(mean[0], mean_flat, 8.0) << "row " << y;
    }
    if (distance < 0.8) {
      EXPECT_GT(std[0], 50.0) << "row " << y << " lost its contrast";
    }
  }
}

// Exposure multiplies intensities and saturates at 255; per-room factors
// dim one room only.
TEST(Renderer, ExposureScalesAndSaturates) {
  std::vector<cv::Vec3b> colours;
  World w = colouredRoom(&colours);
  const CameraModel cam = simCamera();
  const Eigen::Isometry3d pose = levelCameraPose({1, 1, 0.4}, 0.6, 0.1);
  cv::Mat base, half, triple, doubled_world;
  Renderer r(w, cam);
  r.render(pose, {}, {}, false, base);
  RenderEffects fx;
  fx.exposure = 0.5;
  r.render(pose, {}, fx, false, half);
  fx.exposure = 3.0;
  r.render(pose, {}, fx, false, triple);
  w.exposure = 2.0;
  fx.exposure = 0.5;
  Renderer(w, cam).render(pose, {}, fx, false, doubled_world);

  cv::Mat base16, half16, triple16;
  base.convertTo(base16, CV_32F);
  half.convertTo(half16, CV_32F);
  triple.convertTo(triple16, CV_32F);
  EXPECT_LE(cv::norm(half16 * 2.0, base16, cv::NORM_INF), 2.5);
  cv::Mat expected_triple = cv::min(base16 * 3.0, 255.0);
  EXPECT_LE(cv::norm(triple16, expected_triple, cv::NORM_INF), 3.5);
  EXPECT_GT(cv::countNonZero(triple == 255), 1000);  // saturated
  EXPECT_EQ(cv::norm(doubled_world, base, cv::NORM_INF), 0.0);
  EXPECT_NEAR(meanOf(half), meanOf(base) / 2, 0.6);

  // Rooms: surfaces tagged with room 0 go dark at room_exposure 0.1.
  World rooms = colouredRoom(&colours);
  for (auto& s : rooms.surfaces) s.room = 0;
  Renderer rr(rooms, cam);
  RenderEffects dim;
  dim.room_exposure = {0.1};
  cv::Mat dark;
  rr.render(pose, {}, dim, false, dark);
  EXPECT_NEAR(meanOf(dark), meanOf(base) * 0.1, 1.0);
}

// Gaussian sensor noise with the requested sigma, zero mean, reproducible per
// seed, independent between seeds. (Compared between two seeds: against the
// clean image, round(x + n) - round(x) has mean x - round(x), not 0.)
TEST(Renderer, NoiseHasRequestedSigma) {
  std::vector<cv::Vec3b> colours;
  const World w = colouredRoom(&colours);
  Renderer r(w, simCamera());
  const Eigen::Isometry3d pose = levelCameraPose({2.5, 2, 1.2}, 0.3);
  cv::Mat clean;
  r.render(pose, {}, {}, false, clean);
  for (double sigma : {2.0, 6.0}) {
    std::vector<cv::Mat> n(4);
    RenderEffects fx;
    fx.noise_sigma = sigma;
    for (int k = 0; k < 4; ++k) {
      fx.noise_seed = 100 + k;
      r.render(pose, {}, fx, false, n[k]);
    }
    cv::Mat again;
    fx.noise_seed = 100;
    r.render(pose, {}, fx, false, again);
    EXPECT_EQ(cv::norm(n[0], again, cv::NORM_INF), 0.0);  // reproducible
    EXPECT_NEAR(meanOf(n[0]), meanOf(clean), 0.5);
    cv::Mat d01, d23;
    cv::subtract(n[0], n[1], d01, cv::noArray(), CV_32F);
    cv::subtract(n[2], n[3], d23, cv::noArray(), CV_32F);
    // d = difference of two noisy roundings: variance 2 sigma^2 (+ ~1/6 from rounding).
    const double sd = std::sqrt(2 * sigma * sigma + 1.0 / 6);
    cv::Scalar mean, std;
    cv::meanStdDev(d01, mean, std);
    EXPECT_NEAR(std[0], sd, 0.03 * sd) << "sigma " << sigma;
    EXPECT_NEAR(mean[0], 0.0, 0.05);
    const double corr = d01.dot(d23) / (cv::norm(d01) * cv::norm(d23));
    EXPECT_LT(std::abs(corr), 0.015);  // 4 sigmas of the sampling error
    // Gaussian shape: the tail beyond ~2 sd as for a normal (|d| > k
    // for integers means beyond k + 0.5).
    const double k = std::floor(2 * sd);
    const double beyond = cv::countNonZero(cv::abs(d01) > k + 0.5) / double(d01.total());
    EXPECT_NEAR(beyond, std::erfc((k + 0.5) / (std::sqrt(2.0) * sd)), 0.006) << "sigma " << sigma;
  }
}

// Motion blur is the average of the renders at the sample poses.
TEST(Renderer, BlurIsTheAverageOfSamplePoses) {
  const World w = World::loadFile(kSource / "config/worlds/living_room.yaml");
  Renderer r(w, simCamera());
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < 4; ++k) poses.push_back(levelCameraPose({1.5, 2, 0.3}, 0.02 * k));
  cv::Mat blurred, single, sum = cv::Mat::zeros(240, 320, CV_32F), f;
  r.renderBlurred(poses, {}, {}, false, blurred);
  for (const auto& p : poses) {
    r.render(p, {}, {}, false, single);
    single.convertTo(f, CV_32F);
    sum += f / 4.0;
  }
  cv::Mat b32;
  blurred.convertTo(b32, CV_32F);
  // Averaging happens before the distortion remap: equal up to rounding.
  EXPECT_LT(cv::norm(b32, sum, cv::NORM_L1) / sum.total(), 0.6);
  // Same poses twice: no blur.
  r.renderBlurred({poses[0], poses[0]}, {}, {}, false, blurred);
  r.render(poses[0], {}, {}, false, single);
  EXPECT_EQ(cv::norm(blurred, single, cv::NORM_INF), 0.0);
}

// Colour and gray renders agree (gray = luminance of the colour image).
TEST(Renderer, ColourMatchesGray) {
  const World w = World::loadFile(kSource / "config/worlds/living_room.yaml");
  Renderer r(w, simCamera());
  const Eigen::Isometry3d pose = levelCameraPose({1.5, 2, 0.3}, 0.2);
  cv::Mat gray, colour, conv;
  r.render(pose, {}, {}, false, gray);
  r.render(pose, {}, {}, true, colour);
  ASSERT_EQ(colour.type(), CV_8UC3);
  cv::cvtColor(colour, conv, cv::COLOR_BGR2GRAY);
  cv::Mat diff;
  cv::absdiff(gray, conv, diff);
  EXPECT_LT(meanOf(diff), 1.0);
  EXPECT_LE(cv::norm(diff, cv::NORM_INF), 3.0);
}

TEST(Renderer, PinholeCoversDistortedView) {
  const CameraModel plain{320, 240, 277, 277, 160, 120, {}};
  World w;
  w.surfaces.push_back(facingRect({3, 0, 0}, {-1, 0, 0}, 10, 10, 0.5f));
  Renderer r0(w, plain);
  EXPECT_EQ(r0.pinholeSize(), cv::Size(320, 240));
  EXPECT_EQ(r0.distortionMapError(), 0.0);
  Renderer r1(w, distortedCamera());
  // Barrel distortion: the undistorted view is wider than the image.
  EXPECT_GT(r1.pinholeSize().width, 320);
  EXPECT_GT(r1.pinholeSize().height, 240);
  EXPECT_LT(r1.distortionMapError(), 0.01);
  EXPECT_EQ(r1.distortionInvalidPixels(), 0u);
  // A model that folds over inside the image (r_d peaks at r ~ 1.05, the
  // corners need more) cannot be rendered: refused with a reason.
  const CameraModel folding{
      320, 240, 250.0, 251.0, 158.0, 121.0, {0.4, -0.3, 0.001, 0.0005, 0.05, 0.7, -0.2, 0.1}};
  EXPECT_THROW(Renderer(w, folding), std::invalid_argument);
}

// What the estimator needs: SIFT (as the front-end runs it) finds plenty of
// keypoints in 320x240 views of the apartment, from a pose in every room
// (> 200 each) and across the tour route in four headings (median > 300,
// 85% of views > 150: a few views into a close wall or furniture are thin).
TEST(ShippedWorlds, ApartmentViewsHaveSiftFeatures) {
  const World w = World::loadFile(kSource / "config/worlds/apartment.yaml");
  Renderer r(w, simCamera());
  auto sift = cv::SIFT::create();
  cv::Mat img;
  std::vector<cv::KeyPoint> kp;
  const double poses[][3] = {{1.2, 2.6, 0},    {4.25, 2.9, -90}, {7.0, 1.1, 0},  {8.0, 3.0, 90},
                             {8.0, 4.2, 180},  {8.0, 5.5, 60},   {5.0, 5.5, 90}, {2.0, 4.3, 100},
                             {3.0, 2.9, -135}, {9.0, 1.1, 135}};
  for (const auto& p : poses) {
    r.render(levelCameraPose({p[0], p[1], 0.3}, p[2] * M_PI / 180), {}, {}, false, img);
    sift->detect(img, kp);
    EXPECT_GT(kp.size(), 200u) << "view from " << p[0] << ", " << p[1] << " heading " << p[2]
                               << " in " << w.roomAt(p[0], p[1]);
  }
  ASSERT_FALSE(w.routes.empty());
  std::vector<size_t> counts;
  for (const auto& wp : w.routes[0].waypoints) {
    for (int h = 0; h < 4; ++h) {
      r.render(levelCameraPose({wp.x(), wp.y(), 0.3}, h * M_PI / 2 + 0.3), {}, {}, false, img);
      sift->detect(img, kp);
      counts.push_back(kp.size());
    }
  }
  std::sort(counts.begin(), counts.end());
  EXPECT_GT(counts[counts.size() / 2], 300u);
  EXPECT_GT(counts[counts.size() * 15 / 100], 150u);
}

// Every shipped world loads and renders non-trivial images along its routes
// (no empty pixels: the camera is always inside closed geometry); the
// textureless room is what its name says.
TEST(ShippedWorlds, EveryWorldRendersAlongItsRoutes) {
  auto sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> kp;
  for (const char* name : {"apartment.yaml", "living_room.yaml", "loop.yaml", "textureless.yaml"}) {
    const World w = World::loadFile(kSource / "config/worlds" / name);
    // Empty pixels are the ones that change with the background level.
    RendererOptions black, white;
    black.background = 0;
    white.background = 255;
    Renderer r(w, simCamera(), black), rw(w, simCamera(), white);
    cv::Mat img, img_w;
    for (const Route& route : w.routes) {
      for (const auto& wp : route.waypoints) {
        for (int h = 0; h < 4; ++h) {
          const auto pose = levelCameraPose({wp.x(), wp.y(), 0.3}, h * M_PI / 2);
          r.render(pose, {}, {}, false, img);
          rw.render(pose, {}, {}, false, img_w);
          cv::Scalar mean, sd;
          cv::meanStdDev(img, mean, sd);
          EXPECT_GT(mean[0], 40.0) << name;
          EXPECT_EQ(cv::countNonZero(img != img_w), 0) << name << " at " << wp.transpose();
          if (std::string(name) != "textureless.yaml") {
            EXPECT_GT(sd[0], 10.0) << name << " at " << wp.transpose();
          }
        }
      }
    }
    if (std::string(name) == "textureless.yaml") {
      // Facing the plain room's east wall from its middle: no landmarks to speak of.
      r.render(levelCameraPose({7.5, 2.0, 0.3}, 0.0), {}, {}, false, img);
      sift->detect(img, kp);
      EXPECT_LT(kp.size(), 15u);
      r.render(levelCameraPose({2.5, 1.5, 0.3}, M_PI), {}, {}, false, img);
      sift->detect(img, kp);
      EXPECT_GT(kp.size(), 150u);
    }
  }
}

// Round poses (half-metre grid, headings in steps of 45 degrees) make wall
// seams pass exactly through sample points; shared edges and T-junctions
// (a floor edge beside a wall split at a door) must not crack there.
TEST(ShippedWorlds, NoCracksAtRoundPoses) {
  const World w = World::loadFile(kSource / "config/worlds/apartment.yaml");
  RendererOptions black, white;
  black.background = 0;
  white.background = 255;
  const CameraModel cam{320, 240, 277.0, 277.0, 160.0, 120.0, {}};
  Renderer r(w, cam, black), rw(w, cam, white);
  cv::Mat a, b;
  int views = 0;
  for (double x = 0.5; x < 10; x += 1.0) {
    for (double y = 0.5; y < 8; y += 0.5) {
      if (!w.isFree(x, y, 0.15)) continue;
      for (int h = 0; h < 8; h += 3) {
        const auto pose = levelCameraPose({x, y, 0.3}, h * M_PI / 4);
        r.render(pose, {}, {}, false, a);
        rw.render(pose, {}, {}, false, b);
        ASSERT_EQ(cv::countNonZero(a != b), 0)
            << "crack at " << x << ", " << y << " heading " << 45 * h;
        ++views;
      }
    }
  }
  EXPECT_GT(views, 150);
}
