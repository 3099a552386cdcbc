#include "world/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "config/robot_config.hpp"
#include "world/geometry2d.hpp"

namespace vslam::world {
namespace {

// ---------------------------------------------------------------------------
// Textures: power-of-two mip pyramids, gray and BGRA, repeated (wrap-around).

constexpr int kMaxTextureSize = 1024;

int nearestPowerOfTwo(int n) {
  const int p = 1 << static_cast<int>(std::lround(std::log2(std::max(1, n))));
  return std::clamp(p, 4, kMaxTextureSize);
}

struct MipLevel {
  int mask_x = 0, mask_y = 0, shift = 0;  // width = 1 << shift
  float sx = 1, sy = 1;                   // texels of this level per level-0 texel
  const uint8_t* gray = nullptr;
  const uint8_t* bgra = nullptr;  // 4 bytes per texel
};

struct Texture {
  int w0 = 0, h0 = 0;
  double aspect = 1.0;  // original image rows / cols
  std::vector<std::vector<uint8_t>> gray_store, bgra_store;
  std::vector<MipLevel> levels;
};

// Box-filters a level by two in each dimension (a dimension of 1 stays).
template <int C>
std::vector<uint8_t> halve(const std::vector<uint8_t>& src, int w, int h, int nw, int nh) {
  std::vector<uint8_t> dst(static_cast<size_t>(nw) * nh * C);
  const int fx = w / nw, fy = h / nh;
  for (int y = 0; y < nh; ++y) {
    for (int x = 0; x < nw; ++x) {
      for (int c = 0; c < C; ++c) {
        int sum = 0;
        for (int j = 0; j < fy; ++j) {
          for (int i = 0; i < fx; ++i) {
            sum += src[(static_cast<size_t>(y * fy + j) * w + (x * fx + i)) * C + c];
          }
        }
        const int n = fx * fy;
        dst[(static_cast<size_t>(y) * nw + x) * C + c] = static_cast<uint8_t>((sum + n / 2) / n);
      }
    }
  }
  return dst;
}

Texture buildTexture(const cv::Mat& image) {
  if (image.empty() || image.type() != CV_8UC3) {
    throw std::invalid_argument("world textures must be non-empty CV_8UC3 images");
  }
  Texture t;
  t.aspect = static_cast<double>(image.rows) / image.cols;
  t.w0 = nearestPowerOfTwo(image.cols);
  t.h0 = nearestPowerOfTwo(image.rows);
  cv::Mat resized;
  const bool shrink = t.w0 <= image.cols && t.h0 <= image.rows;
  cv::resize(image, resized, cv::Size(t.w0, t.h0), 0, 0, shrink ? cv::INTER_AREA : cv::INTER_CUBIC);
  cv::Mat bgra, gray;
  cv::cvtColor(resized, bgra, cv::COLOR_BGR2BGRA);
  cv::cvtColor(resized, gray, cv::COLOR_BGR2GRAY);
  t.gray_store.emplace_back(gray.data, gray.data + gray.total());
  t.bgra_store.emplace_back(bgra.data, bgra.data + bgra.total() * 4);
  int w = t.w0, h = t.h0;
  while (w > 1 || h > 1) {
    const int nw = std::max(1, w / 2), nh = std::max(1, h / 2);
    t.gray_store.push_back(halve<1>(t.gray_store.back(), w, h, nw, nh));
    t.bgra_store.push_back(halve<4>(t.bgra_store.back(), w, h, nw, nh));
    w = nw;
    h = nh;
  }
  w = t.w0;
  h = t.h0;
  for (size_t i = 0; i < t.gray_store.size(); ++i) {
    MipLevel L;
    L.shift = static_cast<int>(std::lround(std::log2(w)));
    L.mask_x = w - 1;
    L.mask_y = h - 1;
    L.sx = static_cast<float>(w) / t.w0;
    L.sy = static_cast<float>(h) / t.h0;
    L.gray = t.gray_store[i].data();
    L.bgra = t.bgra_store[i].data();
    t.levels.push_back(L);
    w = std::max(1, w / 2);
    h = std::max(1, h / 2);
  }
  return t;
}

// log2 good to ~0.01 for positive normal floats: the mip level only sets a
// blend weight, so the approximation is invisible.
inline float fastLog2(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, 4);
  const float e = static_cast<float>(static_cast<int>(bits >> 23) - 127);
  bits = (bits & 0x007FFFFFu) | 0x3F800000u;
  float m;
  std::memcpy(&m, &bits, 4);
  return e + ((-0.34484843f * m + 2.02466578f) * m - 0.67487759f);
}

struct TexCoord {
  int x0, x1, r0, r1;  // wrapped texel columns and row offsets (texels)
  float ax, ay;
};

// floor() for |v| < 2^31 without a libm call (baseline x86-64 has no SSE4.1 round).
inline int floorInt(float v) {
  const int i = static_cast<int>(v);
  return i - (v < static_cast<float>(i));
}

inline TexCoord texCoord(const MipLevel& L, float s, float t) {
  const float x = s * L.sx - 0.5f, y = t * L.sy - 0.5f;
  const int xi = floorInt(x), yi = floorInt(y);
  TexCoord c;
  c.ax = x - static_cast<float>(xi);
  c.ay = y - static_cast<float>(yi);
  c.x0 = xi & L.mask_x;
  c.x1 = (xi + 1) & L.mask_x;
  c.r0 = (yi & L.mask_y) << L.shift;
  c.r1 = ((yi + 1) & L.mask_y) << L.shift;
  return c;
}

inline float bilinearGray(const MipLevel& L, float s, float t) {
  const TexCoord c = texCoord(L, s, t);
  const uint8_t* g = L.gray;
  const float a = g[c.r0 + c.x0], b = g[c.r0 + c.x1], d = g[c.r1 + c.x0], e = g[c.r1 + c.x1];
  const float top = a + c.ax * (b - a), bottom = d + c.ax * (e - d);
  return top + c.ay * (bottom - top);
}

struct Bgr {
  float b, g, r;
};

inline Bgr bilinearBgr(const MipLevel& L, float s, float t) {
  const TexCoord c = texCoord(L, s, t);
  const uint8_t* p00 = L.bgra + 4 * (c.r0 + c.x0);
  const uint8_t* p01 = L.bgra + 4 * (c.r0 + c.x1);
  const uint8_t* p10 = L.bgra + 4 * (c.r1 + c.x0);
  const uint8_t* p11 = L.bgra + 4 * (c.r1 + c.x1);
  float out[3];
  for (int k = 0; k < 3; ++k) {
    const float top = p00[k] + c.ax * (p01[k] - p00[k]);
    const float bottom = p10[k] + c.ax * (p11[k] - p10[k]);
    out[k] = top + c.ay * (bottom - top);
  }
  return {out[0], out[1], out[2]};
}

// ---------------------------------------------------------------------------
// Surfaces.

// A surface prepared once: plane, bounds, texture frame, lighting.
struct Prepared {
  std::array<Eigen::Vector3d, 4> corners;
  Eigen::Vector3d normal;  // facing side, unit
  double offset;           // normal . p = offset on the plane
  Eigen::Vector3d centre;
  double radius;
  Eigen::Vector3d tex_origin, tex_u, tex_v;
  double ks = 0, kt = 0;  // texels (level 0) per metre along u and v
  const Texture* texture = nullptr;
  float value = 0;  // uniform grey level (0..255) when texture is null
  float gain = 1;   // material gain x fixed lighting
  int room = -1;
};

// A view-independent "sky" light: walls facing different ways differ a little
// in brightness, floors are bright, ceilings dimmer. Fixed in the world, so
// every view of a surface agrees.
float lighting(const Eigen::Vector3d& n) {
  const double lx = 0.6, ly = 0.8;  // unit horizontal light direction
  return static_cast<float>(0.84 + 0.16 * (n.x() * lx + n.y() * ly) + 0.08 * n.z());
}

bool prepare(const Surface& s, const std::vector<Texture>& textures, Prepared* p) {
  p->corners = s.corners;
  // Newell's normal: robust for quads with a repeated corner (triangles).
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) n += s.corners[i].cross(s.corners[(i + 1) % 4]);
  if (n.norm() < 1e-12) return false;
  n.normalize();
  p->normal = n;
  p->centre = Eigen::Vector3d::Zero();
  for (const auto& c : s.corners) p->centre += 0.25 * c;
  p->offset = n.dot(p->centre);
  p->radius = 0.0;
  for (const auto& c : s.corners) p->radius = std::max(p->radius, (c - p->centre).norm());
  if (s.texture_u.squaredNorm() > 0.0) {
    p->tex_u = s.texture_u.normalized();
    p->tex_v = s.texture_v.normalized();
    p->tex_origin = s.texture_origin;
  } else {
    p->tex_u = (s.corners[1] - s.corners[0]);
    if (p->tex_u.norm() < 1e-12) return false;
    p->tex_u.normalize();
    const Eigen::Vector3d down = s.corners[0] - s.corners[3];
    p->tex_v = down - down.dot(p->tex_u) * p->tex_u;
    if (p->tex_v.norm() < 1e-12) p->tex_v = n.cross(p->tex_u);
    p->tex_v.normalize();
    p->tex_origin = s.corners[3];
  }
  p->texture = nullptr;
  if (s.texture >= 0) {
    if (static_cast<size_t>(s.texture) >= textures.size()) {
      throw std::out_of_range("surface texture index " + std::to_string(s.texture) +
                              " is not in the world's textures");
    }
    const Texture& t = textures[static_cast<size_t>(s.texture)];
    p->texture = &t;
    const double scale = std::max(1e-6, s.texture_scale_m);
    p->ks = t.w0 / scale;
    p->kt = t.h0 / (scale * t.aspect);
  }
  p->value = 255.0f * std::clamp(s.albedo, 0.0f, 1.0f);
  p->gain = s.gain * lighting(n);
  p->room = s.room;
  return true;
}

