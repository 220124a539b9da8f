// core/features: the fast ORB mode covers the image (grid bucketing), respects the feature
// budget, is deterministic, finds the same corners with the same descriptors in a shifted
// image, and the radius search agrees with brute force. The per-cell FAST fallback equals a
// detection at the lower threshold in the cells it re-detects and leaves the other cells
// alone.
#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <random>

#include "core/features.h"

namespace rdslam {
namespace {

cv::Mat textured(int w, int h, uint32_t seed) {
  cv::Mat img(h, w, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  return img;
}

// `img` with its contrast scaled by `c` about grey level `mean`.
cv::Mat low_contrast(const cv::Mat& img, double c, double mean) {
  cv::Mat out;
  img.convertTo(out, CV_8U, c, mean * (1.0 - c));
  return out;
}

CameraModel cam(int w, int h) {
  CameraModel c;
  c.width = w;
  c.height = h;
  c.cx = w / 2.0;
  c.cy = h / 2.0;
  return c;
}

TEST(Features, BudgetCoverageAndDeterminism) {
  const cv::Mat img = textured(640, 480, 1);
  FeatureParams p;
  FeatureExtractor ex(p, cam(640, 480));
  Features a, b;
  ex.extract(img, a);
  ex.extract(img, b);
  ASSERT_GT(a.count, p.max_features / 2);
  EXPECT_LE(a.count, p.max_features);
  ASSERT_EQ(a.count, b.count);
  EXPECT_EQ(cv::norm(a.desc.rowRange(0, a.count), b.desc.rowRange(0, b.count), cv::NORM_HAMMING),
            0.0);
  // Every 80x80 block of the image holds features (bucketing, not clustering).
  int blocks = 0, covered = 0;
  for (int by = 0; by < 6; ++by) {
    for (int bx = 0; bx < 8; ++bx) {
      ++blocks;
      for (int i = 0; i < a.count; ++i) {
        if (int(a.un[i].x) / 80 == bx && int(a.un[i].y) / 80 == by) {
          ++covered;
          break;
        }
      }
    }
  }
  EXPECT_GE(covered, blocks - 4);
}

TEST(Features, ShiftedImageGivesMatchingDescriptors) {
  const cv::Mat big = textured(700, 520, 2);
  const cv::Mat a_img = big(cv::Rect(0, 0, 640, 480)).clone();
  const cv::Mat b_img = big(cv::Rect(7, 5, 640, 480)).clone();  // content moves by (-7, -5)
  FeatureParams p;
  FeatureExtractor ex(p, cam(640, 480));
  Features a, b;
  ex.extract(a_img, a);
  ex.extract(b_img, b);
  int same = 0, good = 0;
  for (int i = 0; i < a.count; ++i) {
    if (a.level[i] != 0) continue;
    int cand[16];
    const int n = b.radius_search(a.un[i].x - 7, a.un[i].y - 5, 0.5f, 0, 0, cand, 16);
    if (n == 0) continue;
    ++same;
    good += hamming256(a.desc_ptr(i), b.desc_ptr(cand[0])) <= 10;
  }
  ASSERT_GT(same, 200);
  EXPECT_GT(good, 0.95 * same);
}

TEST(Features, RadiusSearchMatchesBruteForce) {
  FeatureParams p;
  FeatureExtractor ex(p, cam(640, 480));
  Features f;
  ex.extract(textured(640, 480, 3), f);
  std::vector<int> out(4096);
  for (int q = 0; q < 50; ++q) {
    const float x = 13.f * q, y = 9.f * q, r = 25.f;
    const int n = f.radius_search(x, y, r, 0, 100, out.data(), 4096);
    int brute = 0;
    for (int i = 0; i < f.count; ++i) {
      const float dx = f.un[i].x - x, dy = f.un[i].y - y;
      brute += dx * dx + dy * dy <= r * r;
    }
    EXPECT_EQ(n, brute);
  }
}

// Through a lens the ideal (undistorted) coordinates of border features lie far outside the
// ideal rectangle (a 150-degree fisheye's corners about 900 px out): the grid covers the
// camera's ideal_extent(), so the radius search finds every one of them, as brute force does.
TEST(Features, RadiusSearchFindsLensBorderFeaturesBeyondTheRectangle) {
  FeatureParams p;
  CameraModel c = cam(640, 480);
  c.model = "pinhole-equidistant";
  c.fx = c.fy = 305;
  c.cx = 319.5;
  c.cy = 239.5;
  FeatureExtractor ex(p, c);
  Features f;
  ex.extract(textured(640, 480, 5), f);
  ASSERT_GT(f.count, 500);
  std::vector<int> out(4096);
  int outside = 0;
  for (int i = 0; i < f.count; ++i) {
    const float x = f.un[i].x, y = f.un[i].y;
    if (x >= 0 && y >= 0 && x < 640 && y < 480) continue;
    ++outside;
    const float r = 6.f;
    const int n = f.radius_search(x, y, r, 0, 100, out.data(), 4096);
    int brute = 0;
    for (int k = 0; k < f.count; ++k) {
      const float dx = f.un[k].x - x, dy = f.un[k].y - y;
      brute += dx * dx + dy * dy <= r * r;
    }
    EXPECT_EQ(n, brute) << "feature " << i << " at ideal (" << x << ", " << y << ")";
    EXPECT_GE(n, 1);
  }
  // A good share of a fisheye's features lies outside the ideal rectangle.
  EXPECT_GT(outside, f.count / 5);
}

TEST(Features, BadInputGivesNoFeatures) {
  FeatureParams p;
  FeatureExtractor ex(p, cam(640, 480));
  Features f;
  ex.extract(cv::Mat(), f);
  EXPECT_EQ(f.count, 0);
  ex.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)), f);  // black frame
  EXPECT_EQ(f.count, 0);
}

