#include "core/change_detection.h"

#include <Eigen/LU>
#include <algorithm>
#include <limits>

namespace rdslam {

void ChangeDetectionParams::visit(ParamVisitor& v) {
  v.field("map_update", map_update, "online 3D point and keyframe updating (Sec. 4)");
  v.field("occlusion_handling", occlusion_handling, "Algorithm 1 occlusion handling");
  v.field("closest_keyframes", closest_keyframes, 1, 20, "keyframes checked per frame");
  v.field("check_all_in_view", check_all_in_view,
          "also check points in view held by no selected keyframe (nearest observing keyframe)");
  v.field("keyframe_view_angle_deg", keyframe_view_angle_deg, 1.0, 180.0,
          "max optical-axis angle of a checked keyframe");
  v.field("histogram_threshold", histogram_threshold, 0.0, 10.0,
          "colour histogram difference that triggers the point check");
  v.field("tau_n", tau_n, -1.0, 1.0, "view-direction cosine threshold");
  v.field("window", window, 3, 31, "appearance window size (odd)");
  v.field("search_d", search_d, 0, 8, "local search radius of eq. (2) in pixels");
  v.field("tau_c", tau_c, 0.0, 255.0, "appearance threshold, mean abs difference per pixel");
  v.field("normalise_appearance", normalise_appearance,
          "eq. (2) on bias- and gain-compensated windows (robust to lighting changes)");
  v.field("tau_c_relative", tau_c_relative, 0.0, 2.0,
          "appearance threshold of the normalised eq. (2), in units of the window's contrast");
  v.field("ray_search", ray_search,
          "search eq. (2) along the keyframe ray over the point's depth uncertainty");
  v.field("ray_search_sigmas", ray_search_sigmas, 0.0, 10.0,
          "depth uncertainty (in bearing-error sigmas) the ray search covers");
  v.field("temporal_check", temporal_check,
          "require the new appearance to be static before a point is invalidated");
  v.field("require_static_evidence", require_static_evidence,
          "invalidate only when the temporal check finds a static surface at/behind the point");
  v.field("check_new_points", check_new_points,
          "a new point must look the same in a recent frame (a third view)");
  v.field("temporal_max_gap_s", temporal_max_gap_s, 0.0, 10.0,
          "oldest recent frame the temporal check may use (s)");
  v.field("temporal_depth_margin", temporal_depth_margin, 0.0, 0.9,
          "relative depth below the point's that counts as an occluder in front");
  v.field("r1", r1, 1.0, 200.0, "radius of phi(x') in pixels");
  v.field("r2", r2, 1.0, 200.0, "first-keyframe distance threshold in pixels");
  v.field("check_every_n_frames", check_every_n_frames, 0, 1000,
          "tracked frames between per-frame map updates (0: keyframe candidates only)");
  v.field("min_observations", min_observations, 1, 100,
          "keyframes that must observe a point before Algorithm 1 checks it");
  v.field("confirm_checks", confirm_checks, 1, 100,
          "consecutive change verdicts before a point is invalidated");
  v.field("landmark_counters", landmark_counters, "second paper's missed/moved counters");
  v.field("count_missed", count_missed,
          "miss counter on Alg. 1's untracked-occluder verdict (needs landmark_counters)");
  v.field("miss_threshold", miss_threshold, 1, 10000, "missed count that discards a landmark");
  v.field("prune_unmatched", prune_unmatched,
          "erase unmatched duplicates of tracked points after miss_threshold checks");
  v.field("moved_threshold", moved_threshold, 1, 10000, "moved count that discards a landmark");
  v.field("flow_rejection", flow_rejection, "optical-flow rejection while stationary");
  v.field("flow_threshold_px", flow_threshold_px, 0.0, 100.0, "flow magnitude threshold");
  v.field("stationary_translation", stationary_translation, 0.0, 10.0,
          "per-frame translation below which the camera is stationary (map units)");
  v.field("stationary_rotation_deg", stationary_rotation_deg, 0.0, 45.0,
          "per-frame rotation below which the camera is stationary");
}

void compute_color_histogram(const cv::Mat& image, int stride, ColorHistogram& out) {
  out.bins.fill(0.f);
  out.valid = false;
  if (image.empty() || image.depth() != CV_8U || stride < 1) return;
  const int ch = image.channels();
  if (ch != 1 && ch != 3) return;
  float* b = out.bins.data();
  for (int y = 0; y < image.rows; y += stride) {
    const uint8_t* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < image.cols; x += stride) {
      if (ch == 3) {
        // BGR storage; histogram order R, G, B.
        b[0 * 256 + row[3 * x + 2]] += 1.f;
        b[1 * 256 + row[3 * x + 1]] += 1.f;
        b[2 * 256 + row[3 * x + 0]] += 1.f;
      } else {
        const uint8_t g = row[x];
        b[g] += 1.f;
        b[256 + g] += 1.f;
        b[512 + g] += 1.f;
      }
    }
  }
  for (int c = 0; c < 3; ++c) {
    double ss = 0;
    for (int i = 0; i < 256; ++i) ss += double(b[c * 256 + i]) * b[c * 256 + i];
    if (ss <= 0) return;
    const float inv = float(1.0 / std::sqrt(ss));
    for (int i = 0; i < 256; ++i) b[c * 256 + i] *= inv;
  }
  out.valid = true;
}