// Per frame, per visible surface: screen-space plane equations in pinhole
// pixel coordinates (x, y): D = n.r (proportional to 1/depth), s = S/D and
// t = T/D in level-0 texels (the plane-to-image homography).
struct ShadeRec {
  float sx, sy, s0, tx, ty, t0, dx, dy, d0;
  float gain;  // everything multiplied in, incl. exposure
  float value;
  const Texture* texture;
};

// ---------------------------------------------------------------------------
// Sensor noise: a table of normal quantiles indexed by a fast PRNG.

uint64_t splitmix64(uint64_t& state) {
  uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// Acklam's rational approximation of the normal quantile (rel. error 1e-9).
double normalQuantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double plow = 0.02425;
  if (p < plow) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > 1 - plow) return -normalQuantile(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

const std::vector<float>& gaussianTable() {
  static const std::vector<float> table = [] {
    std::vector<float> t(65536);
    double sum2 = 0.0;
    for (size_t i = 0; i < t.size(); ++i) {
      t[i] = static_cast<float>(normalQuantile((i + 0.5) / t.size()));
      sum2 += static_cast<double>(t[i]) * t[i];
    }
    // Quantile sampling truncates the far tails; restore unit variance.
    const float k = static_cast<float>(1.0 / std::sqrt(sum2 / t.size()));
    for (float& v : t) v *= k;
    return t;
  }();
  return table;
}

// out = saturate(round(linear * scale + N(0, sigma^2))), per channel.
void quantizeWithNoise(const cv::Mat& linear, float scale, double sigma, uint64_t seed,
                       cv::Mat& out) {
  const std::vector<float>& g = gaussianTable();
  uint64_t state = seed * 0xD1B54A32D192ED03ull + 0x2545F4914F6CDD1Dull;
  const float sg = static_cast<float>(sigma);
  const int n = linear.cols * linear.channels();
  for (int y = 0; y < linear.rows; ++y) {
    const uint16_t* in = linear.ptr<uint16_t>(y);
    uint8_t* row = out.ptr<uint8_t>(y);
    for (int x = 0; x < n; x += 4) {
      uint64_t r = splitmix64(state);
      const int m = std::min(4, n - x);
      for (int k = 0; k < m; ++k, r >>= 16) {
        const float v = in[x + k] * scale + sg * g[r & 0xFFFF];
        row[x + k] = static_cast<uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f));
      }
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------

struct Renderer::Impl {
  CameraModel camera;
  RendererOptions options;
  double world_exposure = 1.0;
  std::vector<Room> rooms;  // for dynamic surfaces' rooms
  std::vector<Texture> textures;
  std::vector<Prepared> statics;

  // Pinhole image (undistorted) and the distortion remap.
  int pw = 0, ph = 0;
  double pfx = 0, pfy = 0, pcx = 0, pcy = 0;
  bool distorted = false;
  cv::Mat map1, map2;
  double map_error = 0.0;
  size_t invalid_pixels = 0;

  // Visibility samples: factor x factor per pinhole pixel.
  int factor = 2;
  int sw = 0, sh = 0;
  std::vector<float> zbuf;
  std::vector<int32_t> ids;

  // Per-frame scratch, reused.
  std::vector<Prepared> dynamic_prepared;
  std::vector<ShadeRec> recs;
  cv::Mat pinhole;   // linear, 16-bit (see kLinearScale)
  cv::Mat remapped;  // the same after the lens remap
  cv::Mat accum;
  std::vector<Eigen::Vector3d> clip_a, clip_b;
  std::vector<Eigen::Vector2d> screen;

  // Camera-frame side planes of the sampled view (inward normals through the origin).
  std::array<Eigen::Vector3d, 4> side_planes;

  // The pinhole image, the lens remap (distorted lenses) and the sample grid.
  void setupCamera();
  // Distorted lenses: the pixels whose ray is found (sets map_error,
  // invalid_pixels), the pinhole image that holds their rays and the remap
  // from it to the lens image.
  std::vector<bool> invertiblePixels(const std::vector<cv::Point2f>& pix,
                                     const std::vector<cv::Point2f>& und,
                                     const std::vector<cv::Point2f>& back);
  void fitPinholeImage(const std::vector<cv::Point2f>& und, const std::vector<bool>& valid);
  void buildLensRemap(const std::vector<cv::Point2f>& und, const std::vector<bool>& valid);
  // The visibility samples and the view's side planes.
  void setupSampleGrid();
  void renderPinhole(const Eigen::Isometry3d& world_T_camera, const std::vector<Surface>& dynamic,
                     const RenderEffects& effects, bool color);
  void drawSurface(const Prepared& p, const Eigen::Matrix3d& R_cw, const Eigen::Vector3d& t_cw,
                   const Eigen::Vector3d& cam_pos, float frame_gain);
  template <bool kColor>
  void shade();
  void finish(const RenderEffects& effects, bool color, cv::Mat& out);
};

namespace {

// Every pixel of the image, row by row.
std::vector<cv::Point2f> pixelGrid(const CameraModel& c) {
  const size_t n = static_cast<size_t>(c.width) * c.height;
  std::vector<cv::Point2f> pix(n);
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u)
      pix[static_cast<size_t>(v) * c.width + u] = {float(u), float(v)};
  }
  return pix;
}

// The undistorted normalized ray of every pixel, and (`back`) where the lens
// model puts that ray again. Round trip: distort the undistorted rays again;
// refine where OpenCV's iteration stopped short (Gauss-Newton with a
// numerical Jacobian).
std::vector<cv::Point2f> undistortPixels(const CameraModel& c, const std::vector<cv::Point2f>& pix,
                                         std::vector<cv::Point2f>* back_out) {
  const size_t n = pix.size();
  std::vector<cv::Point2f> und;
  const cv::Matx33d K = c.cameraMatrix();
  cv::undistortPoints(pix, und, K, c.distortion, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-9));
  auto project = [&](const std::vector<cv::Point2f>& xy, std::vector<cv::Point2f>& out) {
    std::vector<cv::Point3f> rays(xy.size());
    for (size_t i = 0; i < xy.size(); ++i) rays[i] = {xy[i].x, xy[i].y, 1.0f};
    cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, c.distortion, out);
  };
  std::vector<cv::Point2f>& back = *back_out;
  std::vector<cv::Point2f> bx, by;
  for (int iter = 0; iter < 3; ++iter) {
    project(und, back);
    std::vector<cv::Point2f> ux = und, uy = und;
    const float h = 1e-4f;
    for (auto& p : ux) p.x += h;
    for (auto& p : uy) p.y += h;
    project(ux, bx);
    project(uy, by);
    for (size_t i = 0; i < n; ++i) {
      const double ex = pix[i].x - back[i].x, ey = pix[i].y - back[i].y;
      const double j00 = (bx[i].x - back[i].x) / h, j10 = (bx[i].y - back[i].y) / h;
      const double j01 = (by[i].x - back[i].x) / h, j11 = (by[i].y - back[i].y) / h;
      const double det = j00 * j11 - j01 * j10;
      if (std::abs(det) < 1e-12) continue;
      und[i].x += static_cast<float>((j11 * ex - j01 * ey) / det);
      und[i].y += static_cast<float>((-j10 * ex + j00 * ey) / det);
    }
  }
  project(und, back);
  return und;
}

}  // namespace

