#include "core/image_ops.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace rdslam {

namespace {

// Bresenham circle of radius 3 (x, y), clockwise from the top, as in FAST and OpenCV.
constexpr int kCircle[16][2] = {{0, -3}, {1, -3},  {2, -2},  {3, -1}, {3, 0},  {3, 1},
                                {2, 2},  {1, 3},   {0, 3},   {-1, 3}, {-2, 2}, {-3, 1},
                                {-3, 0}, {-3, -1}, {-2, -2}, {-1, -3}};

typedef uint8_t V16 __attribute__((vector_size(16)));

inline V16 load16(const uint8_t* p) {
  V16 v;
  std::memcpy(&v, p, 16);
  return v;
}

inline V16 splat16(uint8_t a) {
  V16 v;
  for (int i = 0; i < 16; ++i) v[i] = a;
  return v;
}

inline V16 vmin(V16 a, V16 b) {
  return a < b ? a : b;
}

// Per lane: max over the 16 arcs of 9 (of p[0..24], the circle plus its first 9 pixels
// again) of the arc's minimum; minima of 2, 4, 8 then 9 consecutive values.
inline V16 max_arc_min(const V16* p) {
  V16 m2[24], m4[22], best = V16{};
  for (int k = 0; k < 24; ++k) m2[k] = vmin(p[k], p[k + 1]);
  for (int k = 0; k < 22; ++k) m4[k] = vmin(m2[k], m2[k + 2]);
  for (int k = 0; k < 16; ++k) {
    const V16 m9 = vmin(vmin(m4[k], m4[k + 4]), p[k + 8]);
    best = best > m9 ? best : m9;
  }
  return best;
}

// True when the circular 16-bit mask has a run of at least 9 set bits.
inline bool has_run9(uint32_t m) {
  uint32_t r = m | (m << 16);
  r &= r >> 1;  // runs of 2
  r &= r >> 2;  // runs of 4
  r &= r >> 4;  // runs of 8
  r &= r >> 1;  // runs of 9
  return (r & 0xFFFFu) != 0;
}

// Largest t for which an arc of 9 has every difference > t, i.e. max over arcs of the arc's
// minimum, minus one (OpenCV's cornerScore<16>).
inline int arc_score(const int* d) {
  int m2[24], m4[22], best = -1000;
  for (int k = 0; k < 24; ++k) m2[k] = std::min(d[k], d[k + 1]);
  for (int k = 0; k < 22; ++k) m4[k] = std::min(m2[k], m2[k + 2]);
  for (int k = 0; k < 16; ++k) {
    const int m9 = std::min(std::min(m4[k], m4[k + 4]), d[k + 8]);
    best = std::max(best, m9);
  }
  return best - 1;
}

}  // namespace

