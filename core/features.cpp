#include "core/features.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rdslam {

namespace {

constexpr int kHalfPatch = 15;    // orientation patch radius (ORB)
constexpr int kEdge = 19;         // border so rotated BRIEF tests stay inside the image
constexpr int kPatternClip = 13;  // |x|,|y| of test points: 13*sqrt(2) < kEdge
constexpr int kAngleBins = 32;    // orientation bins of the pre-rotated pattern
// The per-cell fallback detects a cell inside this margin: FAST reads 3 pixels around a
// candidate and the suppression compares its score with its 8 neighbours'.
constexpr int kCellMargin = 4;
static_assert(kEdge >= kCellMargin, "the margin must stay inside the image");

// Deterministic BRIEF test pattern (Calonder et al.'s G II: isotropic Gaussian, sigma = S/5
// for a 31-pixel patch), from a fixed 64-bit LCG and Box-Muller so every build and platform
// uses the same bits.
std::vector<int> make_pattern() {
  uint64_t state = 0x9E3779B97F4A7C15ULL;
  auto uniform = [&state]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((state >> 11) + 0.5) / 9007199254740992.0;  // (0, 1)
  };
  auto gauss = [&]() {
    const double u1 = uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  };
  std::vector<int> p;
  p.reserve(256 * 4);
  while (p.size() < 256 * 4) {
    int v[4];
    for (int& c : v) {
      c = static_cast<int>(std::lround(gauss() * 31.0 / 5.0));
      c = std::max(-kPatternClip, std::min(kPatternClip, c));
    }
    if (v[0] == v[2] && v[1] == v[3]) continue;
    p.insert(p.end(), v, v + 4);
  }
  return p;
}

// Multiplicative hash of a corner position (Knuth's golden-ratio constants).
inline uint32_t position_hash(const FastCorner& c) {
  return (static_cast<uint32_t>(c.x) * 2654435761u) ^ (static_cast<uint32_t>(c.y) * 2246822519u);
}

}  // namespace

void FeatureParams::visit(ParamVisitor& v) {
  v.field("mode", mode, {"orb", "sift"},
          "orb: fast default (FAST + steered BRIEF, grid bucketing); sift: the paper");
  v.field("max_features", max_features, 100, 10000, "features per frame");
  v.field("levels", levels, 1, 8, "ORB pyramid levels");
  v.field("scale_factor", scale_factor, 1.05, 2.0, "ORB pyramid scale between levels");
  v.field("fast_threshold", fast_threshold, 1, 100, "FAST corner threshold (grey levels)");
  v.field("grid_cell_px", grid_cell_px, 8, 256, "bucketing cell size in pixels");
  v.field("min_fast_threshold", min_fast_threshold, 1, 100,
          "FAST threshold of the per-cell fallback (<= fast_threshold; equal: off)");
  v.field("fallback_cell_corners", fallback_cell_corners, 0, 10000,
          "a cell with fewer corners at fast_threshold is re-detected at min_fast_threshold "
          "(0: off)");
  v.field("fallback_last", fallback_last,
          "the fallback's corners only fill what the main threshold's corners leave of a "
          "level's quota (false: ranked with them cell by cell, as ORB-SLAM)");
  v.field("sift_first_octave", sift_first_octave, -1, 0,
          "SIFT first octave: 0 image resolution (SiftGPU default), -1 upsampled 2x (slow)");
}

std::string FeatureParams::validate() const {
  if (max_features < 100) return "features.max_features: must be >= 100";
  if (min_fast_threshold > fast_threshold) {
    return "features.min_fast_threshold: " + std::to_string(min_fast_threshold) +
           " is above features.fast_threshold " + std::to_string(fast_threshold);
  }
  return {};
}

void Features::set_grid_extent(const cv::Rect2d& e) {
  grid_x0 = static_cast<float>(std::floor(e.x));
  grid_y0 = static_cast<float>(std::floor(e.y));
  grid_w = static_cast<float>(std::ceil(e.x + e.width)) - grid_x0;
  grid_h = static_cast<float>(std::ceil(e.y + e.height)) - grid_y0;
}