void expect_same_features(const Features& a, const Features& b) {
  ASSERT_EQ(a.count, b.count);
  for (int i = 0; i < a.count; ++i) {
    ASSERT_EQ(a.kps[i].pt, b.kps[i].pt) << i;
    ASSERT_EQ(a.level[i], b.level[i]) << i;
    ASSERT_EQ(a.kps[i].response, b.kps[i].response) << i;
  }
  EXPECT_EQ(cv::norm(a.desc.rowRange(0, a.count), b.desc.rowRange(0, b.count), cv::NORM_HAMMING),
            0.0);
}

TEST(Features, CellFallbackEqualsLowThresholdDetectionInTheCellsItRedetects) {
  // A low-contrast image: most of its corners score between the two thresholds.
  const cv::Mat img = low_contrast(textured(640, 480, 4), 0.25, 128);
  FeatureParams low;
  low.fast_threshold = 6;
  low.min_fast_threshold = 6;  // no fallback: one detection at 6
  FeatureParams fb;
  fb.fast_threshold = 14;
  fb.min_fast_threshold = 6;
  fb.fallback_cell_corners = 100000;  // every cell is re-detected
  fb.fallback_last = false;           // ranked with the others, as one detection would be
  FeatureParams high = fb;
  high.min_fast_threshold = high.fast_threshold;  // no fallback: one detection at 14
  FeatureExtractor ex_low(low, cam(640, 480)), ex_fb(fb, cam(640, 480)),
      ex_high(high, cam(640, 480));
  Features a, b, c;
  ex_low.extract(img, a);
  ex_fb.extract(img, b);
  ex_high.extract(img, c);
  ASSERT_GT(a.count, 2 * c.count) << "the image does not starve the high threshold";
  // Cell borders, the border margin and the suppression's neighbours across cell edges: the
  // cell-by-cell re-detection must reproduce the whole-image detection exactly.
  expect_same_features(a, b);
}

// The left `bright` columns as photographed, the rest at 25% contrast (a dim part of the room).
cv::Mat part_dim(int bright = 320) {
  const cv::Mat base = textured(640, 480, 5);
  cv::Mat img = base.clone();
  const cv::Rect dim(bright, 0, 640 - bright, 480);
  low_contrast(base(dim), 0.25, 60).copyTo(img(dim));
  return img;
}

// Threshold 12, and 5 in the cells without a corner at 12.
FeatureParams fallback_params(bool last) {
  FeatureParams p;
  p.fast_threshold = 12;
  p.min_fast_threshold = 5;
  p.fallback_cell_corners = 1;
  p.fallback_last = last;
  return p;
}

TEST(Features, CellFallbackServesDimCellsAndLeavesTexturedCellsAlone) {
  const cv::Mat img = part_dim();
  // Cell by cell: the dim cells' corners rank with the others.
  const FeatureParams p = fallback_params(false);
  FeatureParams off = p;
  off.fallback_cell_corners = 0;
  FeatureExtractor ex(p, cam(640, 480)), ex_off(off, cam(640, 480));
  Features with, without;
  ex.extract(img, with);
  ex_off.extract(img, without);
  auto right = [](const Features& f, int* weak, int thr) {
    int n = 0;
    *weak = 0;
    for (int i = 0; i < f.count; ++i) {
      if (f.kps[i].pt.x < 330) continue;
      ++n;
      *weak += f.kps[i].response < thr;
    }
    return n;
  };
  int weak_with = 0, weak_without = 0;
  const int n_with = right(with, &weak_with, p.fast_threshold);
  const int n_without = right(without, &weak_without, p.fast_threshold);
  EXPECT_EQ(weak_without, 0);
  std::printf("dim half: %d features with the fallback (%d below the threshold), %d without\n",
              n_with, weak_with, n_without);
  EXPECT_LT(n_without, 0.05 * without.count);
  EXPECT_GT(n_with, 0.25 * with.count);
  // Only starved cells are re-detected: every corner under the main threshold lies in the dim
  // half or in a cell straddling its edge (cells are 40 pixels of their level: up to
  // 40 x 1.2^3 = 69 image pixels on level 3).
  for (int i = 0; i < with.count; ++i) {
    if (with.kps[i].response < p.fast_threshold) {
      EXPECT_GE(with.kps[i].pt.x, 320.f - 70.f) << i;
    }
  }
}

TEST(Features, FallbackLastOnlyFillsWhatTheMainThresholdLeavesOfTheBudget) {
  const cv::Mat img = part_dim();
  const FeatureParams p = fallback_params(true);
  FeatureParams off = p;
  off.min_fast_threshold = off.fast_threshold;
  // The default budget (1200), which the textured half fills at the main threshold on every
  // pyramid level: the fallback changes nothing.
  {
    FeatureExtractor ex(p, cam(640, 480)), ex_off(off, cam(640, 480));
    Features a, b;
    ex.extract(img, a);
    ex_off.extract(img, b);
    ASSERT_EQ(b.count, p.max_features);
    expect_same_features(a, b);
  }
  // All at 25% contrast: the main threshold does not fill the budget; every main-threshold
  // feature is kept, and the fallback's fill more of it.
  const cv::Mat mostly_dim = part_dim(0);
  FeatureExtractor ex(p, cam(640, 480)), ex_off(off, cam(640, 480));
  Features with, without;
  ex.extract(mostly_dim, with);
  ex_off.extract(mostly_dim, without);
  ASSERT_LT(without.count, p.max_features);
  EXPECT_GT(with.count, without.count + 200);
  int strong = 0;
  for (int i = 0; i < with.count; ++i) strong += with.kps[i].response >= p.fast_threshold;
  EXPECT_EQ(strong, without.count);
}

}  // namespace
}  // namespace rdslam