void Renderer::Impl::setupCamera() {
  const CameraModel& c = camera;
  if (c.width <= 0 || c.height <= 0 || c.fx <= 0 || c.fy <= 0) {
    throw std::invalid_argument("camera model needs positive size and focal lengths");
  }
  distorted =
      std::any_of(c.distortion.begin(), c.distortion.end(), [](double v) { return v != 0.0; });
  pfx = c.fx;
  pfy = c.fy;
  if (!distorted) {
    pw = c.width;
    ph = c.height;
    pcx = c.cx;
    pcy = c.cy;
  } else {
    const std::vector<cv::Point2f> pix = pixelGrid(c);
    std::vector<cv::Point2f> back;
    const std::vector<cv::Point2f> und = undistortPixels(c, pix, &back);
    const std::vector<bool> valid = invertiblePixels(pix, und, back);
    fitPinholeImage(und, valid);
    buildLensRemap(und, valid);
  }
  setupSampleGrid();
}

std::vector<bool> Renderer::Impl::invertiblePixels(const std::vector<cv::Point2f>& pix,
                                                   const std::vector<cv::Point2f>& und,
                                                   const std::vector<cv::Point2f>& back) {
  // Pixels the lens model cannot be inverted at (a polynomial that folds
  // over inside the image: no ray reaches them) stay background; a model
  // that fails on more than a sliver of the image is an error.
  constexpr double kMaxRoundTripPx = 0.05;
  constexpr double kMaxInvalidFraction = 0.005;
  const size_t n = pix.size();
  map_error = 0.0;
  std::vector<bool> valid(n);
  size_t invalid = 0;
  for (size_t i = 0; i < n; ++i) {
    const double e = cv::norm(pix[i] - back[i]);
    valid[i] = std::isfinite(e) && e < kMaxRoundTripPx && std::isfinite(und[i].x) &&
               std::isfinite(und[i].y);
    if (valid[i]) {
      map_error = std::max(map_error, e);
    } else {
      ++invalid;
    }
  }
  if (invalid > kMaxInvalidFraction * n) {
    throw std::invalid_argument(
        "camera distortion cannot be inverted over the image: " + std::to_string(invalid) + " of " +
        std::to_string(n) + " pixels have no undistorted ray (the model folds over)");
  }
  invalid_pixels = invalid;
  return valid;
}