void Features::build_grid() {
  const float gw = grid_w > 0.f ? grid_w : float(width);
  const float gh = grid_h > 0.f ? grid_h : float(height);
  const float ox = grid_w > 0.f ? grid_x0 : 0.f, oy = grid_h > 0.f ? grid_y0 : 0.f;
  grid_cols = std::max(1, static_cast<int>(std::ceil(gw / cell_px)));
  grid_rows = std::max(1, static_cast<int>(std::ceil(gh / cell_px)));
  const int ncell = grid_cols * grid_rows;
  cell_start.assign(ncell + 1, 0);
  if (static_cast<int>(cell_items.size()) < count) cell_items.resize(kps.size());
  auto cell_of = [&](int i) {
    const int cx = std::min(grid_cols - 1, std::max(0, static_cast<int>((un[i].x - ox) / cell_px)));
    const int cy = std::min(grid_rows - 1, std::max(0, static_cast<int>((un[i].y - oy) / cell_px)));
    return cy * grid_cols + cx;
  };
  for (int i = 0; i < count; ++i) ++cell_start[cell_of(i) + 1];
  for (int c = 0; c < ncell; ++c) cell_start[c + 1] += cell_start[c];
  // Fill using a moving cursor; cell_start is restored afterwards.
  for (int i = 0; i < count; ++i) cell_items[cell_start[cell_of(i)]++] = i;
  for (int c = ncell; c > 0; --c) cell_start[c] = cell_start[c - 1];
  cell_start[0] = 0;
}

int Features::radius_search(float x, float y, float radius, int min_level, int max_level, int* out,
                            int cap) const {
  if (grid_cols == 0) return 0;
  const float ox = grid_w > 0.f ? grid_x0 : 0.f, oy = grid_h > 0.f ? grid_y0 : 0.f;
  const int x0 = std::max(0, static_cast<int>((x - radius - ox) / cell_px));
  const int x1 = std::min(grid_cols - 1, static_cast<int>((x + radius - ox) / cell_px));
  const int y0 = std::max(0, static_cast<int>((y - radius - oy) / cell_px));
  const int y1 = std::min(grid_rows - 1, static_cast<int>((y + radius - oy) / cell_px));
  if (x1 < 0 || y1 < 0 || x0 >= grid_cols || y0 >= grid_rows) return 0;
  const float r2 = radius * radius;
  int n = 0;
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * grid_cols + cx;
      for (int k = cell_start[c]; k < cell_start[c + 1]; ++k) {
        const int i = cell_items[k];
        if (level[i] < min_level || level[i] > max_level) continue;
        const float dx = un[i].x - x, dy = un[i].y - y;
        if (dx * dx + dy * dy > r2) continue;
        if (n < cap) out[n++] = i;
      }
    }
  }
  return n;
}

void Features::copy_from(const Features& o) {
  count = o.count;
  width = o.width;
  height = o.height;
  binary = o.binary;
  if (kps.size() < o.kps.size()) {
    kps.resize(o.kps.size());
    un.resize(o.kps.size());
    scale.resize(o.kps.size());
    level.resize(o.kps.size());
  }
  std::copy(o.kps.begin(), o.kps.begin() + count, kps.begin());
  std::copy(o.un.begin(), o.un.begin() + count, un.begin());
  std::copy(o.scale.begin(), o.scale.begin() + count, scale.begin());
  std::copy(o.level.begin(), o.level.begin() + count, level.begin());
  if (desc.rows < o.desc.rows || desc.type() != o.desc.type() || desc.cols != o.desc.cols) {
    desc.create(o.desc.rows, o.desc.cols, o.desc.type());
  }
  if (count > 0) o.desc.rowRange(0, count).copyTo(desc.rowRange(0, count));
  cell_px = o.cell_px;
  grid_x0 = o.grid_x0;
  grid_y0 = o.grid_y0;
  grid_w = o.grid_w;
  grid_h = o.grid_h;
  build_grid();
}

