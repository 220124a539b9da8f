// Software rasteriser for SynthScene: z-buffered, perspective-exact textured quads with
// trilinear (mip-mapped) bilinear sampling, Lambertian shading, a spot light, global
// exposure, Gaussian sensor noise and optional motion blur.
//
// Two passes per frame (deferred shading): pass 1 walks each visible quad's screen
// bounding box and keeps, per pixel, the nearest depth and the quad index; pass 2 shades
// every pixel exactly once from its quad's plane parameters. Depth is exact: for a plane
// n . X = n . p0 and the pixel ray X = z * K^-1 (x, y, 1), z = (n . p0) / (n . K^-1 (x, y, 1)),
// evaluated at pixel centres (pixel (x, y) covers [x - 0.5, x + 0.5]; OpenCV convention), so
// a world point projects with u = fx * X/Z + cx exactly where it is drawn.
//
// Lenses (camera.model pinhole-radtan with k1..p2..k3, or pinhole-equidistant): the same
// ray casting with each pixel's own ray. At start-up every pixel centre is undistorted once
// (CameraModel::undistort, Newton to 1e-9 px) into its ideal ray (x, y, 1); depth, texture
// coordinates and shading use that ray instead of K^-1 (x, y, 1), so a world point is drawn
// exactly at CameraModel::project (its distorted projection), with no resampling of a pinhole
// image. A quad's screen bounding box is the box of its outline (clipped to the image's ray
// footprint, 32 samples per edge) mapped through the lens, plus 2 px (edges curve). The mip
// level adds half the log2 of the lens's local area stretch (ideal pixels per raw pixel),
// so texture filtering follows the lens as it follows distance and viewing angle
// (isotropically, like the pinhole case). Every ray must lie less than 90 degrees off the
// optical axis (an equidistant lens: field of view below 180 degrees over the image).
//
// Ownership: the renderer owns its textures and scratch buffers (allocated once in the
// constructor); it keeps a reference to the scene, which must outlive it. Threads: one
// thread per renderer (render() mutates scratch state); several renderers may share a scene.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "drivers/synth_scene.h"

namespace rdslam {

// One rendered frame. The caller owns the buffers; render() reuses them when their size and
// type already match (no allocation per frame after the first).
struct SynthFrame {
  int index = -1;
  int64_t stamp_ns = 0;  // index / fps, from t = 0
  cv::Mat image;         // CV_8UC3 BGR
  cv::Mat depth;         // CV_32F, metres along the optical axis (z); 0 where nothing
  cv::Mat ids;           // CV_16U object id (0 nothing, 1 room, 2.. objects)
  cv::Mat mask;          // CV_8U, 255 where the pixel shows something that moves or has moved
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

class SynthRenderer {
 public:
  // Loads and mip-maps the scene's textures. Throws std::runtime_error (start-up boundary)
  // when a texture cannot be read or a pixel of the camera has no ideal ray (see above).
  explicit SynthRenderer(const SynthScene& scene);
  ~SynthRenderer();
  SynthRenderer(const SynthRenderer&) = delete;
  SynthRenderer& operator=(const SynthRenderer&) = delete;

  // Renders frame `index` (0 <= index < scene.frame_count); false when out of range.
  bool render(int index, SynthFrame& out);

 private:
  struct Texture;
  struct QuadSetup;
  void setup(double frame, int index_for_flags);
  void rasterize();
  void shade(cv::Mat& image, double frame);
  template <bool kLens>
  void rasterize_rays();
  template <bool kLens>
  void shade_rays(cv::Mat& image, double frame);
  void build_lens();
  // The lens: a quad's raw-pixel bounding box from its near-clipped outline (camera frame).
  bool lens_bounds(const Eigen::Vector3d* poly, int np, int* xmin, int* xmax, int* ymin,
                   int* ymax) const;
  void add_noise(cv::Mat& image, int index);

  const SynthScene& scene_;
  std::vector<Texture> textures_;
  std::vector<QuadSetup> quads_;
  int n_quads_ = 0;
  std::vector<float> zbuf_;
  std::vector<int32_t> qbuf_;
  std::vector<float> ray_x_, ray_y_;  // (x - cx) / fx per column, (y - cy) / fy per row
  // Lens only (empty without distortion): per pixel its ideal ray (x, y) at unit depth,
  // interleaved, the mip-level offset, and the rays' bounding box (x0, y0, x1, y1).
  bool lens_ = false;
  std::vector<float> lens_ray_, lens_lod_;
  double lens_box_[4] = {0, 0, 0, 0};
  std::vector<int8_t> noise_;
  cv::Mat blur_tmp_;
  cv::Mat blur_acc_;
};

}  // namespace rdslam
