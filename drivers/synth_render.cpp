#include "drivers/synth_render.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#if defined(__SSE2__)
#include <emmintrin.h>
#elif defined(__ARM_NEON)
#include <arm_neon.h>
#endif

namespace rdslam {

namespace synth_render_detail {

// A texture level: 4 bytes per texel (B, G, R and an unused fourth byte), so that one
// texel is one 32-bit load and its three channels are filtered as one 4-lane vector. (Not in
// the anonymous namespace: SynthRenderer::Texture holds it, and GCC rejects a member of an
// anonymous-namespace type in a class with linkage when this file is part of a unity build.)
struct TexLevel {
  const uint8_t* data = nullptr;
  int w = 0, h = 0;
  size_t step = 0;
};

}  // namespace synth_render_detail

using synth_render_detail::TexLevel;

namespace {

constexpr float kEdgeEps = 1e-5f;  // closes rounding gaps between quads sharing an edge
// Lens bounding boxes: samples per outline edge, and the margin (px) for the curve between.
constexpr int kLensEdgeSamples = 32;
constexpr double kLensBoxMarginPx = 2.0;

// Four floats, one per texel byte (B, G, R, unused). GCC vector extensions: +, -, * are
// lane-wise IEEE single-precision operations, so a lane computes exactly what the scalar
// code `w00 * p00[c] + w01 * p01[c] + ...` computes for channel c (same operations, same
// order; no FMA on baseline x86-64). Frames stay byte-identical to the scalar renderer.
typedef float Vec4 __attribute__((vector_size(16)));
typedef int32_t Vec4i __attribute__((vector_size(16)));

inline Vec4 load_texel(const uint8_t* p) {
#if defined(__SSE2__)
  int32_t bits;
  std::memcpy(&bits, p, 4);
  const __m128i zero = _mm_setzero_si128();
  const __m128i b = _mm_cvtsi32_si128(bits);
  return Vec4(_mm_cvtepi32_ps(_mm_unpacklo_epi16(_mm_unpacklo_epi8(b, zero), zero)));
#elif defined(__ARM_NEON)
  uint32_t bits;
  std::memcpy(&bits, p, 4);
  const uint16x8_t h = vmovl_u8(vcreate_u8(bits));
  return Vec4(vcvtq_f32_u32(vmovl_u16(vget_low_u16(h))));
#else
  return Vec4{static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2]),
              static_cast<float>(p[3])};
#endif
}

// Bilinear sample with repeat wrap; (u, v) in [0, 1) (the caller wraps repeats away).
// Integer truncation of values > -1 replaces floor() and modulo, which cost a libm call and
// integer divisions per texel on baseline x86-64 and ARMv8 builds.
inline Vec4 bilinear(const TexLevel& L, float u, float v) {
  u = u * static_cast<float>(L.w) - 0.5f;  // in [-0.5, w - 0.5)
  v = v * static_cast<float>(L.h) - 0.5f;
  const int xi = static_cast<int>(u + 1.0f) - 1;  // floor(u) for u > -1
  const int yi = static_cast<int>(v + 1.0f) - 1;
  const float ax = u - static_cast<float>(xi), ay = v - static_cast<float>(yi);
  const int x0 = xi < 0 ? L.w - 1 : (xi >= L.w ? L.w - 1 : xi);
  const int y0 = yi < 0 ? L.h - 1 : (yi >= L.h ? L.h - 1 : yi);
  const int x1 = x0 + 1 >= L.w ? 0 : x0 + 1;
  const int y1 = y0 + 1 >= L.h ? 0 : y0 + 1;
  const uint8_t* r0 = L.data + y0 * L.step;
  const uint8_t* r1 = L.data + y1 * L.step;
  const float w00 = (1 - ax) * (1 - ay), w01 = ax * (1 - ay), w10 = (1 - ax) * ay, w11 = ax * ay;
  return load_texel(r0 + 4 * x0) * w00 + load_texel(r0 + 4 * x1) * w01 +
         load_texel(r1 + 4 * x0) * w10 + load_texel(r1 + 4 * x1) * w11;
}

inline float smooth01(float x) {
  x = std::min(1.0f, std::max(0.0f, x));
  return x * x * (3.0f - 2.0f * x);
}

}  // namespace