FeatureExtractor::FeatureExtractor(const FeatureParams& params, const CameraModel& camera)
    : params_(params), camera_(camera) {
  pattern_ = make_pattern();
  // Rotated test points (x, y) for each orientation bin: 256 tests x 2 points.
  rot_xy_.resize(static_cast<size_t>(kAngleBins) * 512 * 2);
  for (int bin = 0; bin < kAngleBins; ++bin) {
    const double a = 2.0 * M_PI * bin / kAngleBins;
    const double ca = std::cos(a), sa = std::sin(a);
    for (int t = 0; t < 256; ++t) {
      for (int e = 0; e < 2; ++e) {
        const int px = pattern_[t * 4 + 2 * e], py = pattern_[t * 4 + 2 * e + 1];
        const size_t k = (static_cast<size_t>(bin) * 512 + t * 2 + e) * 2;
        rot_xy_[k] = static_cast<int>(std::lround(ca * px - sa * py));
        rot_xy_[k + 1] = static_cast<int>(std::lround(sa * px + ca * py));
      }
    }
  }
  // Circular patch bounds for the intensity centroid (as in ORB).
  umax_.assign(kHalfPatch + 1, 0);
  const int vmax = static_cast<int>(std::floor(kHalfPatch * std::sqrt(2.0) / 2 + 1));
  const int vmin = static_cast<int>(std::ceil(kHalfPatch * std::sqrt(2.0) / 2));
  for (int v = 0; v <= vmax; ++v) {
    umax_[v] = static_cast<int>(std::lround(std::sqrt(double(kHalfPatch * kHalfPatch - v * v))));
  }
  for (int v = kHalfPatch, v0 = 0; v >= vmin; --v) {
    while (umax_[v0] == umax_[v0 + 1]) ++v0;
    umax_[v] = v0;
    ++v0;
  }
  const int L = params_.levels;
  level_scale_.resize(L);
  level_quota_.resize(L);
  pyramid_.resize(L);
  resize_.resize(L);
  // A cell holds at most one suppressed FAST maximum per 2x2 pixels: rank histogram bound.
  const int half_cell = params_.grid_cell_px / 2 + 1;
  // With fallback_last the fallback's ranks follow the main ones: twice that.
  rank_hist_.reserve(2 * static_cast<size_t>(half_cell) * half_cell + 2);
  // The fallback's largest cell detection (FastDetector reserves one corner per 2x2 pixels).
  const size_t half_roi = (params_.grid_cell_px + 2 * kCellMargin + 1) / 2;
  cell_buf_.reserve(half_roi * half_roi);
  blurred_.resize(L);
  rot_off_.resize(L);
  rot_step_.assign(L, -1);
  double total = 0;
  for (int l = 0; l < L; ++l) {
    level_scale_[l] = static_cast<float>(std::pow(params_.scale_factor, l));
    total += 1.0 / (level_scale_[l] * level_scale_[l]);
  }
  int assigned = 0;
  for (int l = 0; l < L; ++l) {
    // Quota by level area, so every level contributes in proportion to its pixels.
    level_quota_[l] =
        static_cast<int>(params_.max_features / (level_scale_[l] * level_scale_[l]) / total);
    assigned += level_quota_[l];
  }
  level_quota_[0] += params_.max_features - assigned;
  if (camera_.has_distortion()) {
    std::vector<cv::Point2f> in, out;
    in.reserve(static_cast<size_t>(camera_.width) * camera_.height);
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) in.emplace_back(float(x), float(y));
    }
    camera_.undistort_points(in, out);
    undistort_map_.create(camera_.height, camera_.width, CV_32FC2);
    for (int y = 0; y < camera_.height; ++y) {
      for (int x = 0; x < camera_.width; ++x) {
        undistort_map_.at<cv::Vec2f>(y, x) =
            cv::Vec2f(out[y * camera_.width + x].x, out[y * camera_.width + x].y);
      }
    }
  }
  grid_extent_ = camera_.ideal_extent();
  if (params_.is_sift()) sift_ = cv::SIFT::create(params_.max_features);
}

void FeatureExtractor::prepare(Features& out, int w, int h) const {
  const size_t cap = static_cast<size_t>(params_.max_features) + 64;
  if (out.kps.size() < cap) {
    out.kps.resize(cap);
    out.un.resize(cap);
    out.scale.resize(cap);
    out.level.resize(cap);
    out.cell_items.resize(cap);
  }
  const int type = params_.is_sift() ? CV_32F : CV_8U;
  const int cols = params_.is_sift() ? 128 : 32;
  if (out.desc.rows < static_cast<int>(cap) || out.desc.type() != type || out.desc.cols != cols) {
    out.desc.create(static_cast<int>(cap), cols, type);
  }
  out.binary = params_.binary();
  out.width = w;
  out.height = h;
  out.count = 0;
  out.cell_px = static_cast<float>(std::max(16, params_.grid_cell_px / 2));
  out.set_grid_extent(grid_extent_);
}