double histogram_difference(const ColorHistogram& a, const ColorHistogram& b) {
  double total = 0;
  for (int c = 0; c < 3; ++c) {
    double ss = 0;
    for (int i = 0; i < 256; ++i) {
      const double d = double(a.bins[c * 256 + i]) - b.bins[c * 256 + i];
      ss += d * d;
    }
    total += std::sqrt(ss);
  }
  return total;
}

int select_closest_keyframes(const Eigen::Vector3d& cur_z_axis, const Eigen::Vector3d& cur_centre,
                             const Eigen::Vector3d* z_axes, const Eigen::Vector3d* centres,
                             int count, double max_angle_deg, int k, int* out, int out_capacity) {
  const double min_cos = std::cos(max_angle_deg * M_PI / 180.0);
  const int cap = std::min(k, out_capacity);
  if (cap <= 0) return 0;
  // Keep the `cap` nearest candidates with an insertion list: k is small (5).
  double best_dist[64];
  const int limit = std::min(cap, 64);
  int n = 0;
  for (int i = 0; i < count; ++i) {
    if (z_axes[i].dot(cur_z_axis) < min_cos) continue;
    const double d = (centres[i] - cur_centre).squaredNorm();
    int pos = n;
    while (pos > 0 && best_dist[pos - 1] > d) --pos;
    if (pos >= limit) continue;
    const int last = std::min(n, limit - 1);
    for (int j = last; j > pos; --j) {
      best_dist[j] = best_dist[j - 1];
      out[j] = out[j - 1];
    }
    best_dist[pos] = d;
    out[pos] = i;
    if (n < limit) ++n;
  }
  return n;
}