struct SynthRenderer::Texture {
  std::vector<cv::Mat> mats;
  std::vector<TexLevel> levels;
};

// Per-quad, per-frame constants in the camera frame (floats: the inner loops are float).
struct SynthRenderer::QuadSetup {
  // n . d = A x + B y + C with d = K^-1 (x, y, 1); z = dn / (n . d).
  float A, B, C, dn;
  // s = z * (As x + Bs y + Cs) - s0, t likewise.
  float As, Bs, Cs, s0, At, Bt, Ct, t0;
  float n2;  // |n|^2, for the viewing-angle term of the mip level
  float uv0x, uv0y, uvsx, uvsy;
  float lod_bias;
  float shade;
  Eigen::Vector3f n_cam;  // unit normal of the visible side, camera frame
  const Texture* tex;
  uint16_t id;
  uint8_t dynamic;
  int xmin, xmax, ymin, ymax;
};

SynthRenderer::SynthRenderer(const SynthScene& scene) : scene_(scene) {
  const CameraModel& cam = scene.camera;
  textures_.resize(scene.textures.size());
  for (size_t i = 0; i < scene.textures.size(); ++i) {
    const SynthTextureSpec& spec = scene.textures[i];
    cv::Mat img = cv::imread(spec.path, cv::IMREAD_COLOR);
    if (img.empty()) throw std::runtime_error("synth: cannot read texture " + spec.path);
    if (spec.blur_px > 0) cv::GaussianBlur(img, img, cv::Size(), spec.blur_px);
    if (spec.contrast != 1.0) {
      const cv::Scalar mean = cv::mean(img);
      cv::Mat f;
      img.convertTo(f, CV_32FC3);
      f = (f - mean) * spec.contrast + mean;
      f.convertTo(img, CV_8UC3);
    }
    Texture& t = textures_[i];
    t.mats.push_back(img);
    while (t.mats.back().cols > 4 && t.mats.back().rows > 4) {
      cv::Mat down;
      cv::pyrDown(t.mats.back(), down);
      t.mats.push_back(down);
    }
    // render.full_mip_chain: down to one texel (the photo's mean), so that a surface far away
    // (a street's end, a long wall at a grazing angle) fades to its mean colour instead of
    // sampling the last level sparsely and aliasing. Area averaging: pyrDown's 5-tap kernel
    // wants larger images. Off by default: the room scenarios have a few grazing pixels per
    // frame beyond the last level above, and they must keep rendering byte for byte.
    while (scene.render.full_mip_chain && (t.mats.back().cols > 1 || t.mats.back().rows > 1)) {
      cv::Mat down;
      cv::resize(t.mats.back(), down,
                 cv::Size(std::max(1, t.mats.back().cols / 2), std::max(1, t.mats.back().rows / 2)),
                 0, 0, cv::INTER_AREA);
      t.mats.push_back(down);
    }
    for (cv::Mat& m : t.mats) {
      cv::Mat bgrx;
      cv::cvtColor(m, bgrx, cv::COLOR_BGR2BGRA);  // the fourth byte is never shown
      m = bgrx;
      t.levels.push_back({m.data, m.cols, m.rows, m.step[0]});
    }
  }
  size_t nq = 0;
  for (const auto& o : scene.objects) nq += o.quads.size();
  quads_.resize(nq);
  const int W = cam.width, H = cam.height;
  zbuf_.resize(static_cast<size_t>(W) * H);
  qbuf_.resize(static_cast<size_t>(W) * H);
  ray_x_.resize(W);
  ray_y_.resize(H);
  for (int x = 0; x < W; ++x) ray_x_[x] = static_cast<float>((x - cam.cx) / cam.fx);
  for (int y = 0; y < H; ++y) ray_y_[y] = static_cast<float>((y - cam.cy) / cam.fy);
  lens_ = cam.has_distortion();
  if (lens_) build_lens();
  // Sensor noise: one table of Gaussian samples, read at a per-frame offset (deterministic
  // by seed and frame, and free of per-pixel random number generation).
  if (scene.render.noise_sigma > 0) {
    std::mt19937_64 rng(scene.seed * 2654435761ULL + 99);
    std::normal_distribution<double> g(0.0, scene.render.noise_sigma);
    noise_.resize(static_cast<size_t>(W) * H * 3 + 65536);
    for (auto& v : noise_) v = static_cast<int8_t>(std::clamp(std::lround(g(rng)), -127L, 127L));
  }
}

