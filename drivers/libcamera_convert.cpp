// convert_libcamera_frame(): always built (no libcamera dependency) so the conversions the
// libcamera source relies on are unit-tested on every machine (tests/unit/test_v4l2_libcamera.cpp).
#include <algorithm>
#include <array>
#include <opencv2/imgproc.hpp>

#include "drivers/libcamera_source.h"

namespace rdslam {
namespace {

// Y'CbCr -> full-range BGR, 16-bit fixed point. BT.601 matrix (libcamera's Smpte170m/Sycc;
// a Rec709 stream would differ by < 3 levels in saturated colours, irrelevant for tracking).
struct Coeffs {
  std::array<int32_t, 256> y, rv, gu, gv, bu;
  std::array<uint8_t, 256> grey;
  explicit Coeffs(bool limited) {
    const double ys = limited ? 255.0 / 219.0 : 1.0;
    const double cs = limited ? 255.0 / 224.0 : 1.0;
    const int y0 = limited ? 16 : 0;
    for (int i = 0; i < 256; ++i) {
      y[i] = static_cast<int32_t>(ys * 65536.0 * (i - y0));
      rv[i] = static_cast<int32_t>(1.402 * cs * 65536.0 * (i - 128));
      gu[i] = static_cast<int32_t>(0.344136 * cs * 65536.0 * (i - 128));
      gv[i] = static_cast<int32_t>(0.714136 * cs * 65536.0 * (i - 128));
      bu[i] = static_cast<int32_t>(1.772 * cs * 65536.0 * (i - 128));
      grey[i] = static_cast<uint8_t>(std::clamp((y[i] + 32768) >> 16, 0, 255));
    }
  }
};

const Coeffs& coeffs(bool limited) {
  static const Coeffs full(false), lim(true);
  return limited ? lim : full;
}

inline uint8_t clamp8(int32_t v_q16) {
  const int32_t v = (v_q16 + 32768) >> 16;
  return static_cast<uint8_t>(v < 0 ? 0 : (v > 255 ? 255 : v));
}

bool plane_fits(const uint8_t* p, size_t bytes, size_t stride, size_t row_bytes, int rows) {
  if (!p || rows <= 0 || stride < row_bytes) return false;
  return bytes >= stride * static_cast<size_t>(rows - 1) + row_bytes;
}

}  // namespace

bool convert_libcamera_frame(LibcameraLayout layout, const uint8_t* const planes[3],
                             const size_t plane_bytes[3], const size_t strides[3], int width,
                             int height, bool limited_range, cv::Mat& out) {
  if (width <= 0 || height <= 0 || out.rows != height || out.cols != width) return false;
  if (out.type() != CV_8UC1 && out.type() != CV_8UC3) return false;
  const bool grey_out = out.type() == CV_8UC1;
  const size_t w = static_cast<size_t>(width);
  const int ch = (height + 1) / 2;
  const size_t cw = (w + 1) / 2;
  switch (layout) {
    case LibcameraLayout::kGrey:
      if (!plane_fits(planes[0], plane_bytes[0], strides[0], w, height)) return false;
      break;
    case LibcameraLayout::kYuyv:
      if ((width & 1) || !plane_fits(planes[0], plane_bytes[0], strides[0], 2 * w, height)) {
        return false;
      }
      break;
    case LibcameraLayout::kYuv420:
      if (!plane_fits(planes[0], plane_bytes[0], strides[0], w, height)) return false;
      if (!grey_out && (!plane_fits(planes[1], plane_bytes[1], strides[1], cw, ch) ||
                        !plane_fits(planes[2], plane_bytes[2], strides[2], cw, ch))) {
        return false;
      }
      break;
    case LibcameraLayout::kNv12:
    case LibcameraLayout::kNv21:
      if (!plane_fits(planes[0], plane_bytes[0], strides[0], w, height)) return false;
      if (!grey_out && !plane_fits(planes[1], plane_bytes[1], strides[1], 2 * cw, ch)) {
        return false;
      }
      break;
    case LibcameraLayout::kMjpeg:
      return false;  // decoded by the source's MjpegDecoder, not here
  }
  const Coeffs& k = coeffs(limited_range && layout != LibcameraLayout::kGrey);
  const bool packed = layout == LibcameraLayout::kYuyv;
  for (int r = 0; r < height; ++r) {
    const uint8_t* yrow = planes[0] + strides[0] * static_cast<size_t>(r);
    if (grey_out) {
      uint8_t* d = out.ptr<uint8_t>(r);
      if (layout == LibcameraLayout::kGrey) {
        std::copy_n(yrow, w, d);
      } else {
        for (size_t c = 0; c < w; ++c) d[c] = k.grey[yrow[packed ? 2 * c : c]];
      }
      continue;
    }
    uint8_t* d = out.ptr<uint8_t>(r);
    if (layout == LibcameraLayout::kGrey) {
      for (size_t c = 0; c < w; ++c, d += 3) d[0] = d[1] = d[2] = yrow[c];
      continue;
    }
    const size_t cr = static_cast<size_t>(r / 2);
    const uint8_t* p1 = packed ? nullptr : planes[1] + strides[1] * cr;
    const uint8_t* p2 = layout == LibcameraLayout::kYuv420 ? planes[2] + strides[2] * cr : nullptr;
    for (size_t c = 0; c < w; ++c, d += 3) {
      int yv, u, v;
      const size_t h = c / 2;
      switch (layout) {
        case LibcameraLayout::kYuyv:
          yv = yrow[2 * c];
          u = yrow[4 * h + 1];
          v = yrow[4 * h + 3];
          break;
        case LibcameraLayout::kYuv420:
          yv = yrow[c];
          u = p1[h];
          v = p2[h];
          break;
        case LibcameraLayout::kNv12:
          yv = yrow[c];
          u = p1[2 * h];
          v = p1[2 * h + 1];
          break;
        default:  // kNv21
          yv = yrow[c];
          v = p1[2 * h];
          u = p1[2 * h + 1];
          break;
      }
      const int32_t y = k.y[yv];
      d[0] = clamp8(y + k.bu[u]);
      d[1] = clamp8(y - k.gu[u] - k.gv[v]);
      d[2] = clamp8(y + k.rv[v]);
    }
  }
  return true;
}

}  // namespace rdslam