namespace {

// Eq. (2)'s shift scoring. The current image is sampled once on the grid of the window plus
// the search margin (ch planes of gw x gw doubles, each the float bilinear sample); every shift
// d is then one window of that grid. A shift's score is three sequential sums over the window
// (mean, absolute deviation, SAD; channels, rows, columns in this order), each a chain of
// dependent double additions whose latency, not the arithmetic, bounds the time. Several
// shifts are scored at once (L lanes), each lane keeping exactly the order of additions of a
// shift scored alone, so the chains overlap and every score is the same to the last bit.
struct ShiftScoring {
  const double* grid;  // ch planes of gw * gw
  const double* kv;    // ch planes of w * w: the keyframe window (zero-mean when normalising)
  int gw, w, ch;
  bool normalise;
  double k_dev_all;
};

// Scores the L shifts whose windows start at grid offsets offs[0..L) into out[0..L). A lane
// whose SAD reaches abort_at after a channel (when all lanes of the group do) stops there:
// its partial sum is >= abort_at, which must be >= the running minimum, so the minimum and
// the `accept` decisions do not change (the caller's original loop stopped the same way).
template <int L>
void score_shifts(const ShiftScoring& s, const int* offs, double abort_at, double* out) {
  const int plane = s.gw * s.gw, w = s.w, n = w * w;
  double mean[L], g[L], sum[L];
  for (int k = 0; k < L; ++k) {
    mean[k] = 0;
    g[k] = 1.0;
    sum[k] = 0;
  }
  const double* p[L];
  if (s.normalise) {
    for (int c = 0; c < s.ch; ++c) {
      for (int wy = 0; wy < w; ++wy) {
        for (int k = 0; k < L; ++k) p[k] = s.grid + c * plane + offs[k] + wy * s.gw;
        for (int wx = 0; wx < w; ++wx) {
          for (int k = 0; k < L; ++k) mean[k] += p[k][wx];
        }
      }
    }
    for (int k = 0; k < L; ++k) mean[k] /= double(n) * s.ch;
    double dev[L];
    for (int k = 0; k < L; ++k) dev[k] = 0;
    for (int c = 0; c < s.ch; ++c) {
      for (int wy = 0; wy < w; ++wy) {
        for (int k = 0; k < L; ++k) p[k] = s.grid + c * plane + offs[k] + wy * s.gw;
        for (int wx = 0; wx < w; ++wx) {
          for (int k = 0; k < L; ++k) dev[k] += std::fabs(p[k][wx] - mean[k]);
        }
      }
    }
    for (int k = 0; k < L; ++k) {
      // Gain that maps the current window's contrast onto the keyframe's, bounded: a
      // contrast ratio beyond kMaxAppearanceGain is a different texture, not lighting.
      g[k] = dev[k] > 1e-6 ? s.k_dev_all / dev[k] : kMaxAppearanceGain;
      g[k] = std::clamp(g[k], 1.0 / kMaxAppearanceGain, kMaxAppearanceGain);
    }
  }
  for (int c = 0; c < s.ch; ++c) {
    bool live = false;
    for (int k = 0; k < L; ++k) live |= sum[k] < abort_at;
    if (!live) break;
    const double* kc = s.kv + c * n;
    for (int wy = 0; wy < w; ++wy) {
      for (int k = 0; k < L; ++k) p[k] = s.grid + c * plane + offs[k] + wy * s.gw;
      const double* kr = kc + wy * w;
      if (s.normalise) {
        for (int wx = 0; wx < w; ++wx) {
          for (int k = 0; k < L; ++k) sum[k] += std::fabs(kr[wx] - g[k] * (p[k][wx] - mean[k]));
        }
      } else {  // g = 1, mean = 0: kr - 1 * (v - 0) is kr - v exactly
        for (int wx = 0; wx < w; ++wx) {
          for (int k = 0; k < L; ++k) sum[k] += std::fabs(kr[wx] - p[k][wx]);
        }
      }
    }
  }
  for (int k = 0; k < L; ++k) out[k] = sum[k];
}

// Bilinear sample weights of one grid column (or row): the pixel left of (above) the sample
// and the float weight of the next one, as the per-sample formula computes them.
struct Tap {
  int i0;
  float a;
};

inline Tap tap(double v) {
  const int i0 = static_cast<int>(std::floor(v));
  return {i0, float(v - i0)};
}

// One bilinear sample, the formula of the reference definition (tests/support/
// appearance_reference.h) with its weights precomputed: the same float operations in the same
// order, so the same float.
inline float bilinear(const uint8_t* r0, const uint8_t* r1, int i0, int i1, float ax, float ay) {
  const float v00 = r0[i0], v01 = r0[i1];
  const float v10 = r1[i0], v11 = r1[i1];
  return (1 - ay) * ((1 - ax) * v00 + ax * v01) + ay * ((1 - ax) * v10 + ax * v11);
}

}  // namespace

double appearance_difference(const cv::Mat& keyframe_image, const Eigen::Vector2d& x,
                             const cv::Mat& current_image, const Eigen::Vector2d& x_prime,
                             double scale, int window, int search_d, bool normalise,
                             double accept) {
  if (!(scale > 0) || !std::isfinite(scale)) return std::numeric_limits<double>::infinity();
  return appearance_difference(keyframe_image, x, current_image, x_prime,
                               Eigen::Matrix2d(scale * Eigen::Matrix2d::Identity()), window,
                               search_d, normalise, accept);
}