void FeatureExtractor::extract(const cv::Mat& gray, Features& out) {
  if (gray.empty() || gray.type() != CV_8UC1) {
    out.count = 0;
    out.build_grid();
    return;
  }
  prepare(out, gray.cols, gray.rows);
  if (params_.is_sift()) {
    extract_sift(gray, out);
  } else {
    extract_orb(gray, out);
  }
  undistort(out);
  out.build_grid();
}

void FeatureExtractor::extract_orb(const cv::Mat& gray, Features& out) {
  const int L = params_.levels;
  pyramid_[0] = gray;
  for (int l = 1; l < L; ++l) {
    const cv::Size sz(static_cast<int>(std::lround(gray.cols / level_scale_[l])),
                      static_cast<int>(std::lround(gray.rows / level_scale_[l])));
    resize_[l].apply(pyramid_[l - 1], pyramid_[l], sz);
  }
  const int cell = params_.grid_cell_px;
  for (int l = 0; l < L; ++l) {
    const cv::Mat& img = pyramid_[l];
    if (img.cols <= 2 * kEdge + 1 || img.rows <= 2 * kEdge + 1) continue;
    const float sx = float(gray.cols) / img.cols, sy = float(gray.rows) / img.rows;
    blur_.apply(img, blurred_[l]);
    // Corners at least kEdge from the border, so rotated BRIEF tests stay inside the image.
    fast_.detect(img, params_.fast_threshold, kEdge, fast_buf_);
    cell_fallback(img);
    // Strongest first. FAST scores are small integers, so ties are common and decide which
    // cells get a corner at the quota cut below: ties are broken by a hash of the position
    // (a deterministic total order without favouring any image region, as a raster order
    // would favour the top rows).
    std::sort(fast_buf_.begin(), fast_buf_.end(), [](const FastCorner& a, const FastCorner& b) {
      if (a.score != b.score) return a.score > b.score;
      const uint32_t ha = position_hash(a), hb = position_hash(b);
      if (ha != hb) return ha < hb;
      return a.y != b.y ? a.y < b.y : a.x < b.x;
    });
    // Grid bucketing: rank each corner within its cell (strongest first) and keep corners in
    // rank order, so weak cells are served before strong cells get their second corner.
    const int gc = (img.cols + cell - 1) / cell, gr = (img.rows + cell - 1) / cell;
    cell_count_.assign(static_cast<size_t>(gc) * gr, 0);
    if (rank_buf_.size() < fast_buf_.size()) rank_buf_.resize(fast_buf_.capacity());
    int max_rank = 0;
    for (size_t i = 0; i < fast_buf_.size(); ++i) {
      const int c = fast_buf_[i].y / cell * gc + fast_buf_[i].x / cell;
      rank_buf_[i] = cell_count_[c]++;
      max_rank = std::max(max_rank, rank_buf_[i]);
    }
    if (params_.fallback_last) {
      // The fallback's corners only fill what the main threshold's corners leave of the
      // quota: ranked after every one of them.
      int main_max = -1;
      for (size_t i = 0; i < fast_buf_.size(); ++i) {
        if (fast_buf_[i].score >= params_.fast_threshold)
          main_max = std::max(main_max, rank_buf_[i]);
      }
      for (size_t i = 0; i < fast_buf_.size(); ++i) {
        if (fast_buf_[i].score < params_.fast_threshold) {
          rank_buf_[i] += main_max + 1;
          max_rank = std::max(max_rank, rank_buf_[i]);
        }
      }
    }
    const int quota = level_quota_[l];
    // Rank cut-off: all corners of rank < cut, then rank == cut (strongest first) to fill.
    rank_hist_.assign(static_cast<size_t>(max_rank) + 2, 0);
    for (size_t i = 0; i < fast_buf_.size(); ++i) ++rank_hist_[rank_buf_[i]];
    int cut = 0, below = 0;
    while (cut <= max_rank && below + rank_hist_[cut] <= quota) below += rank_hist_[cut++];
    int room_at_cut = quota - below;
    int taken = 0;
    {
      for (size_t i = 0; i < fast_buf_.size() && taken < quota; ++i) {
        if (rank_buf_[i] > cut) continue;
        if (rank_buf_[i] == cut) {
          if (room_at_cut <= 0) continue;
          --room_at_cut;
        }
        if (out.count >= static_cast<int>(out.kps.size())) break;
        const FastCorner& kp = fast_buf_[i];
        const int x = kp.x, y = kp.y;
        // Intensity centroid orientation (Rosin), circular patch of radius 15.
        const uchar* center = img.ptr<uchar>(y) + x;
        const int step = static_cast<int>(img.step1());
        int m01 = 0, m10 = 0;
        for (int u = -kHalfPatch; u <= kHalfPatch; ++u) m10 += u * center[u];
        for (int v = 1; v <= kHalfPatch; ++v) {
          int vsum = 0;
          const int d = umax_[v];
          for (int u = -d; u <= d; ++u) {
            const int val_plus = center[u + v * step], val_minus = center[u - v * step];
            vsum += (val_plus - val_minus);
            m10 += u * (val_plus + val_minus);
          }
          m01 += v * vsum;
        }
        const float angle = std::atan2(static_cast<float>(m01), static_cast<float>(m10));
        // Steered BRIEF on the smoothed level image, with the test pattern pre-rotated to
        // kAngleBins orientations (as ORB's lookup table; 11.25 degree bins).
        const cv::Mat& b = blurred_[l];
        const uchar* bc = b.ptr<uchar>(y) + x;
        const int bstep = static_cast<int>(b.step1());
        if (rot_step_[l] != bstep) {
          rot_step_[l] = bstep;
          rot_off_[l].resize(static_cast<size_t>(kAngleBins) * 512);
          for (int bin = 0; bin < kAngleBins; ++bin) {
            for (int k = 0; k < 512; ++k) {
              rot_off_[l][bin * 512 + k] =
                  rot_xy_[(bin * 512 + k) * 2 + 1] * bstep + rot_xy_[(bin * 512 + k) * 2];
            }
          }
        }
        int bin = static_cast<int>(std::lround(angle * (kAngleBins / (2.0f * float(M_PI)))));
        bin = ((bin % kAngleBins) + kAngleBins) % kAngleBins;
        const int* off = &rot_off_[l][bin * 512];
        uint8_t* d = out.desc.ptr<uint8_t>(out.count);
        for (int byte = 0; byte < 32; ++byte) {
          uint8_t val = 0;
          for (int bit = 0; bit < 8; ++bit) {
            const int k = (byte * 8 + bit) * 2;
            val |= static_cast<uint8_t>((bc[off[k]] < bc[off[k + 1]]) << bit);
          }
          d[byte] = val;
        }
        cv::KeyPoint& o = out.kps[out.count];
        // Level pixel centre -> level-0 pixel: the pyramid's resampling is pixel-centre
        // aligned (core/image_ops.h BilinearResize), so x0 = (x + 0.5) W0 / Wl - 0.5, not
        // x * scale (that is 0.1-0.4 px off towards the top-left on levels 1-3).
        o.pt = cv::Point2f((x + 0.5f) * sx - 0.5f, (y + 0.5f) * sy - 0.5f);
        o.size = 31.f * level_scale_[l];
        o.angle = angle * 180.f / static_cast<float>(M_PI);
        o.response = kp.score;
        o.octave = l;
        out.level[out.count] = l;
        out.scale[out.count] = level_scale_[l];
        ++out.count;
        ++taken;
      }
    }
  }
}

