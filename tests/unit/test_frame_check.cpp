// core/frame_check.h: what the pipeline's capture thread rejects (zero-size images, wrong
// pixel type or size, stamps that do not increase) and what it counts but passes on (blank
// frames, exposure jumps).
#include "core/frame_check.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

namespace rdslam {
namespace {

Frame textured(int64_t stamp_ns, double gain = 1.0) {
  Frame f;
  f.image.create(48, 64, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(f.image, cv::RNG::UNIFORM, 40, 160);
  f.image.convertTo(f.image, -1, gain, 0.0);
  f.stamp_ns = stamp_ns;
  return f;
}

TEST(FrameCheck, RejectsEmptyWrongTypeAndWrongSize) {
  FrameCheck c;
  Frame empty;
  EXPECT_EQ(c.check(empty).verdict, FrameVerdict::kInvalid);
  Frame bgr_as_gray = textured(0);
  bgr_as_gray.format = PixelFormat::kBgr8;  // the image is CV_8UC1
  EXPECT_EQ(c.check(bgr_as_gray).verdict, FrameVerdict::kInvalid);
  EXPECT_EQ(c.check(textured(0)).verdict, FrameVerdict::kOk);  // first frame: 64 x 48
  Frame bigger = textured(1);
  bigger.image.create(96, 64, CV_8UC1);
  bigger.image.setTo(cv::Scalar(50));
  EXPECT_EQ(c.check(bigger).verdict, FrameVerdict::kInvalid);
  EXPECT_EQ(c.check(textured(2)).verdict, FrameVerdict::kOk);
}

TEST(FrameCheck, RejectsStampsThatDoNotIncrease) {
  FrameCheck c;
  EXPECT_EQ(c.check(textured(100)).verdict, FrameVerdict::kOk);
  EXPECT_EQ(c.check(textured(100)).verdict, FrameVerdict::kStampNotIncreasing);  // duplicate
  EXPECT_EQ(c.check(textured(50)).verdict, FrameVerdict::kStampNotIncreasing);   // backwards
  EXPECT_EQ(c.check(textured(101)).verdict, FrameVerdict::kOk);
  // A rejected frame does not move the reference: 150 is compared with 101, not with 200.
  Frame bad = textured(200);
  bad.image = cv::Mat();
  EXPECT_EQ(c.check(bad).verdict, FrameVerdict::kInvalid);
  EXPECT_EQ(c.check(textured(150)).verdict, FrameVerdict::kOk);
}

TEST(FrameCheck, CountsBlankFramesAndExposureJumps) {
  FrameCheck c;
  FrameCheckResult r = c.check(textured(0));
  EXPECT_FALSE(r.blank);
  EXPECT_FALSE(r.exposure_jump);
  Frame black = textured(1);
  black.image.setTo(cv::Scalar(0));
  r = c.check(black);
  EXPECT_EQ(r.verdict, FrameVerdict::kOk);
  EXPECT_TRUE(r.blank);
  EXPECT_FALSE(r.exposure_jump);
  Frame white = textured(2);
  white.image.setTo(cv::Scalar(255));
  EXPECT_TRUE(c.check(white).blank);
  // After blank frames the next normal one is compared with the last non-blank frame.
  r = c.check(textured(3));
  EXPECT_FALSE(r.blank);
  EXPECT_FALSE(r.exposure_jump);
  EXPECT_FALSE(c.check(textured(4, 1.5)).exposure_jump);  // 1.5x: not a jump
  EXPECT_TRUE(c.check(textured(5, 0.3)).exposure_jump);   // 1.5x -> 0.3x
  EXPECT_FALSE(c.check(textured(6, 0.3)).exposure_jump);  // stays dark
  EXPECT_TRUE(c.check(textured(7)).exposure_jump);        // back
  // BGR: the green channel is sampled.
  FrameCheck cb;
  Frame bgr;
  bgr.format = PixelFormat::kBgr8;
  bgr.image.create(48, 64, CV_8UC3);
  bgr.image.setTo(cv::Scalar(0, 128, 0));
  EXPECT_TRUE(cb.check(bgr).blank);
}

}  // namespace
}  // namespace rdslam