// The definition is the reference in tests/support/appearance_reference.h (the plain loops:
// sample the grid per pixel and channel, then score the shifts one by one, ring by ring); this
// computes the same values faster: weights per grid point instead of per channel (per column
// and per row when A is diagonal, the common case, with a horizontal pass shared by the rows),
// and the shifts of a ring scored together (score_shifts). Every float and double operation
// is the reference's, in the reference's order; test_change_detection checks the two agree.
double appearance_difference(const cv::Mat& keyframe_image, const Eigen::Vector2d& x,
                             const cv::Mat& current_image, const Eigen::Vector2d& x_prime,
                             const Eigen::Matrix2d& A, int window, int search_d, bool normalise,
                             double accept) {
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
  // No shift to try (D < 0: the minimum over none is +inf) or beyond the buffers.
  if (D < 0 || D > 8) return kInf;
  const int gw = w + 2 * D;  // sampled grid: the window plus the search margin
  // Keyframe window (zero-mean when normalising) and the current image sampled once on the
  // warped grid y' = x' + A (y - x + d): the local search d runs in keyframe-window units (s d
  // current pixels, s the depth ratio, near 1 for the selected keyframes). Stack buffers: no
  // allocation.
  constexpr int kMaxGrid = kMaxAppearanceWindow + 2 * 8;
  float kv[3][kMaxAppearanceWindow * kMaxAppearanceWindow];
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
  // The grid, ch planes of gw x gw (doubles: every sum below reads a grid value as a double).
  double grid[3 * kMaxGrid * kMaxGrid];
  double kvd[3 * kMaxAppearanceWindow * kMaxAppearanceWindow];
  for (int c = 0; c < ch; ++c) {
    for (int i = 0; i < n; ++i) kvd[c * n + i] = kv[c][i];
  }
  const int plane = gw * gw;
  if (A(0, 1) == 0 && A(1, 0) == 0) {
    // Diagonal A: column gx samples at the same x for every row and row gy at the same y
    // (x'.x + (A00 ox + 0 oy) is x'.x + A00 ox: x'.x > 0 absorbs the sign of a zero). Each
    // image row's horizontal interpolation (1 - ax) v0 + ax v1 is computed once per column and
    // shared by the grid rows that read it (with scale 1, every image row serves two).
    Tap tx[kMaxGrid];
    for (int gx = 0; gx < gw; ++gx) tx[gx] = tap(x_prime.x() + A(0, 0) * (gx - h - D + off_x));
    float hrow[2][3 * kMaxGrid];  // the horizontal pass of two image rows, [c][gx]
    int hrow_y[2] = {-1, -1};
    // The buffer holding image row y, filled if needed without evicting buffer `keep`.
    auto horizontal = [&](int y, int keep) -> int {
      for (int b = 0; b < 2; ++b) {
        if (hrow_y[b] == y) return b;
      }
      const int b = keep >= 0 ? 1 - keep : (hrow_y[0] == y + 1 ? 1 : 0);
      hrow_y[b] = y;
      const uint8_t* r = current_image.ptr<uint8_t>(y);
      for (int c = 0; c < ch; ++c) {
        for (int gx = 0; gx < gw; ++gx) {
          const float a = tx[gx].a;
          const float v0 = r[tx[gx].i0 * ch + c], v1 = r[(tx[gx].i0 + 1) * ch + c];
          hrow[b][c * kMaxGrid + gx] = (1 - a) * v0 + a * v1;
        }
      }
      return b;
    };
    for (int gy = 0; gy < gw; ++gy) {
      const Tap ty = tap(x_prime.y() + A(1, 1) * (gy - h - D + off_y));
      const int b0 = horizontal(ty.i0, -1);
      const float* h0 = hrow[b0];
      const float* h1 = hrow[horizontal(ty.i0 + 1, b0)];
      const float b = ty.a;
      for (int c = 0; c < ch; ++c) {
        double* out = grid + c * plane + gy * gw;
        const float* t0 = h0 + c * kMaxGrid;
        const float* t1 = h1 + c * kMaxGrid;
        for (int gx = 0; gx < gw; ++gx) out[gx] = (1 - b) * t0[gx] + b * t1[gx];
      }
    }
  } else {
    // A general warp (a lens): the weights once per grid point for all channels.
    const size_t step = current_image.step[0];
    const uint8_t* base = current_image.ptr<uint8_t>(0);
    for (int gy = 0; gy < gw; ++gy) {
      const double oy = gy - h - D + off_y;
      for (int gx = 0; gx < gw; ++gx) {
        const double ox = gx - h - D + off_x;
        const double cx = x_prime.x() + (A(0, 0) * ox + A(0, 1) * oy);
        const double cy = x_prime.y() + (A(1, 0) * ox + A(1, 1) * oy);
        const Tap tx = tap(cx), ty = tap(cy);
        const uint8_t* r0 = base + size_t(ty.i0) * step;
        const uint8_t* r1 = r0 + step;
        for (int c = 0; c < ch; ++c) {
          grid[c * plane + gy * gw + gx] =
              bilinear(r0, r1, tx.i0 * ch + c, (tx.i0 + 1) * ch + c, tx.a, ty.a);
        }
      }
    }
  }
  const ShiftScoring scoring{grid, kvd, gw, w, ch, normalise, k_dev_all};
  const double unit = normalise ? k_dev_all : double(n) * ch;
  const double accept_sum = accept * unit;
  // Shifts ring by ring from the centre (r = max(|dx|, |dy|)), so `accept` stops early; the
  // scores of a group of shifts are walked in that order, with the reference's minimum and
  // early exit. Ring r >= 1 holds 8 r shifts: groups of 8.
  constexpr int kGroup = 8;
  int offs[(2 * 8 + 1) * (2 * 8 + 1)];
  int count = 0;
  for (int r = 0; r <= D; ++r) {
    for (int ddy = -r; ddy <= r; ++ddy) {
      for (int ddx = -r; ddx <= r; ++ddx) {
        if (std::max(std::abs(ddx), std::abs(ddy)) == r) offs[count++] = (ddy + D) * gw + ddx + D;
      }
    }
  }
  double scores[(2 * 8 + 1) * (2 * 8 + 1)];
  double best = kInf;
  if (!(accept_sum >= 0)) {
    // No score can be <= accept_sum (scores are >= 0): the result is the minimum over all
    // shifts, whatever the order. count = 8 m + 1: groups of 8 and one of 9.
    if (count == 1) {
      score_shifts<1>(scoring, offs, best, scores);
    } else {
      int i = 0;
      for (; count - i > kGroup + 1; i += kGroup)
        score_shifts<kGroup>(scoring, offs + i, best, scores + i);
      score_shifts<kGroup + 1>(scoring, offs + i, best, scores + i);
    }
    for (int i = 0; i < count; ++i) best = std::min(best, scores[i]);
    return best / unit;
  }
  // The centre first (an unchanged window usually matches there), then the rings.
  score_shifts<1>(scoring, offs, best, scores);
  best = std::min(best, scores[0]);
  if (best <= accept_sum) return best / unit;
  for (int i = 1; i < count; i += kGroup) {
    score_shifts<kGroup>(scoring, offs + i, best, scores + i);
    for (int j = i; j < i + kGroup; ++j) {
      best = std::min(best, scores[j]);
      if (best <= accept_sum) return best / unit;
    }
  }
  // Relative residual (normalise): the keyframe window's own contrast is the unit.
  return best / unit;
}