void Renderer::Impl::fitPinholeImage(const std::vector<cv::Point2f>& und,
                                     const std::vector<bool>& valid) {
  const CameraModel& c = camera;
  // The pinhole image covers every undistorted pixel plus a bilinear margin.
  float xmin = 1e9f, xmax = -1e9f, ymin = 1e9f, ymax = -1e9f;
  for (size_t i = 0; i < und.size(); ++i) {
    if (!valid[i]) continue;
    const cv::Point2f& p = und[i];
    xmin = std::min(xmin, p.x);
    xmax = std::max(xmax, p.x);
    ymin = std::min(ymin, p.y);
    ymax = std::max(ymax, p.y);
  }
  // Keep the pinhole image at most 3x the output per side (strong fisheyes
  // get a lower pinhole resolution rather than a huge image).
  const double span_x = (xmax - xmin) * c.fx, span_y = (ymax - ymin) * c.fy;
  const double k = std::min({1.0, 3.0 * c.width / span_x, 3.0 * c.height / span_y});
  pfx = k * c.fx;
  pfy = k * c.fy;
  constexpr int kMargin = 2;
  const double x0 = std::floor(xmin * pfx) - kMargin, x1 = std::ceil(xmax * pfx) + kMargin;
  const double y0 = std::floor(ymin * pfy) - kMargin, y1 = std::ceil(ymax * pfy) + kMargin;
  pcx = -x0;
  pcy = -y0;
  pw = static_cast<int>(x1 - x0) + 1;
  ph = static_cast<int>(y1 - y0) + 1;
}