SynthRenderer::~SynthRenderer() = default;

void SynthRenderer::build_lens() {
  const CameraModel& cam = scene_.camera;
  const int W = cam.width, H = cam.height;
  lens_ray_.resize(static_cast<size_t>(W) * H * 2);
  lens_lod_.resize(static_cast<size_t>(W) * H);
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x) {
      Eigen::Vector2d ideal;
      const double det = cam.undistort(Eigen::Vector2d(x, y), &ideal)
                             ? cam.distort_jacobian(ideal).determinant()
                             : 0.0;
      if (!(det > 0)) {
        throw std::runtime_error("synth: camera pixel (" + std::to_string(x) + ", " +
                                 std::to_string(y) +
                                 ") has no ray in front of the lens (field of view of 180 "
                                 "degrees or more, or a distortion that folds over)");
      }
      const size_t i = static_cast<size_t>(y) * W + x;
      const double rx = (ideal.x() - cam.cx) / cam.fx, ry = (ideal.y() - cam.cy) / cam.fy;
      lens_ray_[2 * i] = static_cast<float>(rx);
      lens_ray_[2 * i + 1] = static_cast<float>(ry);
      // A raw pixel covers 1/det ideal pixels: half its log2 on the mip level.
      lens_lod_[i] = static_cast<float>(-0.5 * std::log2(det));
      x0 = std::min(x0, rx);
      x1 = std::max(x1, rx);
      y0 = std::min(y0, ry);
      y1 = std::max(y1, ry);
    }
  }
  // A little beyond the border pixels' rays: nothing outside can reach a pixel centre.
  const double mx = 0.02 * (x1 - x0), my = 0.02 * (y1 - y0);
  lens_box_[0] = x0 - mx;
  lens_box_[1] = y0 - my;
  lens_box_[2] = x1 + mx;
  lens_box_[3] = y1 + my;
}

bool SynthRenderer::lens_bounds(const Eigen::Vector3d* poly, int np, int* xmin, int* xmax,
                                int* ymin, int* ymax) const {
  const CameraModel& cam = scene_.camera;
  // The outline at unit depth (convex: near-clipped before), clipped to the rays' box
  // (Sutherland-Hodgman, one box side at a time).
  Eigen::Vector2d a[16], b[16];
  int n = np;
  for (int i = 0; i < np; ++i) a[i] = Eigen::Vector2d(poly[i].x(), poly[i].y()) / poly[i].z();
  for (int side = 0; side < 4 && n >= 3; ++side) {
    const int axis = side % 2;
    const double lim = lens_box_[side];
    const double sign = side < 2 ? 1.0 : -1.0;  // keep sign * (p - lim) >= 0
    int m = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d& p = a[i];
      const Eigen::Vector2d& q = a[(i + 1) % n];
      const double dp = sign * (p[axis] - lim), dq = sign * (q[axis] - lim);
      if (dp >= 0) b[m++] = p;
      if ((dp >= 0) != (dq >= 0)) b[m++] = p + (q - p) * (dp / (dp - dq));
    }
    n = m;
    for (int i = 0; i < n; ++i) a[i] = b[i];
  }
  if (n < 3) return false;
  double umin = 1e30, umax = -1e30, vmin = 1e30, vmax = -1e30;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d d = a[(i + 1) % n] - a[i];
    for (int k = 0; k < kLensEdgeSamples; ++k) {
      const Eigen::Vector2d q = a[i] + d * (static_cast<double>(k) / kLensEdgeSamples);
      const Eigen::Vector2d px =
          cam.distort(Eigen::Vector2d(cam.fx * q.x() + cam.cx, cam.fy * q.y() + cam.cy));
      umin = std::min(umin, px.x());
      umax = std::max(umax, px.x());
      vmin = std::min(vmin, px.y());
      vmax = std::max(vmax, px.y());
    }
  }
  *xmin = std::max(0, static_cast<int>(std::floor(umin - kLensBoxMarginPx)));
  *xmax = std::min(cam.width - 1, static_cast<int>(std::ceil(umax + kLensBoxMarginPx)));
  *ymin = std::max(0, static_cast<int>(std::floor(vmin - kLensBoxMarginPx)));
  *ymax = std::min(cam.height - 1, static_cast<int>(std::ceil(vmax + kLensBoxMarginPx)));
  return *xmin <= *xmax && *ymin <= *ymax;
}