const char* to_string(PointDecision d) {
  switch (d) {
    case PointDecision::kKeepViewAngle:
      return "keep:view-angle";
    case PointDecision::kKeepSameAppearance:
      return "keep:same-appearance";
    case PointDecision::kKeepOccludedMoving:
      return "keep:occluded-by-moving";
    case PointDecision::kKeepOccludedStatic:
      return "keep:occluded-by-static";
    case PointDecision::kInvalidNothingInFront:
      return "invalid:nothing-in-front";
    case PointDecision::kInvalidSameObject:
      return "invalid:same-object";
    case PointDecision::kInvalidNoOcclusionHandling:
      return "invalid:no-occlusion-handling";
    case PointDecision::kKeepNotChecked:
      return "keep:not-checked";
    case PointDecision::kInvalidStaticChange:
      return "invalid:static-change";
    case PointDecision::kKeepUndecided:
      return "keep:undecided";
  }
  return "unknown";
}

PointDecision update_point_validity(const ChangeDetectionParams& p, const Eigen::Vector3d& n_x,
                                    const Eigen::Vector3d& n_x_prime, double d_c, double depth_x,
                                    const Eigen::Vector2d& x_p, const NeighbourPoint* neighbours,
                                    int neighbour_count, NewSurface seen) {
  // Alg. 1 line 4 (sign as in the prose): large view change -> keep V(X) = 1.
  if (n_x.dot(n_x_prime) < p.tau_n) return PointDecision::kKeepViewAngle;
  if (!std::isfinite(d_c)) return PointDecision::kKeepNotChecked;
  if (d_c <= p.tau_c) return PointDecision::kKeepSameAppearance;
  if (!p.occlusion_handling) return PointDecision::kInvalidNoOcclusionHandling;
  // What is in front of X now moves, or is a static surface in front of it: occluded.
  if (seen == NewSurface::kMoving) return PointDecision::kKeepOccludedMoving;
  if (seen == NewSurface::kInFront) return PointDecision::kKeepOccludedStatic;
  // phi(x') empty: X is hidden by something never tracked, i.e. a moving object - unless what
  // X's place shows now is static and not in front of X.
  if (neighbour_count <= 0) {
    return seen == NewSurface::kBehind ? PointDecision::kInvalidStaticChange
                                       : PointDecision::kKeepOccludedMoving;
  }
  if (p.temporal_check && p.require_static_evidence && seen != NewSurface::kBehind) {
    return PointDecision::kKeepUndecided;
  }
  bool all_behind = true;
  for (int i = 0; i < neighbour_count; ++i) all_behind &= neighbours[i].depth_current >= depth_x;
  if (all_behind) return PointDecision::kInvalidNothingInFront;
  // Some X_y lies in front of X: X changed (X_y on the same object, close to X where X first
  // appeared) or a static object occludes X (X_y far from X in that keyframe). The listing
  // loops over all of phi(x'); the prose restricts the test to "those X_y with z_{X_y} < z_X",
  // which is what we do: a point behind X cannot be the reason X looks different.
  for (int i = 0; i < neighbour_count; ++i) {
    const NeighbourPoint& y = neighbours[i];
    if (y.depth_current >= depth_x || !y.in_first_keyframe) continue;
    if ((x_p - y.pixel_in_first_keyframe).norm() < p.r2) return PointDecision::kInvalidSameObject;
  }
  return PointDecision::kKeepOccludedStatic;
}

