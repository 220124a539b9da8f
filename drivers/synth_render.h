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
  // when a texture cannot be read or the camera is not an undistorted pinhole.
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
  void add_noise(cv::Mat& image, int index);

  const SynthScene& scene_;
  std::vector<Texture> textures_;
  std::vector<QuadSetup> quads_;
  int n_quads_ = 0;
  std::vector<float> zbuf_;
  std::vector<int32_t> qbuf_;
  std::vector<float> ray_x_, ray_y_;  // (x - cx) / fx per column, (y - cy) / fy per row
  std::vector<int8_t> noise_;
  cv::Mat blur_tmp_;
  cv::Mat blur_acc_;
};

}  // namespace rdslam