void Renderer::Impl::buildLensRemap(const std::vector<cv::Point2f>& und,
                                    const std::vector<bool>& valid) {
  const CameraModel& c = camera;
  cv::Mat mx(c.height, c.width, CV_32F), my(c.height, c.width, CV_32F);
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) {
      const size_t i = static_cast<size_t>(v) * c.width + u;
      const cv::Point2f& p = und[i];
      mx.at<float>(v, u) = valid[i] ? static_cast<float>(pfx * p.x + pcx) : -10.0f;
      my.at<float>(v, u) = valid[i] ? static_cast<float>(pfy * p.y + pcy) : -10.0f;
    }
  }
  cv::convertMaps(mx, my, map1, map2, CV_16SC2);
}

void Renderer::Impl::setupSampleGrid() {
  factor = options.antialias ? 2 : 1;
  sw = pw * factor;
  sh = ph * factor;
  zbuf.assign(static_cast<size_t>(sw) * sh, 0.0f);
  ids.assign(static_cast<size_t>(sw) * sh, -1);
  // Side planes through the borders of the sample grid (half a sample out).
  const double fxs = pfx * factor, fys = pfy * factor;
  const double off = 0.5 * (factor - 1);
  const double cxs = pcx * factor + off, cys = pcy * factor + off;
  auto ray = [&](double X, double Y) {
    return Eigen::Vector3d((X - cxs) / fxs, (Y - cys) / fys, 1.0);
  };
  const Eigen::Vector3d tl = ray(-0.5, -0.5), tr = ray(sw - 0.5, -0.5);
  const Eigen::Vector3d bl = ray(-0.5, sh - 0.5), br = ray(sw - 0.5, sh - 0.5);
  side_planes = {tl.cross(bl).normalized(), br.cross(tr).normalized(), tr.cross(tl).normalized(),
                 bl.cross(br).normalized()};
  for (auto& pl : side_planes) {
    if (pl.dot(Eigen::Vector3d(0, 0, 1)) < 0) pl = -pl;  // inward
  }
}