int FastDetector::detect(const cv::Mat& img, int threshold, int border,
                         std::vector<FastCorner>& out) {
  out.clear();
  if (img.empty() || img.type() != CV_8UC1) return 0;
  border = std::max(3, border);
  const int cols = img.cols, rows = img.rows;
  if (cols <= 2 * border || rows <= 2 * border) return 0;
  // Strict 3x3 maxima are never 8-adjacent: at most one per 2x2 block.
  const size_t max_corners = static_cast<size_t>((cols + 1) / 2) * ((rows + 1) / 2);
  if (out.capacity() < max_corners) out.reserve(max_corners);
  if (score_rows_.size() < static_cast<size_t>(3 * cols)) {
    score_rows_.assign(static_cast<size_t>(3) * cols, 0);
    for (auto& rc : row_corners_) rc.reserve(cols);
  }
  for (auto& rc : row_corners_) rc.clear();
  std::memset(score_rows_.data(), 0, static_cast<size_t>(3) * cols);
  const int t = std::max(1, std::min(254, threshold));
  const int step = static_cast<int>(img.step1());
  int offs[16];
  for (int k = 0; k < 16; ++k) offs[k] = kCircle[k][1] * step + kCircle[k][0];
  // Scores are computed one pixel beyond the emitted region so its border pixels have
  // complete 3x3 neighbourhoods for the suppression.
  const int xs = std::max(3, border - 1), xe = std::min(cols - 3, cols - border + 1);
  const int ys = std::max(3, border - 1), ye = std::min(rows - 3, rows - border + 1);
  const V16 tv = splat16(static_cast<uint8_t>(t));
  const V16 lim_hi = splat16(static_cast<uint8_t>(255 - t));

  auto suppress_row = [&](int y) {  // emits the maxima of row y (scores of y-1..y+1 ready)
    if (y < border || y >= rows - border) return;
    const uint8_t* prev = &score_rows_[static_cast<size_t>((y - 1) % 3) * cols];
    const uint8_t* curr = &score_rows_[static_cast<size_t>(y % 3) * cols];
    const uint8_t* next = &score_rows_[static_cast<size_t>((y + 1) % 3) * cols];
    for (const int16_t x : row_corners_[y % 3]) {
      if (x < border || x >= cols - border) continue;
      const int s = curr[x];
      if (s > curr[x - 1] && s > curr[x + 1] && s > prev[x - 1] && s > prev[x] && s > prev[x + 1] &&
          s > next[x - 1] && s > next[x] && s > next[x + 1]) {
        FastCorner c;
        c.x = x;
        c.y = static_cast<int16_t>(y);
        c.score = static_cast<int16_t>(s);
        out.push_back(c);
      }
    }
  };

  for (int y = ys; y < ye; ++y) {
    const uint8_t* row = img.ptr<uint8_t>(y);
    uint8_t* score = &score_rows_[static_cast<size_t>(y % 3) * cols];
    std::memset(score, 0, cols);
    std::vector<int16_t>& corners = row_corners_[y % 3];
    corners.clear();
    // Pre-test: the 7 circle pixels outside a 9-arc never contain both pixel k and pixel
    // k+8, so every opposite pair has a member in the arc. 16 pixels at a time with GCC
    // vector extensions (SSE2 on x86-64, NEON on aarch64; no intrinsics), scalar tail.
    const uint8_t* q[16];
    for (int k = 0; k < 16; ++k) q[k] = row + offs[k];
    int x = xs;
    for (; x + 16 <= xe; x += 16) {
      const V16 v = load16(row + x);
      const V16 hi = (v + tv) | reinterpret_cast<V16>(v > lim_hi);  // saturated v + t
      const V16 lo = (v - tv) & ~reinterpret_cast<V16>(v < tv);     // saturated v - t
      V16 bright = ~V16{}, dark = ~V16{};
      for (int k = 0; k < 8; ++k) {
        const V16 a = load16(q[k] + x), b = load16(q[k + 8] + x);
        bright &= reinterpret_cast<V16>(a > hi) | reinterpret_cast<V16>(b > hi);
        dark &= reinterpret_cast<V16>(a < lo) | reinterpret_cast<V16>(b < lo);
      }
      V16 c = bright | dark;
      uint64_t any[2];
      std::memcpy(any, &c, 16);
      if ((any[0] | any[1]) == 0) continue;
      // Full segment test for the 16 pixels: longest run of brighter (darker) pixels around
      // the circle (wrapping: 16 + 8 positions), as OpenCV's SIMD FAST does.
      V16 pb[25], pd[25];  // saturated differences p - v and v - p
      V16 run_b = V16{}, run_d = V16{}, max_b = V16{}, max_d = V16{};
      for (int k = 0; k < 25; ++k) {
        const V16 a = load16(q[k & 15] + x);
        const V16 gt = reinterpret_cast<V16>(a > v), lt = reinterpret_cast<V16>(a < v);
        pb[k] = (a - v) & gt;
        pd[k] = (v - a) & lt;
        const V16 mb = reinterpret_cast<V16>(a > hi), md = reinterpret_cast<V16>(a < lo);
        run_b = (run_b - mb) & mb;  // mb lanes are 0xFF: run + 1, else 0
        run_d = (run_d - md) & md;
        max_b = max_b > run_b ? max_b : run_b;
        max_d = max_d > run_d ? max_d : run_d;
      }
      c &= reinterpret_cast<V16>(max_b > 8) | reinterpret_cast<V16>(max_d > 8);
      std::memcpy(any, &c, 16);
      if ((any[0] | any[1]) == 0) continue;
      // Score (OpenCV's): max over the 16 arcs of 9 of the arc's smallest difference, minus
      // one. Saturated differences give the same maximum for the corner's polarity; the
      // other polarity has no 9-arc of non-zero differences, so it contributes 0.
      const V16 sb = max_arc_min(pb), sd = max_arc_min(pd);
      const V16 sc = (sb > sd ? sb : sd) - splat16(1);
      uint8_t cs[16], ss[16];
      std::memcpy(cs, &c, 16);
      std::memcpy(ss, &sc, 16);
      for (int i = 0; i < 16; ++i) {
        if (!cs[i]) continue;
        score[x + i] = ss[i];
        corners.push_back(static_cast<int16_t>(x + i));
      }
    }
    for (; x < xe; ++x) {
      const int v = row[x];
      const int hi = v + t, lo = v - t;
      int bright = 1, dark = 1;
      for (int k = 0; k < 8; ++k) {
        const int a = q[k][x], b = q[k + 8][x];
        bright &= (a > hi) | (b > hi);
        dark &= (a < lo) | (b < lo);
      }
      if (!(bright | dark)) continue;
      const uint8_t* p = row + x;
      int d[25];
      uint32_t bm = 0, dm = 0;
      for (int k = 0; k < 16; ++k) {
        d[k] = p[offs[k]] - v;
        bm |= static_cast<uint32_t>(d[k] > t) << k;
        dm |= static_cast<uint32_t>(d[k] < -t) << k;
      }
      const bool is_bright = has_run9(bm), is_dark = has_run9(dm);
      if (!is_bright && !is_dark) continue;
      for (int k = 16; k < 25; ++k) d[k] = d[k - 16];
      int s = 0;
      if (is_bright) s = arc_score(d);
      if (is_dark) {
        int nd[25];
        for (int k = 0; k < 25; ++k) nd[k] = -d[k];
        s = std::max(s, arc_score(nd));
      }
      score[x] = static_cast<uint8_t>(std::min(255, std::max(1, s)));
      corners.push_back(static_cast<int16_t>(x));
    }
    if (y - 1 >= ys) suppress_row(y - 1);
  }
  // The last computed row has no computed row below it: its neighbours there score 0.
  if (ye - 1 >= ys) {
    std::memset(&score_rows_[static_cast<size_t>(ye % 3) * cols], 0, cols);
    row_corners_[ye % 3].clear();
    suppress_row(ye - 1);
  }
  return static_cast<int>(out.size());
}