void FeatureExtractor::cell_fallback(const cv::Mat& img) {
  const int lo = params_.min_fast_threshold, hi = params_.fast_threshold;
  if (lo >= hi || params_.fallback_cell_corners <= 0) return;
  const int cell = params_.grid_cell_px;
  const int gc = (img.cols + cell - 1) / cell, gr = (img.rows + cell - 1) / cell;
  cell_count_.assign(static_cast<size_t>(gc) * gr, 0);
  for (const FastCorner& c : fast_buf_) ++cell_count_[c.y / cell * gc + c.x / cell];
  // Detected inside kCellMargin, a cell gets exactly the corners a whole-level detection at
  // `lo` would give there.
  for (int cy = 0; cy < gr; ++cy) {
    for (int cx = 0; cx < gc; ++cx) {
      if (cell_count_[static_cast<size_t>(cy) * gc + cx] >= params_.fallback_cell_corners) {
        continue;
      }
      // The cell, clipped to where corners are allowed (kEdge from the border).
      const int x0 = std::max(cx * cell, kEdge), x1 = std::min((cx + 1) * cell, img.cols - kEdge);
      const int y0 = std::max(cy * cell, kEdge), y1 = std::min((cy + 1) * cell, img.rows - kEdge);
      if (x0 >= x1 || y0 >= y1) continue;
      const cv::Rect roi(x0 - kCellMargin, y0 - kCellMargin, x1 - x0 + 2 * kCellMargin,
                         y1 - y0 + 2 * kCellMargin);
      fast_.detect(img(roi), lo, kCellMargin, cell_buf_);
      for (FastCorner c : cell_buf_) {
        // Corners at or above `hi` are already in fast_buf_ (same position and score).
        if (c.score >= hi) continue;
        c.x = static_cast<int16_t>(c.x + roi.x);
        c.y = static_cast<int16_t>(c.y + roi.y);
        // fast_buf_'s capacity bounds any whole-level detection (one corner per 2x2
        // pixels), which these corners and the main ones together are part of.
        if (fast_buf_.size() < fast_buf_.capacity()) fast_buf_.push_back(c);
      }
    }
  }
}

