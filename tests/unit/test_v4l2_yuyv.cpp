// YUYV conversion on real footage: raw yuyv422 frames made by ffmpeg from vtest.avi,
// converted by yuyv_to_image, compared with ffmpeg's own conversion of the same bytes.
#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/core.hpp>

#include "drivers/yuyv.h"
#include "tests/unit/v4l2_test_footage.h"

namespace rdslam {
namespace {

using namespace rdslam::testing;

class YuyvFootage : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string why = footage_unavailable();
    if (!why.empty()) GTEST_SKIP() << "YUYV footage test skipped: " << why;
    ASSERT_FALSE(dir_.path().empty());
    ASSERT_TRUE(make_yuyv_frames(dir_)) << "ffmpeg could not make YUYV frames";
    yuyv_ = read_bytes(dir_.file("yuyv.raw"));
    ASSERT_EQ(yuyv_.size(), static_cast<size_t>(kW) * kH * 2 * kFrames);
  }
  TempDir dir_;
  std::vector<uint8_t> yuyv_;
};

void expect_close(const cv::Mat& got, const uint8_t* ref, double mean_tol, int max_tol, int i) {
  const cv::Mat r(got.rows, got.cols, got.type(), const_cast<uint8_t*>(ref));
  cv::Mat d;
  cv::absdiff(got, r, d);
  double mx = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &mx);
  const cv::Scalar m = cv::mean(d);
  double mean = 0;
  for (int c = 0; c < got.channels(); ++c) mean += m[c];
  mean /= got.channels();
  std::printf("yuyv %s frame %d vs ffmpeg: mean |diff| %.3f, max %.0f\n",
              got.channels() == 3 ? "bgr" : "grey", i, mean, mx);
  EXPECT_LT(mean, mean_tol) << "frame " << i;
  EXPECT_LE(mx, max_tol) << "frame " << i;
}

TEST_F(YuyvFootage, BgrMatchesFfmpeg) {
  ASSERT_TRUE(convert_yuyv_with_ffmpeg(dir_, "bgr24", "ref_bgr.raw"));
  const auto ref = read_bytes(dir_.file("ref_bgr.raw"));
  const size_t in_bytes = static_cast<size_t>(kW) * kH * 2;
  const size_t out_bytes = static_cast<size_t>(kW) * kH * 3;
  ASSERT_EQ(ref.size(), out_bytes * kFrames);
  cv::Mat out(kH, kW, CV_8UC3);
  const uint8_t* data_before = out.data;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(yuyv_to_image(yuyv_.data() + in_bytes * i, in_bytes, kW, kH, kW * 2, out));
    // Same BT.601 limited-range matrix; swscale's fixed-point rounding differs by a few
    // levels (measured: mean 1.07, max 3 on these frames).
    expect_close(out, ref.data() + out_bytes * i, 1.5, 4, i);
  }
  EXPECT_EQ(out.data, data_before);
}

TEST_F(YuyvFootage, GreyMatchesFfmpeg) {
  ASSERT_TRUE(convert_yuyv_with_ffmpeg(dir_, "gray", "ref_gray.raw"));
  const auto ref = read_bytes(dir_.file("ref_gray.raw"));
  const size_t in_bytes = static_cast<size_t>(kW) * kH * 2;
  const size_t out_bytes = static_cast<size_t>(kW) * kH;
  ASSERT_EQ(ref.size(), out_bytes * kFrames);
  cv::Mat out(kH, kW, CV_8UC1);
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(yuyv_to_image(yuyv_.data() + in_bytes * i, in_bytes, kW, kH, kW * 2, out));
    expect_close(out, ref.data() + out_bytes * i, 0.1, 1, i);
  }
}

TEST_F(YuyvFootage, PaddedStrideIsHonoured) {
  // Some drivers pad rows (bytesperline > 2*width).
  const size_t stride = static_cast<size_t>(kW) * 2 + 64;
  std::vector<uint8_t> padded(stride * kH, 0xAB);
  for (int r = 0; r < kH; ++r) {
    std::copy_n(yuyv_.data() + static_cast<size_t>(r) * kW * 2, kW * 2, padded.data() + stride * r);
  }
  cv::Mat a(kH, kW, CV_8UC3), b(kH, kW, CV_8UC3);
  ASSERT_TRUE(yuyv_to_image(yuyv_.data(), static_cast<size_t>(kW) * kH * 2, kW, kH, kW * 2, a));
  ASSERT_TRUE(yuyv_to_image(padded.data(), padded.size(), kW, kH, stride, b));
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

TEST(Yuyv, ShortBufferAndBadShapesAreRejected) {
  std::vector<uint8_t> buf(64 * 48 * 2, 128);
  cv::Mat out(48, 64, CV_8UC3, cv::Scalar(7, 7, 7));
  EXPECT_FALSE(yuyv_to_image(buf.data(), buf.size() - 1, 64, 48, 128, out));  // short frame
  EXPECT_FALSE(yuyv_to_image(buf.data(), buf.size(), 63, 48, 128, out));      // odd width
  EXPECT_FALSE(yuyv_to_image(buf.data(), buf.size(), 64, 48, 100, out));      // stride < 2w
  EXPECT_FALSE(yuyv_to_image(nullptr, buf.size(), 64, 48, 128, out));
  cv::Mat wrong(48, 32, CV_8UC3);
  EXPECT_FALSE(yuyv_to_image(buf.data(), buf.size(), 64, 48, 128, wrong));
  cv::Mat wrong_type(48, 64, CV_16UC1);
  EXPECT_FALSE(yuyv_to_image(buf.data(), buf.size(), 64, 48, 128, wrong_type));
  EXPECT_EQ(out.at<cv::Vec3b>(0, 0), cv::Vec3b(7, 7, 7)) << "rejected input must not write";
}

TEST(Yuyv, LimitedRangeEndpointsMapToFullRange) {
  // Y=16 is black, Y=235 is white; neutral chroma 128 gives grey levels.
  const uint8_t px[8] = {16, 128, 235, 128, 126, 128, 126, 128};
  cv::Mat bgr(1, 4, CV_8UC3), grey(1, 4, CV_8UC1);
  ASSERT_TRUE(yuyv_to_image(px, sizeof(px), 4, 1, 8, bgr));
  ASSERT_TRUE(yuyv_to_image(px, sizeof(px), 4, 1, 8, grey));
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 1), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(grey.at<uint8_t>(0, 0), 0);
  EXPECT_EQ(grey.at<uint8_t>(0, 1), 255);
  EXPECT_NEAR(grey.at<uint8_t>(0, 2), 128, 1);
}

}  // namespace
}  // namespace rdslam