bool update_landmark_counters(LandmarkCounters& c, LandmarkEvent e, int miss_threshold,
                              int moved_threshold) {
  auto inc = [](uint16_t& v) {
    if (v < UINT16_MAX) ++v;
  };
  switch (e) {
    case LandmarkEvent::kMatchedStill:
      c.missed = 0;
      c.moved = 0;
      return false;
    case LandmarkEvent::kMatchedMoved:
      inc(c.moved);
      return c.moved > moved_threshold;
    case LandmarkEvent::kMissed:
      inc(c.missed);
      return c.missed > miss_threshold;
  }
  return false;
}

bool camera_is_stationary(const ChangeDetectionParams& p, const Eigen::Matrix3d& R_prev,
                          const Eigen::Vector3d& c_prev, const Eigen::Matrix3d& R_cur,
                          const Eigen::Vector3d& c_cur) {
  const Eigen::Matrix3d dR = R_prev.transpose() * R_cur;
  const double cos_angle = std::clamp((dR.trace() - 1.0) * 0.5, -1.0, 1.0);
  const double angle_deg = std::acos(cos_angle) * 180.0 / M_PI;
  return (c_cur - c_prev).norm() < p.stationary_translation &&
         angle_deg < p.stationary_rotation_deg;
}

int reject_by_flow(const cv::Mat& flow, const float* xs, const float* ys, int count,
                   double flow_threshold_px, uint8_t* keep) {
  if (flow.empty() || flow.type() != CV_32FC2) return 0;
  int rejected = 0;
  const double t2 = flow_threshold_px * flow_threshold_px;
  for (int i = 0; i < count; ++i) {
    const int x = static_cast<int>(std::lround(xs[i]));
    const int y = static_cast<int>(std::lround(ys[i]));
    if (x < 0 || y < 0 || x >= flow.cols || y >= flow.rows) continue;
    const cv::Vec2f f = flow.at<cv::Vec2f>(y, x);
    if (double(f[0]) * f[0] + double(f[1]) * f[1] > t2) {
      if (keep[i]) ++rejected;
      keep[i] = 0;
    }
  }
  return rejected;
}

}  // namespace rdslam