GaussianBlur7::GaussianBlur7(double sigma) {
  double w[7], sum = 0;
  for (int i = 0; i < 7; ++i) {
    w[i] = std::exp(-(i - 3) * (i - 3) / (2.0 * sigma * sigma));
    sum += w[i];
  }
  int total = 0;
  for (int i = 0; i < 7; ++i) {
    kx_[i] = static_cast<uint16_t>(std::lround(256.0 * w[i] / sum));
    total += kx_[i];
  }
  kx_[3] = static_cast<uint16_t>(kx_[3] + 256 - total);  // exact unit gain
}

void GaussianBlur7::apply(const cv::Mat& src, cv::Mat& dst) {
  const int w = src.cols, h = src.rows;
  if (src.empty() || src.type() != CV_8UC1 || w < 4 || h < 4) {
    dst.release();
    return;
  }
  dst.create(h, w, CV_8UC1);  // no-op when the size is unchanged
  const size_t n = static_cast<size_t>(w) * h;
  if (rows_.size() < n) rows_.resize(n);
  if (padded_.size() < static_cast<size_t>(w + 6)) padded_.resize(w + 6);
  const uint16_t k0 = kx_[0], k1 = kx_[1], k2 = kx_[2], k3 = kx_[3];  // symmetric kernel
  uint8_t* pad = padded_.data();
  for (int y = 0; y < h; ++y) {
    const uint8_t* s = src.ptr<uint8_t>(y);
    std::memcpy(pad + 3, s, w);
    for (int i = 1; i <= 3; ++i) {  // BORDER_REFLECT_101: gfedcb|abcdefgh|gfedcba
      pad[3 - i] = s[i];
      pad[w + 2 + i] = s[w - 1 - i];
    }
    uint16_t* o = &rows_[static_cast<size_t>(y) * w];
    for (int x = 0; x < w; ++x) {
      const uint8_t* q = pad + x;
      o[x] = static_cast<uint16_t>(k0 * (q[0] + q[6]) + k1 * (q[1] + q[5]) + k2 * (q[2] + q[4]) +
                                   k3 * q[3]);
    }
  }
  for (int y = 0; y < h; ++y) {
    const uint16_t* r[7];
    for (int i = -3; i <= 3; ++i) {
      int yy = y + i;
      if (yy < 0) yy = -yy;
      if (yy >= h) yy = 2 * h - 2 - yy;
      r[i + 3] = &rows_[static_cast<size_t>(yy) * w];
    }
    uint8_t* o = dst.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const uint32_t acc = uint32_t(k0) * (r[0][x] + r[6][x]) + uint32_t(k1) * (r[1][x] + r[5][x]) +
                           uint32_t(k2) * (r[2][x] + r[4][x]) + uint32_t(k3) * r[3][x];
      o[x] = static_cast<uint8_t>((acc + 32768u) >> 16);
    }
  }
}

