// core/features: the fast ORB mode covers the image (grid bucketing), respects the feature
// budget, is deterministic, finds the same corners with the same descriptors in a shifted
// image, and the radius search agrees with brute force.
#include <gtest/gtest.h>

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

TEST(Features, BadInputGivesNoFeatures) {
  FeatureParams p;
  FeatureExtractor ex(p, cam(640, 480));
  Features f;
  ex.extract(cv::Mat(), f);
  EXPECT_EQ(f.count, 0);
  ex.extract(cv::Mat(480, 640, CV_8UC1, cv::Scalar(0)), f);  // black frame
  EXPECT_EQ(f.count, 0);
}

}  // namespace
}  // namespace rdslam