void FeatureExtractor::extract_sift(const cv::Mat& gray, Features& out) {
  sift_kps_.clear();
  // OpenCV's SIFT always upsamples its input 2x (first octave -1); on the half-size image
  // that is first octave 0 on the full-size image (4x fewer pixels in the scale space).
  const bool half = params_.sift_first_octave == 0 && gray.cols >= 64 && gray.rows >= 64;
  if (half) {
    cv::resize(gray, sift_half_, cv::Size(gray.cols / 2, gray.rows / 2), 0, 0, cv::INTER_AREA);
    sift_->detectAndCompute(sift_half_, cv::noArray(), sift_kps_, sift_desc_);
    const float sx = float(gray.cols) / sift_half_.cols, sy = float(gray.rows) / sift_half_.rows;
    for (cv::KeyPoint& kp : sift_kps_) {
      // Pixel centres: half-size pixel u covers full-size pixels 2u and 2u+1.
      kp.pt.x = (kp.pt.x + 0.5f) * sx - 0.5f;
      kp.pt.y = (kp.pt.y + 0.5f) * sy - 0.5f;
      kp.size *= sx;
      // One octave finer in full-size terms (octave is packed in the low byte).
      const int oct = kp.octave & 255;
      kp.octave = (kp.octave & ~255) | ((oct + 1) & 255);
    }
  } else {
    sift_->detectAndCompute(gray, cv::noArray(), sift_kps_, sift_desc_);
  }
  const int n = std::min(static_cast<int>(sift_kps_.size()), static_cast<int>(out.kps.size()));
  for (int i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = sift_kps_[i];
    int octave = kp.octave & 255;
    if (octave >= 128) octave -= 256;
    out.kps[i] = kp;
    out.level[i] = std::max(0, octave + 1);
    // Localisation noise grows with the detection scale.
    out.scale[i] = std::max(1.f, kp.size / 6.f);
    sift_desc_.row(i).copyTo(out.desc.row(i));
  }
  out.count = n;
}

void FeatureExtractor::undistort(Features& out) const {
  for (int i = 0; i < out.count; ++i) {
    const cv::Point2f p = out.kps[i].pt;
    if (undistort_map_.empty()) {
      out.un[i] = p;
      continue;
    }
    // Bilinear interpolation of the per-pixel undistortion table.
    const float fx = std::min(std::max(p.x, 0.f), float(undistort_map_.cols - 1.001f));
    const float fy = std::min(std::max(p.y, 0.f), float(undistort_map_.rows - 1.001f));
    const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
    const float ax = fx - x0, ay = fy - y0;
    const cv::Vec2f a = undistort_map_.at<cv::Vec2f>(y0, x0);
    const cv::Vec2f b = undistort_map_.at<cv::Vec2f>(y0, x0 + 1);
    const cv::Vec2f c = undistort_map_.at<cv::Vec2f>(y0 + 1, x0);
    const cv::Vec2f d = undistort_map_.at<cv::Vec2f>(y0 + 1, x0 + 1);
    const cv::Vec2f r = (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * c + ax * d);
    out.un[i] = cv::Point2f(r[0], r[1]);
  }
}

}  // namespace rdslam
