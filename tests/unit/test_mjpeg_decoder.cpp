// MJPEG decoding on real footage: JPEGs made by ffmpeg from vtest.avi, decoded by
// MjpegDecoder, compared with ffmpeg's own decode of the same files.
#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/core.hpp>

#include "drivers/mjpeg_decoder.h"
#include "tests/unit/v4l2_test_footage.h"

namespace rdslam {
namespace {

using namespace rdslam::testing;

struct Diff {
  double mean = 0;
  int max = 0;
};

Diff compare(const cv::Mat& a, const uint8_t* ref) {
  const cv::Mat r(a.rows, a.cols, a.type(), const_cast<uint8_t*>(ref));
  cv::Mat d;
  cv::absdiff(a, r, d);
  double mx = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &mx);
  const cv::Scalar m = cv::mean(d);
  double mean = 0;
  for (int c = 0; c < a.channels(); ++c) mean += m[c];
  return {mean / a.channels(), static_cast<int>(mx)};
}

class MjpegFootage : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string why = footage_unavailable();
    if (!why.empty()) GTEST_SKIP() << "MJPEG footage test skipped: " << why;
    ASSERT_FALSE(dir_.path().empty());
    ASSERT_TRUE(make_mjpeg_frames(dir_)) << "ffmpeg could not make JPEGs from " << vtest_path();
  }
  TempDir dir_;
};

TEST_F(MjpegFootage, BgrMatchesFfmpegDecode) {
  ASSERT_TRUE(decode_jpegs_with_ffmpeg(dir_, "bgr24", "ref_bgr.raw"));
  const auto ref = read_bytes(dir_.file("ref_bgr.raw"));
  const size_t frame_bytes = static_cast<size_t>(kW) * kH * 3;
  ASSERT_EQ(ref.size(), frame_bytes * kFrames);
  MjpegDecoder dec;
  cv::Mat out(kH, kW, CV_8UC3);
  const uint8_t* data_before = out.data;
  for (int i = 0; i < kFrames; ++i) {
    const auto jpg = read_bytes(dir_.file(jpeg_name(i)));
    ASSERT_GT(jpg.size(), 1000u);
    ASSERT_EQ(dec.decode(jpg.data(), jpg.size(), out), DecodeStatus::kOk) << dec.last_error();
    const Diff d = compare(out, ref.data() + frame_bytes * i);
    // Two correct decoders differ by IDCT rounding and chroma upsampling (libjpeg's "fancy"
    // triangle filter vs ffmpeg's): measured mean 0.79, max 32 (at sharp colour edges).
    EXPECT_LT(d.mean, 1.2) << "frame " << i;
    EXPECT_LE(d.max, 40) << "frame " << i;
    std::printf("mjpeg->bgr frame %d vs ffmpeg: mean |diff| %.3f, max %d\n", i, d.mean, d.max);
  }
  EXPECT_EQ(out.data, data_before) << "decode must write into the preallocated buffer";
}

TEST_F(MjpegFootage, GreyMatchesFfmpegDecode) {
  ASSERT_TRUE(decode_jpegs_with_ffmpeg(dir_, "gray", "ref_gray.raw"));
  const auto ref = read_bytes(dir_.file("ref_gray.raw"));
  const size_t frame_bytes = static_cast<size_t>(kW) * kH;
  ASSERT_EQ(ref.size(), frame_bytes * kFrames);
  MjpegDecoder dec;
  cv::Mat out(kH, kW, CV_8UC1);
  for (int i = 0; i < kFrames; ++i) {
    const auto jpg = read_bytes(dir_.file(jpeg_name(i)));
    ASSERT_EQ(dec.decode(jpg.data(), jpg.size(), out), DecodeStatus::kOk) << dec.last_error();
    const Diff d = compare(out, ref.data() + frame_bytes * i);
    std::printf("mjpeg->grey frame %d vs ffmpeg: mean |diff| %.3f, max %d\n", i, d.mean, d.max);
    EXPECT_LT(d.mean, 0.1) << "frame " << i;  // luma only: measured mean 0.02, max 1
    EXPECT_LE(d.max, 2) << "frame " << i;
  }
}

TEST_F(MjpegFootage, TruncatedFrameIsCorruptAndDecoderRecovers) {
  MjpegDecoder dec;
  cv::Mat out(kH, kW, CV_8UC1);
  const auto jpg = read_bytes(dir_.file(jpeg_name(0)));
  // A USB transfer cut short: only the first 60 % of the bytes arrived.
  const size_t cut = jpg.size() * 6 / 10;
  EXPECT_EQ(dec.decode(jpg.data(), cut, out), DecodeStatus::kCorrupt);
  EXPECT_STRNE(dec.last_error(), "");
  // Header only.
  EXPECT_EQ(dec.decode(jpg.data(), 200, out), DecodeStatus::kCorrupt);
  // The next good frame decodes normally.
  EXPECT_EQ(dec.decode(jpg.data(), jpg.size(), out), DecodeStatus::kOk) << dec.last_error();
}

TEST_F(MjpegFootage, LenientModeAcceptsTruncatedFrame) {
  MjpegDecoder dec(/*strict=*/false);
  cv::Mat out(kH, kW, CV_8UC1);
  const auto jpg = read_bytes(dir_.file(jpeg_name(0)));
  EXPECT_EQ(dec.decode(jpg.data(), jpg.size() * 6 / 10, out), DecodeStatus::kOk);
}

TEST_F(MjpegFootage, WrongSizeIsReported) {
  MjpegDecoder dec;
  cv::Mat out(kH / 2, kW / 2, CV_8UC3);
  const auto jpg = read_bytes(dir_.file(jpeg_name(1)));
  int w = 0, h = 0;
  ASSERT_TRUE(dec.peek_size(jpg.data(), jpg.size(), w, h));
  EXPECT_EQ(w, kW);
  EXPECT_EQ(h, kH);
  EXPECT_EQ(dec.decode(jpg.data(), jpg.size(), out), DecodeStatus::kSizeMismatch);
}

TEST(MjpegDecoder, GarbageAndEmptyInputAreCorrupt) {
  MjpegDecoder dec;
  cv::Mat out(48, 64, CV_8UC3);
  std::vector<uint8_t> garbage(5000);
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<uint8_t>(i * 37 + 11);
  EXPECT_EQ(dec.decode(garbage.data(), garbage.size(), out), DecodeStatus::kCorrupt);
  EXPECT_EQ(dec.decode(nullptr, 0, out), DecodeStatus::kCorrupt);
  // SOI followed by garbage.
  garbage[0] = 0xFF;
  garbage[1] = 0xD8;
  EXPECT_EQ(dec.decode(garbage.data(), garbage.size(), out), DecodeStatus::kCorrupt);
  cv::Mat empty;
  EXPECT_EQ(dec.decode(garbage.data(), garbage.size(), empty), DecodeStatus::kBadOutput);
}

}  // namespace
}  // namespace rdslam