void Renderer::Impl::drawSurface(const Prepared& p, const Eigen::Matrix3d& R_cw,
                                 const Eigen::Vector3d& t_cw, const Eigen::Vector3d& cam_pos,
                                 float frame_gain) {
  // Back faces and surfaces seen exactly edge-on draw nothing.
  const double facing = p.normal.dot(cam_pos) - p.offset;
  if (facing <= 1e-9) return;
  const Eigen::Vector3d centre = R_cw * p.centre + t_cw;
  if (centre.z() + p.radius < options.near_m) return;
  for (const auto& pl : side_planes) {
    if (pl.dot(centre) < -p.radius) return;
  }
  // Near-plane clipping (Sutherland-Hodgman) in the camera frame.
  clip_a.clear();
  for (const auto& c : p.corners) clip_a.push_back(R_cw * c + t_cw);
  clip_b.clear();
  const double near = options.near_m;
  for (size_t i = 0; i < clip_a.size(); ++i) {
    const Eigen::Vector3d& a = clip_a[i];
    const Eigen::Vector3d& b = clip_a[(i + 1) % clip_a.size()];
    const bool ain = a.z() >= near, bin = b.z() >= near;
    if (ain) clip_b.push_back(a);
    if (ain != bin) clip_b.push_back(a + (b - a) * ((near - a.z()) / (b.z() - a.z())));
  }
  if (clip_b.size() < 3) return;

  const double F = factor, off = 0.5 * (factor - 1);
  const double fxs = pfx * F, fys = pfy * F, cxs = pcx * F + off, cys = pcy * F + off;
  screen.clear();
  double ymin = 1e300, ymax = -1e300, xmin = 1e300, xmax = -1e300;
  for (const auto& v : clip_b) {
    const Eigen::Vector2d s(fxs * v.x() / v.z() + cxs, fys * v.y() / v.z() + cys);
    screen.push_back(s);
    ymin = std::min(ymin, s.y());
    ymax = std::max(ymax, s.y());
    xmin = std::min(xmin, s.x());
    xmax = std::max(xmax, s.x());
  }
  // Coverage is conservative by kEps samples: a sample exactly on an edge
  // shared by two polygons (common with axis-aligned walls seen from round
  // poses, and at T-junctions such as a floor edge beside a wall split at a
  // door) is covered by both and the depth test decides, instead of falling
  // into a crack when the two intercepts differ in the last bit.
  constexpr double kEps = 1e-4;
  const int row0 = std::max(0, static_cast<int>(std::ceil(ymin - kEps)));
  const int row1 = std::min(sh - 1, static_cast<int>(std::floor(ymax + kEps)));
  if (row0 > row1 || xmax < -0.5 || xmin > sw - 0.5) return;

  // Plane in the camera frame, oriented so that N.p = dd > 0.
  const Eigen::Vector3d N = -(R_cw * p.normal);
  const double dd = facing;
  // Shading record (pinhole pixel coordinates).
  ShadeRec rec;
  auto screenPlane = [&](const Eigen::Vector3d& a, float* cx_, float* cy_, float* c0_) {
    *cx_ = static_cast<float>(a.x() / pfx);
    *cy_ = static_cast<float>(a.y() / pfy);
    *c0_ = static_cast<float>(a.z() - a.x() * pcx / pfx - a.y() * pcy / pfy);
  };
  screenPlane(N, &rec.dx, &rec.dy, &rec.d0);
  rec.texture = p.texture;
  rec.value = p.value;
  rec.gain = p.gain * frame_gain;
  if (p.texture) {
    const Eigen::Vector3d u = R_cw * p.tex_u, v = R_cw * p.tex_v;
    const Eigen::Vector3d o = R_cw * p.tex_origin + t_cw;
    const Eigen::Vector3d as = p.ks * (dd * u - o.dot(u) * N);
    const Eigen::Vector3d at = p.kt * (dd * v - o.dot(v) * N);
    screenPlane(as, &rec.sx, &rec.sy, &rec.s0);
    screenPlane(at, &rec.tx, &rec.ty, &rec.t0);
  } else {
    rec.sx = rec.sy = rec.s0 = rec.tx = rec.ty = rec.t0 = 0.0f;
  }
  const int32_t id = static_cast<int32_t>(recs.size());
  recs.push_back(rec);

  // Inverse depth at sample (X, Y): D(x, y) / dd with x = (X - off) / F.
  const double zx = N.x() / pfx / F / dd, zy = N.y() / pfy / F / dd;
  const double z0 =
      (N.z() - N.x() * pcx / pfx - N.y() * pcy / pfy - (N.x() / pfx + N.y() / pfy) * off / F) / dd;

  const size_t nv = screen.size();
  for (int row = row0; row <= row1; ++row) {
    const double Y = row;
    double xl = 1e300, xr = -1e300;
    for (size_t i = 0; i < nv; ++i) {
      const Eigen::Vector2d* a = &screen[i];
      const Eigen::Vector2d* b = &screen[(i + 1) % nv];
      if (a->y() == b->y()) continue;
      if (a->y() > b->y()) std::swap(a, b);  // same arithmetic for a shared edge either way
      if (Y < a->y() - kEps || Y > b->y() + kEps) continue;
      const double x = a->x() + (Y - a->y()) * (b->x() - a->x()) / (b->y() - a->y());
      xl = std::min(xl, x);
      xr = std::max(xr, x);
    }
    if (xl > xr) continue;
    const int c0 = std::max(0, static_cast<int>(std::ceil(std::max(xl, -2.0) - kEps)));
    const int c1 = std::min(sw - 1, static_cast<int>(std::floor(std::min(xr, sw + 2.0) + kEps)));
    if (c0 > c1) continue;
    float* zr = zbuf.data() + static_cast<size_t>(row) * sw;
    int32_t* ir = ids.data() + static_cast<size_t>(row) * sw;
    const float zrow = static_cast<float>(z0 + zy * Y);
    const float zdx = static_cast<float>(zx);
    for (int col = c0; col <= c1; ++col) {
      const float z = zrow + zdx * col;
      if (z > zr[col]) {
        zr[col] = z;
        ir[col] = id;
      }
    }
  }
}

