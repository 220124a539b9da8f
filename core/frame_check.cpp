#include "core/frame_check.h"

#include <algorithm>

namespace rdslam {

namespace {

struct GridStats {
  int min = 255, max = 0;
  double mean = 0.0;
};

// At most 32 x 24 samples, evenly spread; one byte per pixel (grey, or green of BGR).
GridStats sample_grid(const cv::Mat& img) {
  const int nx = std::min(32, img.cols), ny = std::min(24, img.rows);
  const int channels = img.channels();
  const int offset = channels == 3 ? 1 : 0;
  GridStats g;
  int64_t sum = 0;
  for (int j = 0; j < ny; ++j) {
    const int y = static_cast<int>((static_cast<int64_t>(2 * j + 1) * img.rows) / (2 * ny));
    const uint8_t* row = img.ptr<uint8_t>(y);
    for (int i = 0; i < nx; ++i) {
      const int x = static_cast<int>((static_cast<int64_t>(2 * i + 1) * img.cols) / (2 * nx));
      const int v = row[x * channels + offset];
      g.min = std::min(g.min, v);
      g.max = std::max(g.max, v);
      sum += v;
    }
  }
  g.mean = static_cast<double>(sum) / (nx * ny);
  return g;
}

}  // namespace

FrameCheckResult FrameCheck::check(const Frame& f) {
  FrameCheckResult r;
  const int want_type = f.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  if (f.image.empty() || f.image.type() != want_type ||
      (have_first_ && (f.image.cols != width_ || f.image.rows != height_))) {
    r.verdict = FrameVerdict::kInvalid;
    return r;
  }
  if (have_first_ && f.stamp_ns <= last_stamp_ns_) {
    r.verdict = FrameVerdict::kStampNotIncreasing;
    return r;
  }
  if (!have_first_) {
    have_first_ = true;
    width_ = f.image.cols;
    height_ = f.image.rows;
  }
  last_stamp_ns_ = f.stamp_ns;
  const GridStats g = sample_grid(f.image);
  r.blank = g.max - g.min <= kBlankRange;
  if (r.blank) return r;
  if (last_mean_ >= kExposureMinMean || g.mean >= kExposureMinMean) {
    const double lo = std::max(std::min(last_mean_, g.mean), 1.0);
    const double hi = std::max(last_mean_, g.mean);
    r.exposure_jump = last_mean_ >= 0.0 && hi > kExposureJumpRatio * lo;
  }
  last_mean_ = g.mean;
  return r;
}

}  // namespace rdslam