void SynthRenderer::setup(double frame, int index) {
  const CameraModel& cam = scene_.camera;
  const float fx = static_cast<float>(cam.fx), fy = static_cast<float>(cam.fy);
  const float cx = static_cast<float>(cam.cx), cy = static_cast<float>(cam.cy);
  const double near_m = scene_.render.near_m;
  const Eigen::Isometry3d T_cam_world = scene_.camera_pose(frame).inverse();
  const Eigen::Vector3d sun = Eigen::Vector3d(0.35, -0.55, 0.75).normalized();
  n_quads_ = 0;
  for (const auto& o : scene_.objects) {
    if (!scene_.object_visible(o.id, index)) continue;
    const Eigen::Isometry3d T_world_obj = scene_.object_pose(o.id, frame);
    const Eigen::Isometry3d T_cam_obj = T_cam_world * T_world_obj;
    const bool dynamic = scene_.object_dynamic(o.id, index);
    for (const auto& q : o.quads) {
      const Eigen::Vector3d P0 = T_cam_obj * q.p0;
      const Eigen::Vector3d U = T_cam_obj.linear() * q.u;
      const Eigen::Vector3d V = T_cam_obj.linear() * q.v;
      Eigen::Vector3d n = V.cross(U);  // visible side
      double dn = n.dot(P0);
      if (dn >= 0) {  // the camera sees the back
        if (!q.two_sided) continue;
        n = -n;
        dn = -dn;
      }
      // Clip the quad against the near plane (Sutherland-Hodgman) to bound it on screen.
      Eigen::Vector3d poly_in[4] = {P0, P0 + U, P0 + U + V, P0 + V};
      Eigen::Vector3d poly[8];
      int np = 0;
      for (int i = 0; i < 4; ++i) {
        const Eigen::Vector3d& a = poly_in[i];
        const Eigen::Vector3d& b = poly_in[(i + 1) % 4];
        const bool ain = a.z() >= near_m, bin = b.z() >= near_m;
        if (ain) poly[np++] = a;
        if (ain != bin) poly[np++] = a + (b - a) * ((near_m - a.z()) / (b.z() - a.z()));
      }
      if (np < 3) continue;
      QuadSetup& s = quads_[n_quads_];
      if (lens_) {
        if (!lens_bounds(poly, np, &s.xmin, &s.xmax, &s.ymin, &s.ymax)) continue;
      } else {
        double umin = 1e30, umax = -1e30, vmin = 1e30, vmax = -1e30;
        for (int i = 0; i < np; ++i) {
          const double u = cam.fx * poly[i].x() / poly[i].z() + cam.cx;
          const double v = cam.fy * poly[i].y() / poly[i].z() + cam.cy;
          umin = std::min(umin, u);
          umax = std::max(umax, u);
          vmin = std::min(vmin, v);
          vmax = std::max(vmax, v);
        }
        s.xmin = std::max(0, static_cast<int>(std::floor(std::max(umin, -1e6))));
        s.xmax = std::min(cam.width - 1, static_cast<int>(std::ceil(std::min(umax, 1e6))));
        s.ymin = std::max(0, static_cast<int>(std::floor(std::max(vmin, -1e6))));
        s.ymax = std::min(cam.height - 1, static_cast<int>(std::ceil(std::min(vmax, 1e6))));
      }
      if (s.xmin > s.xmax || s.ymin > s.ymax) continue;
      // Dual vectors: (X - P0) . as = s and . at = t for X on the plane.
      const Eigen::Vector3d as = V.cross(n) / U.dot(V.cross(n));
      const Eigen::Vector3d at = n.cross(U) / V.dot(n.cross(U));
      // Plane terms as affine functions of the pixel (pinhole) or of the pixel's ideal ray
      // (x, y, 1) (lens).
      auto affine = [&](const Eigen::Vector3d& a, float* A, float* B, float* C) {
        if (lens_) {
          *A = static_cast<float>(a.x());
          *B = static_cast<float>(a.y());
          *C = static_cast<float>(a.z());
          return;
        }
        *A = static_cast<float>(a.x()) / fx;
        *B = static_cast<float>(a.y()) / fy;
        *C = static_cast<float>(a.z() - a.x() * cam.cx / cam.fx - a.y() * cam.cy / cam.fy);
      };
      (void)cx;
      (void)cy;
      affine(n, &s.A, &s.B, &s.C);
      s.dn = static_cast<float>(dn);
      affine(as, &s.As, &s.Bs, &s.Cs);
      s.s0 = static_cast<float>(as.dot(P0));
      affine(at, &s.At, &s.Bt, &s.Ct);
      s.t0 = static_cast<float>(at.dot(P0));
      s.n2 = static_cast<float>(n.squaredNorm());
      const Texture& tex = textures_[q.texture];
      s.tex = &tex;
      s.uv0x = static_cast<float>(q.uv0.x());
      s.uv0y = static_cast<float>(q.uv0.y());
      s.uvsx = static_cast<float>(q.uv_scale.x());
      s.uvsy = static_cast<float>(q.uv_scale.y());
      // Texels per metre on the surface vs pixels per metre at unit depth: the mip level is
      // log2(z * tpm / f) plus a viewing-angle term computed per pixel.
      const double tpm = std::max(tex.levels[0].w * q.uv_scale.x() / q.u.norm(),
                                  tex.levels[0].h * q.uv_scale.y() / q.v.norm());
      s.lod_bias = static_cast<float>(std::log2(tpm / std::sqrt(cam.fx * cam.fy)));
      const Eigen::Vector3d n_world = (T_cam_world.linear().transpose() * n).normalized();
      s.shade =
          static_cast<float>(q.albedo * (scene_.render.ambient +
                                         scene_.render.diffuse * std::max(0.0, n_world.dot(sun))));
      s.n_cam = n.normalized().cast<float>();
      s.id = static_cast<uint16_t>(o.id);
      s.dynamic = dynamic ? 255 : 0;
      ++n_quads_;
    }
  }
}