namespace {

// Shades one surface at pinhole pixel (x, y): perspective-correct texture
// coordinates from the homography, mip level from the pixel footprint
// (isotropic: the longer axis), trilinear filtering.
template <bool kColor>
inline void shadeAt(const ShadeRec& r, float x, float y, float* out) {
  if (!r.texture) {
    const float v = r.value * r.gain;
    out[0] = v;
    if (kColor) out[1] = out[2] = v;
    return;
  }
  const float D = std::max(r.dx * x + r.dy * y + r.d0, 1e-9f);
  const float inv = 1.0f / D;
  constexpr float kLimit = 1e9f;
  const float s = std::clamp((r.sx * x + r.sy * y + r.s0) * inv, -kLimit, kLimit);
  const float t = std::clamp((r.tx * x + r.ty * y + r.t0) * inv, -kLimit, kLimit);
  const float dsdx = (r.sx - s * r.dx) * inv, dsdy = (r.sy - s * r.dy) * inv;
  const float dtdx = (r.tx - t * r.dx) * inv, dtdy = (r.ty - t * r.dy) * inv;
  const float rho2 = std::max(dsdx * dsdx + dtdx * dtdx, dsdy * dsdy + dtdy * dtdy) + 1e-20f;
  const Texture& tex = *r.texture;
  const int nlev = static_cast<int>(tex.levels.size());
  float lod = 0.5f * fastLog2(rho2);
  lod = std::clamp(lod, 0.0f, static_cast<float>(nlev - 1));
  const int l0 = static_cast<int>(lod);
  const float f = lod - static_cast<float>(l0);
  if (!kColor) {
    float v = bilinearGray(tex.levels[static_cast<size_t>(l0)], s, t);
    if (f > 1.0f / 64 && l0 + 1 < nlev) {
      const float v1 = bilinearGray(tex.levels[static_cast<size_t>(l0 + 1)], s, t);
      v += f * (v1 - v);
    }
    out[0] = v * r.gain;
  } else {
    Bgr v = bilinearBgr(tex.levels[static_cast<size_t>(l0)], s, t);
    if (f > 1.0f / 64 && l0 + 1 < nlev) {
      const Bgr v1 = bilinearBgr(tex.levels[static_cast<size_t>(l0 + 1)], s, t);
      v.b += f * (v1.b - v.b);
      v.g += f * (v1.g - v.g);
      v.r += f * (v1.r - v.r);
    }
    out[0] = v.b * r.gain;
    out[1] = v.g * r.gain;
    out[2] = v.r * r.gain;
  }
}

// The pinhole image holds linear grey levels x kLinearScale in 16 bits, before
// the global exposure: exposure, saturation and noise are applied after the
// lens remap, as in a sensor (saturating first would make the remap blend
// clipped values).
constexpr float kLinearScale = 16.0f;
inline uint16_t toLinear(float v) {
  return static_cast<uint16_t>(std::clamp(v * kLinearScale + 0.5f, 0.0f, 65535.0f));
}

}  // namespace

template <bool kColor>
void Renderer::Impl::shade() {
  constexpr int C = kColor ? 3 : 1;
  const float bg = options.background;
  for (int y = 0; y < ph; ++y) {
    uint16_t* row = pinhole.ptr<uint16_t>(y);
    const float fy = static_cast<float>(y);
    if (factor == 1) {
      const int32_t* ir = ids.data() + static_cast<size_t>(y) * sw;
      for (int x = 0; x < pw; ++x) {
        float v[3] = {bg, bg, bg};
        if (ir[x] >= 0) shadeAt<kColor>(recs[static_cast<size_t>(ir[x])], float(x), fy, v);
        for (int k = 0; k < C; ++k) row[x * C + k] = toLinear(v[k]);
      }
      continue;
    }
    const int32_t* i0 = ids.data() + static_cast<size_t>(2 * y) * sw;
    const int32_t* i1 = i0 + sw;
    for (int x = 0; x < pw; ++x) {
      const int32_t a = i0[2 * x], b = i0[2 * x + 1], c = i1[2 * x], d = i1[2 * x + 1];
      float v[3] = {bg, bg, bg};
      if (a == b && a == c && a == d) {
        if (a >= 0) shadeAt<kColor>(recs[static_cast<size_t>(a)], float(x), fy, v);
      } else {
        // Edge pixel: shade each distinct surface once, weight by its samples.
        const int32_t s[4] = {a, b, c, d};
        float acc[3] = {0, 0, 0};
        bool done[4] = {false, false, false, false};
        for (int i = 0; i < 4; ++i) {
          if (done[i]) continue;
          int count = 0;
          for (int j = i; j < 4; ++j) {
            if (s[j] == s[i]) done[j] = true, ++count;
          }
          float w[3] = {bg, bg, bg};
          if (s[i] >= 0) shadeAt<kColor>(recs[static_cast<size_t>(s[i])], float(x), fy, w);
          for (int k = 0; k < C; ++k) acc[k] += 0.25f * static_cast<float>(count) * w[k];
        }
        for (int k = 0; k < C; ++k) v[k] = acc[k];
      }
      for (int k = 0; k < C; ++k) row[x * C + k] = toLinear(v[k]);
    }
  }
}

