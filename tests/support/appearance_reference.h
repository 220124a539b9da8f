// The reference definition of eq. (2)'s appearance difference: a verbatim copy of
// core/change_detection.cpp's appearance_difference() (both overloads) as of main f2d5606,
// before it was optimised (precomputed bilinear weights, separable sampling, several shifts
// scored at once). The optimised function must return the same values (to float rounding;
// on x86-64 bit for bit), so the map updater's decisions and the trajectories do not change:
// tests/unit/test_change_detection.cpp compares the two on random cases and
// benchmarks/bench_appearance.cpp times them. Header-only, test and benchmark code only.
#pragma once

#include <Eigen/Core>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>

#include "core/change_detection.h"

namespace rdslam::test {

inline float reference_sample_bilinear(const cv::Mat& img, double x, double y, int c) {
  const int x0 = static_cast<int>(std::floor(x));
  const int y0 = static_cast<int>(std::floor(y));
  const float ax = float(x - x0), ay = float(y - y0);
  const int ch = img.channels();
  const uint8_t* r0 = img.ptr<uint8_t>(y0);
  const uint8_t* r1 = img.ptr<uint8_t>(y0 + 1);
  const float v00 = r0[x0 * ch + c], v01 = r0[(x0 + 1) * ch + c];
  const float v10 = r1[x0 * ch + c], v11 = r1[(x0 + 1) * ch + c];
  return (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11);
}

// (Declared first: in a header the scale overload below calls the warp one.)
inline double reference_appearance_difference(const cv::Mat& keyframe_image,
                                              const Eigen::Vector2d& x,
                                              const cv::Mat& current_image,
                                              const Eigen::Vector2d& x_prime,
                                              const Eigen::Matrix2d& A, int window, int search_d,
                                              bool normalise, double accept);

inline double reference_appearance_difference(const cv::Mat& keyframe_image,
                                              const Eigen::Vector2d& x,
                                              const cv::Mat& current_image,
                                              const Eigen::Vector2d& x_prime, double scale,
                                              int window, int search_d, bool normalise,
                                              double accept) {
  if (!(scale > 0) || !std::isfinite(scale)) return std::numeric_limits<double>::infinity();
  return reference_appearance_difference(keyframe_image, x, current_image, x_prime,
                                         Eigen::Matrix2d(scale * Eigen::Matrix2d::Identity()),
                                         window, search_d, normalise, accept);
}

inline double reference_appearance_difference(const cv::Mat& keyframe_image,
                                              const Eigen::Vector2d& x,
                                              const cv::Mat& current_image,
                                              const Eigen::Vector2d& x_prime,
                                              const Eigen::Matrix2d& A, int window, int search_d,
                                              bool normalise, double accept) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (keyframe_image.empty() || current_image.empty() ||
      keyframe_image.channels() != current_image.channels() || keyframe_image.depth() != CV_8U ||
      current_image.depth() != CV_8U || !A.allFinite() || !(A.determinant() > 0) || window < 1 ||
      window > kMaxAppearanceWindow || !x.allFinite() || !x_prime.allFinite()) {
    // (A non-finite pixel passes every bounds test below: a point projected from behind the
    // camera crashed the mapper on synth:turn_in_place_offset.)
    return kInf;
  }
  // How far the warped grid reaches from x' per keyframe-window pixel, along x and y.
  const double ax = std::fabs(A(0, 0)) + std::fabs(A(0, 1));
  const double ay = std::fabs(A(1, 0)) + std::fabs(A(1, 1));
  const int h = window / 2;
  const int ch = keyframe_image.channels();
  // The keyframe window must lie inside the keyframe image (integer pixels around x).
  const int kx = static_cast<int>(std::lround(x.x()));
  const int ky = static_cast<int>(std::lround(x.y()));
  if (kx - h < 0 || ky - h < 0 || kx + h >= keyframe_image.cols || ky + h >= keyframe_image.rows) {
    return kInf;
  }
  // The warped window plus the search margin must lie inside the current image.
  const double reach_x = ax * h + search_d + 1, reach_y = ay * h + search_d + 1;
  if (x_prime.x() - reach_x < 0 || x_prime.y() - reach_y < 0 ||
      x_prime.x() + reach_x >= current_image.cols - 1 ||
      x_prime.y() + reach_y >= current_image.rows - 1) {
    return kInf;
  }
  const int w = 2 * h + 1;
  const int n = w * w;
  const int D = search_d;
  const int gw = w + 2 * D;  // sampled grid: the window plus the search margin
  // Keyframe window (per channel zero-mean when normalising) and the current image sampled
  // once on the warped grid y' = x' + s (y - x + d): the local search d runs in keyframe-window
  // units (s d current pixels, s the depth ratio, near 1 for the selected keyframes). Stack
  // buffers: no allocation.
  float kv[3][kMaxAppearanceWindow * kMaxAppearanceWindow];
  float grid[3][(kMaxAppearanceWindow + 2 * 8) * (kMaxAppearanceWindow + 2 * 8)];
  if (D > 8) return kInf;
  double k_mean[3] = {0, 0, 0}, k_dev[3] = {0, 0, 0};
  for (int wy = -h; wy <= h; ++wy) {
    const uint8_t* krow = keyframe_image.ptr<uint8_t>(ky + wy);
    for (int wx = -h; wx <= h; ++wx) {
      const int i = (wy + h) * w + (wx + h);
      for (int c = 0; c < ch; ++c) {
        kv[c][i] = krow[(kx + wx) * ch + c];
        k_mean[c] += kv[c][i];
      }
    }
  }
  // Bias and gain shared by the channels (white light, exposure): the window's mean colour
  // balance is part of its appearance.
  const double k_mean_all = (k_mean[0] + (ch > 1 ? k_mean[1] + k_mean[2] : 0.0)) / (double(n) * ch);
  for (int c = 0; c < ch; ++c) {
    k_mean[c] /= n;
    if (!normalise) continue;
    for (int i = 0; i < n; ++i) {
      kv[c][i] -= float(k_mean_all);
      k_dev[c] += std::fabs(kv[c][i]);
    }
  }
  // The score's unit: per pixel and channel (plain) or the keyframe window's contrast.
  double k_dev_all = 0;
  for (int c = 0; c < ch; ++c) k_dev_all += k_dev[c];
  if (normalise && k_dev_all < kMinAppearanceContrast * n * ch) return kInf;  // no texture
  const double off_x = kx - x.x(), off_y = ky - x.y();                        // sub-pixel part of x
  // The grid's offsets reach h + D + |sub-pixel part of x| (<= 0.5) keyframe pixels: with a
  // large scale (the camera much closer than the keyframe) the half pixel times A exceeded the
  // bilinear margin of 1 and read past the image (a mapper crash on synth:turn_in_place_offset).
  const double reach_gx = ax * (h + D + std::fabs(off_x)) + 1,
               reach_gy = ay * (h + D + std::fabs(off_y)) + 1;
  if (x_prime.x() - reach_gx < 0 || x_prime.y() - reach_gy < 0 ||
      x_prime.x() + reach_gx >= current_image.cols - 1 ||
      x_prime.y() + reach_gy >= current_image.rows - 1) {
    return kInf;
  }
  for (int gy = 0; gy < gw; ++gy) {
    const double oy = gy - h - D + off_y;
    for (int gx = 0; gx < gw; ++gx) {
      const double ox = gx - h - D + off_x;
      const double cx = x_prime.x() + (A(0, 0) * ox + A(0, 1) * oy);
      const double cy = x_prime.y() + (A(1, 0) * ox + A(1, 1) * oy);
      for (int c = 0; c < ch; ++c)
        grid[c][gy * gw + gx] = reference_sample_bilinear(current_image, cx, cy, c);
    }
  }
  const double unit = normalise ? k_dev_all : double(n) * ch;
  const double accept_sum = accept * unit;
  double best = kInf;
  // Shifts ring by ring from the centre (r = max(|dx|, |dy|)), so `accept` stops early.
  for (int r = 0; r <= D; ++r) {
    for (int ddy = -r; ddy <= r; ++ddy) {
      for (int ddx = -r; ddx <= r; ++ddx) {
        if (std::max(std::abs(ddx), std::abs(ddy)) != r) continue;
        const int dy = ddy + D, dx = ddx + D;
        double sum = 0;
        double mean = 0, g = 1.0;
        if (normalise) {
          for (int c = 0; c < ch; ++c) {
            const float* g0 = grid[c] + dy * gw + dx;
            for (int wy = 0; wy < w; ++wy) {
              for (int wx = 0; wx < w; ++wx) mean += g0[wy * gw + wx];
            }
          }
          mean /= double(n) * ch;
          double dev = 0;
          for (int c = 0; c < ch; ++c) {
            const float* g0 = grid[c] + dy * gw + dx;
            for (int wy = 0; wy < w; ++wy) {
              for (int wx = 0; wx < w; ++wx) dev += std::fabs(g0[wy * gw + wx] - mean);
            }
          }
          // Gain that maps the current window's contrast onto the keyframe's, bounded: a
          // contrast ratio beyond kMaxAppearanceGain is a different texture, not lighting.
          g = dev > 1e-6 ? k_dev_all / dev : kMaxAppearanceGain;
          g = std::clamp(g, 1.0 / kMaxAppearanceGain, kMaxAppearanceGain);
        }
        for (int c = 0; c < ch && sum < best; ++c) {
          const float* g0 = grid[c] + dy * gw + dx;
          const float* kc = kv[c];
          for (int wy = 0; wy < w; ++wy) {
            const float* gr = g0 + wy * gw;
            const float* kr = kc + wy * w;
            for (int wx = 0; wx < w; ++wx) sum += std::fabs(kr[wx] - g * (gr[wx] - mean));
          }
        }
        best = std::min(best, sum);
        if (best <= accept_sum) return best / unit;
      }
    }
  }
  // Relative residual (normalise): the keyframe window's own contrast is the unit.
  return best / unit;
}

}  // namespace rdslam::test