void SynthRenderer::rasterize() {
  if (lens_) {
    rasterize_rays<true>();
  } else {
    rasterize_rays<false>();
  }
}

// kLens: the plane terms are affine in the pixel's ideal ray (lens_ray_), else in the pixel.
template <bool kLens>
void SynthRenderer::rasterize_rays() {
  const int W = scene_.camera.width;
  std::fill(zbuf_.begin(), zbuf_.end(), std::numeric_limits<float>::infinity());
  std::fill(qbuf_.begin(), qbuf_.end(), -1);
  const float near_m = static_cast<float>(scene_.render.near_m);
  for (int qi = 0; qi < n_quads_; ++qi) {
    const QuadSetup& s = quads_[qi];
    for (int y = s.ymin; y <= s.ymax; ++y) {
      [[maybe_unused]] const float fy_row = static_cast<float>(y);
      [[maybe_unused]] const float wy_row = s.B * fy_row + s.C, sy_row = s.Bs * fy_row + s.Cs,
                                   ty_row = s.Bt * fy_row + s.Ct;
      float* zrow = &zbuf_[static_cast<size_t>(y) * W];
      int32_t* qrow = &qbuf_[static_cast<size_t>(y) * W];
      [[maybe_unused]] const float* ray =
          kLens ? &lens_ray_[2 * (static_cast<size_t>(y) * W + s.xmin)] : nullptr;
      for (int x = s.xmin; x <= s.xmax; ++x) {
        float fx, wy, sy, ty;
        if constexpr (kLens) {
          fx = ray[0];
          const float fy = ray[1];
          ray += 2;
          wy = s.B * fy + s.C;
          sy = s.Bs * fy + s.Cs;
          ty = s.Bt * fy + s.Ct;
        } else {
          fx = static_cast<float>(x);
          wy = wy_row;
          sy = sy_row;
          ty = ty_row;
        }
        const float w = s.A * fx + wy;
        // dn < 0 (visible side), so a point in front of the camera has w < 0.
        if (w >= 0.0f) continue;
        const float z = s.dn / w;
        if (z < near_m || z >= zrow[x]) continue;
        const float sc = z * (s.As * fx + sy) - s.s0;
        if (sc < -kEdgeEps || sc > 1.0f + kEdgeEps) continue;
        const float tc = z * (s.At * fx + ty) - s.t0;
        if (tc < -kEdgeEps || tc > 1.0f + kEdgeEps) continue;
        zrow[x] = z;
        qrow[x] = qi;
      }
    }
  }
}

