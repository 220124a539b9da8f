// core/image_ops: the allocation-free FAST-9, Gaussian blur and bilinear resize agree with
// OpenCV's cv::FAST (same corners, same scores), cv::GaussianBlur and cv::resize (within one
// grey level of fixed-point rounding), and reuse their buffers between calls.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <tuple>

#include "core/image_ops.h"

namespace rdslam {
namespace {

cv::Mat textured(int w, int h, uint32_t seed, double blur = 1.5) {
  cv::Mat img(h, w, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), blur);
  return img;
}

TEST(ImageOps, FastMatchesOpenCvCornersAndScores) {
  for (const int t : {7, 12, 20}) {
    for (const uint32_t seed : {1u, 2u}) {
      const cv::Mat img = textured(333, 251, seed);
      const int border = 19;
      std::vector<cv::KeyPoint> ref;
      cv::FAST(img, ref, t, true);
      std::set<std::tuple<int, int, int>> want;
      for (const auto& k : ref) {
        const int x = static_cast<int>(k.pt.x), y = static_cast<int>(k.pt.y);
        if (x < border || y < border || x >= img.cols - border || y >= img.rows - border) continue;
        want.insert({x, y, static_cast<int>(k.response)});
      }
      FastDetector fast;
      std::vector<FastCorner> got;
      const int n = fast.detect(img, t, border, got);
      ASSERT_EQ(n, static_cast<int>(got.size()));
      std::set<std::tuple<int, int, int>> have;
      for (const auto& c : got) have.insert({c.x, c.y, c.score});
      ASSERT_GT(want.size(), 100u) << "threshold " << t;
      EXPECT_EQ(have, want) << "threshold " << t << " seed " << seed;
    }
  }
}

TEST(ImageOps, FastFindsASyntheticCornerAndNothingOnAFlatImage) {
  cv::Mat flat(100, 120, CV_8UC1, cv::Scalar(90));
  FastDetector fast;
  std::vector<FastCorner> got;
  EXPECT_EQ(fast.detect(flat, 10, 5, got), 0);
  cv::Mat sq = flat.clone();
  cv::rectangle(sq, cv::Rect(50, 40, 30, 30), cv::Scalar(200), cv::FILLED);
  // Blurred, so the corner's score has a strict maximum (a sharp corner is a plateau).
  cv::GaussianBlur(sq, sq, cv::Size(5, 5), 1.0);
  ASSERT_GT(fast.detect(sq, 10, 5, got), 0);
  bool near_corner = false;
  for (const auto& c : got) near_corner |= std::abs(c.x - 50) <= 2 && std::abs(c.y - 40) <= 2;
  EXPECT_TRUE(near_corner);
  // Bad input: empty, wrong type, smaller than the border.
  EXPECT_EQ(fast.detect(cv::Mat(), 10, 5, got), 0);
  EXPECT_EQ(fast.detect(cv::Mat(50, 50, CV_8UC3), 10, 5, got), 0);
  EXPECT_EQ(fast.detect(sq, 10, 60, got), 0);
}

TEST(ImageOps, FastReusesItsOutputCapacity) {
  const cv::Mat img = textured(320, 240, 3);
  FastDetector fast;
  std::vector<FastCorner> got;
  fast.detect(img, 12, 19, got);
  const FastCorner* data = got.data();
  const size_t cap = got.capacity();
  fast.detect(textured(320, 240, 4), 5, 19, got);
  EXPECT_EQ(got.data(), data);
  EXPECT_EQ(got.capacity(), cap);
}

TEST(ImageOps, BlurWithinOneGreyLevelOfOpenCv) {
  for (const cv::Size sz : {cv::Size(640, 480), cv::Size(37, 23), cv::Size(5, 4)}) {
    const cv::Mat img = textured(sz.width, sz.height, 5, 0.5);
    cv::Mat ref, got;
    cv::GaussianBlur(img, ref, cv::Size(7, 7), 2, 2, cv::BORDER_REFLECT_101);
    GaussianBlur7 blur(2.0);
    blur.apply(img, got);
    ASSERT_EQ(got.size(), img.size());
    cv::Mat diff;
    cv::absdiff(ref, got, diff);
    double mx = 0;
    cv::minMaxLoc(diff, nullptr, &mx);
    EXPECT_LE(mx, 1.0) << sz;
    const uchar* data = got.data;
    blur.apply(img, got);
    EXPECT_EQ(got.data, data) << "the output buffer is reused";
  }
}

TEST(ImageOps, ResizeWithinOneGreyLevelOfOpenCv) {
  const cv::Mat img = textured(640, 480, 6, 0.8);
  BilinearResize rs;
  for (const cv::Size sz : {cv::Size(533, 400), cv::Size(444, 333), cv::Size(370, 278)}) {
    cv::Mat ref, got;
    cv::resize(img, ref, sz, 0, 0, cv::INTER_LINEAR);
    rs.apply(img, got, sz);
    ASSERT_EQ(got.size(), sz);
    cv::Mat diff;
    cv::absdiff(ref, got, diff);
    double mx = 0;
    cv::minMaxLoc(diff, nullptr, &mx);
    EXPECT_LE(mx, 1.0) << sz;
  }
}

}  // namespace
}  // namespace rdslam
