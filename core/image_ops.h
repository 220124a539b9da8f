// Allocation-free image primitives for the ORB feature path (issue 10): FAST-9 corners with
// non-maximum suppression, a 7x7 Gaussian blur and a bilinear downscale, each writing into
// caller-owned buffers that keep their capacity between frames. OpenCV's cv::FAST,
// cv::GaussianBlur and cv::resize allocate 4-12 temporary buffers per call (row buffers,
// kernels, tables), which breaks the project rule of no heap allocation per frame after
// warm-up; these versions allocate only when an image size is seen for the first time.
//
// The inner loops are plain, branch-free C++ over rows so GCC auto-vectorises them (SSE2 on
// x86-64, NEON on aarch64) without intrinsics. Results equal OpenCV's up to fixed-point
// rounding (blur, resize: at most 1 grey level) and FAST scores are OpenCV's definition
// (the largest threshold at which the pixel is still a corner).
//
// Ownership: each object owns its scratch buffers. Threads: one object per thread.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace rdslam {

struct FastCorner {
  int16_t x = 0, y = 0;
  int16_t score = 0;  // largest threshold at which the point is still a FAST-9 corner
};

class FastDetector {
 public:
  // FAST-9 (segment test, 9 contiguous of 16 circle pixels brighter than centre + t or darker
  // than centre - t, Rosten & Drummond 2006) with 3x3 non-maximum suppression on the score,
  // for corners at least `border` (>= 3) pixels from the image edge. `out` is cleared and
  // filled; its capacity is raised once per image size to the maximum possible count, so
  // later calls never allocate. Returns the number of corners.
  int detect(const cv::Mat& img, int threshold, int border, std::vector<FastCorner>& out);

 private:
  std::vector<uint8_t> score_rows_;  // 3 rows of scores (ring), clamped to 255
  std::vector<int16_t> row_corners_[3];
};

// 7x7 Gaussian (sigma 2) with BORDER_REFLECT_101, as ORB smooths each pyramid level before
// its BRIEF tests. `dst` is (re)created with src's size only when the size differs.
class GaussianBlur7 {
 public:
  explicit GaussianBlur7(double sigma = 2.0);
  void apply(const cv::Mat& src, cv::Mat& dst);

 private:
  uint16_t kx_[7];               // weights summing to 256
  std::vector<uint16_t> rows_;   // 7 horizontally filtered rows (ring)
  std::vector<uint8_t> padded_;  // one source row with 3 reflected pixels each side
};

// Bilinear downscale with pixel-centre alignment (as cv::resize INTER_LINEAR). Tables are
// rebuilt only when the source or destination size changes.
class BilinearResize {
 public:
  void apply(const cv::Mat& src, cv::Mat& dst, cv::Size dst_size);

 private:
  cv::Size src_size_{0, 0}, dst_size_{0, 0};
  std::vector<int> x0_;            // left source column per destination column
  std::vector<uint8_t> wx_;        // weight of the right column, of 128
  std::vector<int> y0_;            // top source row per destination row
  std::vector<uint8_t> wy_;        // weight of the bottom row, of 128
  std::vector<uint16_t> hrow_[2];  // horizontally interpolated rows y0, y0+1
  int cached_rows_[2] = {-1, -1};
};

}  // namespace rdslam