void SynthRenderer::shade(cv::Mat& image, double frame) {
  if (lens_) {
    shade_rays<true>(image, frame);
  } else {
    shade_rays<false>(image, frame);
  }
}

namespace {

// Per-pixel steps on four lanes (GCC vector extensions, lane-wise IEEE operations): a group of
// four pixels of one quad fills the lanes (pinhole or lens), a single pixel (the end of a run)
// broadcasts its values and uses lane 0. One definition for both, so a pixel gets the same bytes
// either way.
// min(1, max(0, x)) as std::min / std::max compute it (NaN -> 0).
inline Vec4 clamp01(Vec4 x) {
  x = Vec4{0.0f, 0.0f, 0.0f, 0.0f} < x ? x : Vec4{0.0f, 0.0f, 0.0f, 0.0f};  // std::max(0, x)
  return x < 1.0f ? x : Vec4{1.0f, 1.0f, 1.0f, 1.0f};                       // std::min(1, x)
}

// x - floor(x) for |x| < 2^23 without libm.
inline Vec4 wrap01(Vec4 x) {
  Vec4 f = x - __builtin_convertvector(__builtin_convertvector(x, Vec4i), Vec4);
  f = f < 0.0f ? f + 1.0f : f;
  return f >= 1.0f ? Vec4{0.0f, 0.0f, 0.0f, 0.0f} : f;
}

// log2 to ~1e-4 accuracy without libm: exponent plus a quartic in the mantissa. Only used
// to pick mip levels, where that is far below visible.
inline Vec4 fast_log2(Vec4 x) {
  Vec4i bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const Vec4 e = __builtin_convertvector(((bits >> 23) & 255) - 127, Vec4);
  bits = (bits & 0x007FFFFF) | 0x3F800000;
  Vec4 m;
  std::memcpy(&m, &bits, sizeof(m));
  return e + (-1.7417939f +
              (2.8212026f + (-1.4699568f + (0.44717955f - 0.056570851f * m) * m) * m) * m);
}

}  // namespace