void Renderer::Impl::renderPinhole(const Eigen::Isometry3d& world_T_camera,
                                   const std::vector<Surface>& dynamic,
                                   const RenderEffects& effects, bool color) {
  const Eigen::Matrix3d R_cw = world_T_camera.linear().transpose();
  const Eigen::Vector3d cam_pos = world_T_camera.translation();
  const Eigen::Vector3d t_cw = -R_cw * cam_pos;
  std::fill(zbuf.begin(), zbuf.end(), 0.0f);
  std::fill(ids.begin(), ids.end(), -1);
  recs.clear();
  // Global exposure is applied in finish(); rooms dim here.
  const float base_gain = 1.0f;
  auto gainFor = [&](int room) {
    if (room < 0 || static_cast<size_t>(room) >= effects.room_exposure.size()) return base_gain;
    return base_gain * static_cast<float>(effects.room_exposure[static_cast<size_t>(room)]);
  };
  for (const Prepared& p : statics) drawSurface(p, R_cw, t_cw, cam_pos, gainFor(p.room));
  dynamic_prepared.resize(dynamic.size());
  for (size_t i = 0; i < dynamic.size(); ++i) {
    Prepared& p = dynamic_prepared[i];
    if (!prepare(dynamic[i], textures, &p)) continue;
    int room = p.room;
    if (room < 0 && !effects.room_exposure.empty()) {
      for (size_t r = 0; r < rooms.size() && room < 0; ++r) {
        if (geo::contains(rooms[r].polygon, p.centre.head<2>())) room = static_cast<int>(r);
      }
    }
    drawSurface(p, R_cw, t_cw, cam_pos, gainFor(room));
  }
  pinhole.create(ph, pw, color ? CV_16UC3 : CV_16UC1);
  if (color) {
    shade<true>();
  } else {
    shade<false>();
  }
}

void Renderer::Impl::finish(const RenderEffects& effects, bool color, cv::Mat& out) {
  const cv::Mat* linear = &pinhole;
  if (distorted) {
    remapped.create(camera.height, camera.width, pinhole.type());
    cv::remap(pinhole, remapped, map1, map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar::all(options.background * kLinearScale));
    linear = &remapped;
  }
  out.create(camera.height, camera.width, color ? CV_8UC3 : CV_8UC1);
  const double scale = world_exposure * effects.exposure / kLinearScale;
  if (effects.noise_sigma <= 0.0) {
    linear->convertTo(out, out.type(), scale);  // rounds and saturates
  } else {
    quantizeWithNoise(*linear, static_cast<float>(scale), effects.noise_sigma, effects.noise_seed,
                      out);
  }
}

Renderer::Renderer(const World& world, const CameraModel& camera, const RendererOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.camera = camera;
  m.options = options;
  m.world_exposure = world.exposure;
  m.rooms = world.rooms;
  m.textures.reserve(world.textures.size());
  for (const cv::Mat& t : world.textures) m.textures.push_back(buildTexture(t));
  m.statics.reserve(world.surfaces.size());
  for (const Surface& s : world.surfaces) {
    Prepared p;
    if (prepare(s, m.textures, &p)) m.statics.push_back(p);
  }
  m.setupCamera();
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

void Renderer::render(const Eigen::Isometry3d& world_T_camera, const std::vector<Surface>& dynamic,
                      const RenderEffects& effects, bool color, cv::Mat& out) {
  impl_->renderPinhole(world_T_camera, dynamic, effects, color);
  impl_->finish(effects, color, out);
}

void Renderer::renderBlurred(const std::vector<Eigen::Isometry3d>& world_T_camera_samples,
                             const std::vector<Surface>& dynamic, const RenderEffects& effects,
                             bool color, cv::Mat& out) {
  Impl& m = *impl_;
  if (world_T_camera_samples.empty()) {
    throw std::invalid_argument("renderBlurred needs at least one pose");
  }
  if (world_T_camera_samples.size() == 1) {
    render(world_T_camera_samples.front(), dynamic, effects, color, out);
    return;
  }
  const int type = color ? CV_32SC3 : CV_32SC1;
  m.accum.create(m.ph, m.pw, type);
  m.accum.setTo(0);
  for (const auto& pose : world_T_camera_samples) {
    m.renderPinhole(pose, dynamic, effects, color);
    cv::add(m.accum, m.pinhole, m.accum, cv::noArray(), type);
  }
  const double n = static_cast<double>(world_T_camera_samples.size());
  m.accum.convertTo(m.pinhole, color ? CV_16UC3 : CV_16UC1, 1.0 / n);
  m.finish(effects, color, out);
}

const CameraModel& Renderer::camera() const { return impl_->camera; }
cv::Size Renderer::pinholeSize() const { return {impl_->pw, impl_->ph}; }
cv::Matx33d Renderer::pinholeMatrix() const {
  return {impl_->pfx, 0, impl_->pcx, 0, impl_->pfy, impl_->pcy, 0, 0, 1};
}
double Renderer::distortionMapError() const { return impl_->map_error; }
size_t Renderer::distortionInvalidPixels() const { return impl_->invalid_pixels; }

CameraModel CameraModel::fromCalibrationFile(const std::string& file) {
  const config::CameraIntrinsics k = config::readOpenCvCalibration(file);
  return CameraModel{k.width, k.height, k.fx, k.fy, k.cx, k.cy, k.distortion};
}

}  // namespace vslam::world