void BilinearResize::apply(const cv::Mat& src, cv::Mat& dst, cv::Size dsize) {
  if (src.empty() || src.type() != CV_8UC1 || src.cols < 2 || src.rows < 2 || dsize.width < 1 ||
      dsize.height < 1) {
    dst.release();
    return;
  }
  if (src.size() != src_size_ || dsize != dst_size_) {
    src_size_ = src.size();
    dst_size_ = dsize;
    auto table = [](int n_src, int n_dst, std::vector<int>& i0, std::vector<uint8_t>& wt) {
      i0.resize(n_dst);
      wt.resize(n_dst);
      const double scale = double(n_src) / n_dst;
      for (int d = 0; d < n_dst; ++d) {
        const double s = (d + 0.5) * scale - 0.5;  // pixel centres aligned
        int a = static_cast<int>(std::floor(s));
        double f = s - a;
        if (a < 0) {
          a = 0;
          f = 0;
        }
        if (a >= n_src - 1) {
          a = n_src - 2;
          f = 1.0;
        }
        i0[d] = a;
        wt[d] = static_cast<uint8_t>(std::lround(f * 128.0));
      }
    };
    table(src.cols, dsize.width, x0_, wx_);
    table(src.rows, dsize.height, y0_, wy_);
    for (auto& r : hrow_) r.resize(dsize.width);
  }
  cached_rows_[0] = cached_rows_[1] = -1;
  dst.create(dsize, CV_8UC1);
  const int w = dsize.width;
  auto interp_row = [&](int sy, std::vector<uint16_t>& o) {
    const uint8_t* s = src.ptr<uint8_t>(sy);
    for (int x = 0; x < w; ++x) {
      const int a = x0_[x], f = wx_[x];
      o[x] = static_cast<uint16_t>(s[a] * (128 - f) + s[a + 1] * f);
    }
  };
  for (int y = 0; y < dsize.height; ++y) {
    const int sy = y0_[y];
    // Reuse horizontally interpolated rows shared with the previous destination row.
    if (cached_rows_[0] != sy) {
      if (cached_rows_[1] == sy) {
        std::swap(hrow_[0], hrow_[1]);
        cached_rows_[0] = sy;
        cached_rows_[1] = -1;
      } else {
        interp_row(sy, hrow_[0]);
        cached_rows_[0] = sy;
      }
    }
    if (cached_rows_[1] != sy + 1) {
      interp_row(sy + 1, hrow_[1]);
      cached_rows_[1] = sy + 1;
    }
    const uint32_t f = wy_[y];
    const uint16_t* a = hrow_[0].data();
    const uint16_t* b = hrow_[1].data();
    uint8_t* o = dst.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      o[x] = static_cast<uint8_t>((a[x] * (128u - f) + b[x] * f + 8192u) >> 14);
    }
  }
}

}  // namespace rdslam