template <bool kLens>
void SynthRenderer::shade_rays(cv::Mat& image, double frame) {
  const int W = scene_.camera.width, H = scene_.camera.height;
  const int index = static_cast<int>(std::lround(frame));
  const float exposure = static_cast<float>(
      scene_.exposure[std::clamp(index, 0, static_cast<int>(scene_.exposure.size()) - 1)]);
  const bool spot = scene_.light_on(index);
  Eigen::Vector3f L_cam(0, 0, 0), aim_cam(0, 0, 1);
  float cos_in = 1, cos_out = 1, intensity = 0;
  if (spot) {
    const Eigen::Isometry3d T_cam_world = scene_.camera_pose(frame).inverse();
    L_cam = (T_cam_world * scene_.light.position).cast<float>();
    aim_cam = (T_cam_world.linear() * scene_.light_aim(frame)).cast<float>();
    const double rad = 3.14159265358979323846 / 180.0;
    cos_in = static_cast<float>(std::cos(scene_.light.cone_deg * rad));
    cos_out = static_cast<float>(std::cos((scene_.light.cone_deg + scene_.light.edge_deg) * rad));
    intensity = static_cast<float>(scene_.light.intensity);
  }
  const float inv_edge = 1.0f / std::max(1e-6f, cos_in - cos_out);
  // Texture coordinates (u, v) and mip level of pixels of quad s at depth z, plane terms
  // (fx, fy) and ray at unit depth (dx, dy), one pixel per lane.
  auto tex_coords = [](const QuadSetup& s, Vec4 z, Vec4 fx, Vec4 dx, Vec4 fy, Vec4 dy, Vec4& u,
                       Vec4& v, Vec4& lod) {
    const Vec4 sc = clamp01(z * (s.As * fx + s.Bs * fy + s.Cs) - s.s0);
    const Vec4 tc = clamp01(z * (s.At * fx + s.Bt * fy + s.Ct) - s.t0);
    u = wrap01(s.uv0x + sc * s.uvsx);
    v = wrap01(s.uv0y + tc * s.uvsy);
    // Mip level: log2(z) - log2(cos(view angle)) / 2 + bias (the half keeps grazing
    // surfaces sharper than isotropic filtering would; GPU-like compromise).
    const Vec4 d2 = dx * dx + dy * dy + 1.0f;
    const Vec4 w = s.A * fx + s.B * fy + s.C;
    lod = 0.25f * fast_log2(z * z * z * z * s.n2 * d2 / (w * w)) + s.lod_bias;
  };
  // Texture lookup, lighting and output of one pixel from its texture coordinates (u, v),
  // mip level, depth and ray at unit depth (dx, dy).
  auto finish = [&](const QuadSetup& s, float u, float v, float lod, float z, float dx, float dy,
                    uint8_t* out) {
    const Texture& tex = *s.tex;
    const int nlev = static_cast<int>(tex.levels.size());
    Vec4 bgr;
    if (lod <= 0.0f) {
      bgr = bilinear(tex.levels[0], u, v);
    } else {
      int l0 = static_cast<int>(lod);
      float f = lod - static_cast<float>(l0);
      if (l0 >= nlev - 1) {
        l0 = nlev - 1;
        f = 0;
      }
      bgr = bilinear(tex.levels[l0], u, v);
      if (f > 0.0f) bgr += f * (bilinear(tex.levels[l0 + 1], u, v) - bgr);
    }
    float gain = s.shade * exposure;
    if (spot) {
      // The paper's flashlight (Fig. 1): a soft-edged cone, inverse-square falloff,
      // Lambertian on the surface.
      const Eigen::Vector3f X(z * dx, z * dy, z);
      const Eigen::Vector3f L = X - L_cam;
      const float dist2 = L.squaredNorm();
      const float inv = 1.0f / std::sqrt(dist2);
      const float cosang = L.dot(aim_cam) * inv;
      if (cosang > cos_out) {
        const float lambert = std::max(0.0f, -s.n_cam.dot(L) * inv);
        gain += exposure * intensity * smooth01((cosang - cos_out) * inv_edge) * lambert / dist2;
      }
    }
    Vec4 val = bgr * gain + 0.5f;
    val = val >= 255.0f ? Vec4{255.0f, 255.0f, 255.0f, 255.0f} : val;
    const Vec4i level = __builtin_convertvector(val, Vec4i);  // truncation, as the cast
    for (int c = 0; c < 3; ++c) out[c] = static_cast<uint8_t>(level[c]);
  };
  for (int y = 0; y < H; ++y) {
    uint8_t* out = image.ptr<uint8_t>(y);
    [[maybe_unused]] const float dy_row = ray_y_[y];
    [[maybe_unused]] const float fy_row = static_cast<float>(y);
    const int32_t* qrow = &qbuf_[static_cast<size_t>(y) * W];
    const float* zrow = &zbuf_[static_cast<size_t>(y) * W];
    for (int x = 0; x < W;) {
      const int32_t qi = qrow[x];
      if (qi < 0) {
        out[0] = out[1] = out[2] = 0;
        ++x;
        out += 3;
        continue;
      }
      const QuadSetup& s = quads_[qi];
      // Four pixels of one quad in the lanes.
      if (x + 3 < W && qrow[x + 1] == qi && qrow[x + 2] == qi && qrow[x + 3] == qi) {
        Vec4 z, fx, fy, dx, dy, u, v, lod;
        std::memcpy(&z, zrow + x, sizeof(z));
        if constexpr (kLens) {
          const float* r = &lens_ray_[2 * (static_cast<size_t>(y) * W + x)];
          fx = dx = Vec4{r[0], r[2], r[4], r[6]};
          fy = dy = Vec4{r[1], r[3], r[5], r[7]};
        } else {
          const float xf = static_cast<float>(x);
          fx = Vec4{xf, xf + 1.0f, xf + 2.0f, xf + 3.0f};
          std::memcpy(&dx, &ray_x_[x], sizeof(dx));
          fy = Vec4{fy_row, fy_row, fy_row, fy_row};
          dy = Vec4{dy_row, dy_row, dy_row, dy_row};
        }
        tex_coords(s, z, fx, dx, fy, dy, u, v, lod);
        if constexpr (kLens) {
          Vec4 lens_lod;
          std::memcpy(&lens_lod, &lens_lod_[static_cast<size_t>(y) * W + x], sizeof(lens_lod));
          lod += lens_lod;
        }
        for (int k = 0; k < 4; ++k) finish(s, u[k], v[k], lod[k], z[k], dx[k], dy[k], out + 3 * k);
        x += 4;
        out += 12;
        continue;
      }
      // One pixel, broadcast to the lanes.
      const size_t pix = static_cast<size_t>(y) * W + x;
      const float z = zrow[x];
      // (fx, fy): what the plane terms are affine in; (dx, dy): the ray at unit depth.
      float fx, fy, dx, dy;
      if constexpr (kLens) {
        fx = dx = lens_ray_[2 * pix];
        fy = dy = lens_ray_[2 * pix + 1];
      } else {
        fx = static_cast<float>(x);
        fy = fy_row;
        dx = ray_x_[x];
        dy = dy_row;
      }
      Vec4 u, v, lod;
      tex_coords(s, Vec4{z, z, z, z}, Vec4{fx, fx, fx, fx}, Vec4{dx, dx, dx, dx},
                 Vec4{fy, fy, fy, fy}, Vec4{dy, dy, dy, dy}, u, v, lod);
      float lod0 = lod[0];
      if constexpr (kLens) lod0 += lens_lod_[pix];
      finish(s, u[0], v[0], lod0, z, dx, dy, out);
      ++x;
      out += 3;
    }
  }
}

