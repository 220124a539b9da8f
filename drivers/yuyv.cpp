#include "drivers/yuyv.h"

#include <algorithm>
#include <array>

namespace rdslam {
namespace {

// BT.601 limited range to full-range RGB, fixed point with 16 fractional bits:
//   R = 1.164 (Y-16) + 1.596 (Cr-128)
//   G = 1.164 (Y-16) - 0.391 (Cb-128) - 0.813 (Cr-128)
//   B = 1.164 (Y-16) + 2.018 (Cb-128)
// Tables keep the per-pixel work to adds and one clamp (the capture thread runs on a small
// ARM core at camera rate).
struct Tables {
  std::array<int32_t, 256> y;   // 1.164 (Y-16) << 16
  std::array<int32_t, 256> rv;  // 1.596 (Cr-128) << 16
  std::array<int32_t, 256> gu;  // 0.391 (Cb-128) << 16
  std::array<int32_t, 256> gv;  // 0.813 (Cr-128) << 16
  std::array<int32_t, 256> bu;  // 2.018 (Cb-128) << 16
  std::array<uint8_t, 256> grey;
  Tables() {
    for (int i = 0; i < 256; ++i) {
      y[i] = static_cast<int32_t>(1.164383 * 65536.0 * (i - 16));
      rv[i] = static_cast<int32_t>(1.596027 * 65536.0 * (i - 128));
      gu[i] = static_cast<int32_t>(0.391762 * 65536.0 * (i - 128));
      gv[i] = static_cast<int32_t>(0.812968 * 65536.0 * (i - 128));
      bu[i] = static_cast<int32_t>(2.017232 * 65536.0 * (i - 128));
      const int g = (y[i] + 32768) >> 16;
      grey[i] = static_cast<uint8_t>(std::clamp(g, 0, 255));
    }
  }
};

const Tables& tables() {
  static const Tables t;  // C++11 magic static: built once, thread-safe
  return t;
}

inline uint8_t clamp8(int32_t v_q16) {
  const int32_t v = (v_q16 + 32768) >> 16;
  return static_cast<uint8_t>(v < 0 ? 0 : (v > 255 ? 255 : v));
}

}  // namespace

bool yuyv_to_image(const uint8_t* src, size_t bytes, int width, int height, size_t stride,
                   cv::Mat& out) {
  if (!src || width <= 0 || height <= 0 || (width & 1) != 0) return false;
  if (stride < static_cast<size_t>(width) * 2) return false;
  const size_t need = stride * static_cast<size_t>(height - 1) + static_cast<size_t>(width) * 2;
  if (bytes < need) return false;
  if (out.rows != height || out.cols != width) return false;
  const Tables& t = tables();
  if (out.type() == CV_8UC1) {
    for (int r = 0; r < height; ++r) {
      const uint8_t* s = src + stride * static_cast<size_t>(r);
      uint8_t* d = out.ptr<uint8_t>(r);
      for (int c = 0; c < width; ++c) d[c] = t.grey[s[2 * c]];
    }
    return true;
  }
  if (out.type() != CV_8UC3) return false;
  for (int r = 0; r < height; ++r) {
    const uint8_t* s = src + stride * static_cast<size_t>(r);
    uint8_t* d = out.ptr<uint8_t>(r);
    for (int c = 0; c < width; c += 2, s += 4, d += 6) {
      const int32_t u = s[1];
      const int32_t v = s[3];
      const int32_t rv = t.rv[v];
      const int32_t g_uv = -t.gu[u] - t.gv[v];
      const int32_t bu = t.bu[u];
      const int32_t y0 = t.y[s[0]];
      const int32_t y1 = t.y[s[2]];
      d[0] = clamp8(y0 + bu);
      d[1] = clamp8(y0 + g_uv);
      d[2] = clamp8(y0 + rv);
      d[3] = clamp8(y1 + bu);
      d[4] = clamp8(y1 + g_uv);
      d[5] = clamp8(y1 + rv);
    }
  }
  return true;
}

}  // namespace rdslam