void SynthRenderer::add_noise(cv::Mat& image, int index) {
  if (noise_.empty()) return;
  uint64_t h =
      scene_.seed * 0x9E3779B97F4A7C15ULL + static_cast<uint64_t>(index) * 0xBF58476D1CE4E5B9ULL;
  h ^= h >> 31;
  h *= 0x94D049BB133111EBULL;
  h ^= h >> 29;
  const int8_t* nz = noise_.data() + (h % 65536);
  const int W = scene_.camera.width, H = scene_.camera.height;
  for (int y = 0; y < H; ++y) {
    uint8_t* p = image.ptr<uint8_t>(y);
    for (int i = 0; i < 3 * W; ++i) {
      const int v = p[i] + *nz++;
      p[i] = static_cast<uint8_t>(v < 0 ? 0 : (v > 255 ? 255 : v));
    }
  }
}

bool SynthRenderer::render(int index, SynthFrame& out) {
  if (index < 0 || index >= scene_.frame_count) return false;
  const int W = scene_.camera.width, H = scene_.camera.height;
  out.image.create(H, W, CV_8UC3);
  out.depth.create(H, W, CV_32F);
  out.ids.create(H, W, CV_16U);
  out.mask.create(H, W, CV_8U);
  out.index = index;
  out.stamp_ns = static_cast<int64_t>(std::llround(index * 1e9 / scene_.fps));
  out.T_world_cam = scene_.T_world_cam[index];
  const int nblur = scene_.render.motion_blur_samples;
  if (nblur > 1) {
    // Motion blur: average sub-frames spread over the shutter time, centred on the frame.
    blur_tmp_.create(H, W, CV_8UC3);
    blur_acc_.create(H, W, CV_32FC3);
    blur_acc_.setTo(0);
    for (int k = 0; k < nblur; ++k) {
      const double f = index + scene_.render.shutter * (static_cast<double>(k) / (nblur - 1) - 0.5);
      setup(f, index);
      rasterize();
      shade(blur_tmp_, f);
      cv::accumulate(blur_tmp_, blur_acc_);
    }
    blur_acc_.convertTo(out.image, CV_8UC3, 1.0 / nblur);
    setup(index, index);
    rasterize();
  } else {
    setup(index, index);
    rasterize();
    shade(out.image, index);
  }
  add_noise(out.image, index);
  for (int y = 0; y < H; ++y) {
    float* d = out.depth.ptr<float>(y);
    uint16_t* id = out.ids.ptr<uint16_t>(y);
    uint8_t* m = out.mask.ptr<uint8_t>(y);
    const int32_t* q = &qbuf_[static_cast<size_t>(y) * W];
    const float* z = &zbuf_[static_cast<size_t>(y) * W];
    for (int x = 0; x < W; ++x) {
      if (q[x] < 0) {
        d[x] = 0;
        id[x] = 0;
        m[x] = 0;
      } else {
        d[x] = z[x];
        id[x] = quads_[q[x]].id;
        m[x] = quads_[q[x]].dynamic;
      }
    }
  }
  return true;
}

}  // namespace rdslam
