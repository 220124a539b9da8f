// The V4L2 streaming state machine against a simulated UVC camera (tests/unit/
// v4l2_fake_device.h) fed with REAL footage (MJPEG/YUYV frames made by ffmpeg from
// vtest.avi): negotiation, frame rate, controls, kernel timestamps, corrupt frames, EIO,
// unplug/replug with backoff, newest-frame delivery. Plus, when the machine has a vivid or
// v4l2loopback device, the same source against the real kernel.
#include <gtest/gtest.h>
#include <linux/videodev2.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>

#include "drivers/mjpeg_decoder.h"
#include "drivers/v4l2_source.h"
#include "drivers/v4l2_syscalls.h"
#include "drivers/yuyv.h"
#include "tests/unit/v4l2_fake_device.h"
#include "tests/unit/v4l2_test_footage.h"

namespace rdslam {
namespace {

using namespace rdslam::testing;

class V4l2Fake : public ::testing::Test {
 protected:
  // Footage is made once per test binary (ffmpeg takes ~1 s); every test gets a fresh camera.
  static void SetUpTestSuite() {
    skip_reason_ = new std::string(footage_unavailable());
    if (!skip_reason_->empty()) return;
    dir_ = new TempDir;
    jpegs_ = new std::vector<std::vector<uint8_t>>;
    yuyvs_ = new std::vector<std::vector<uint8_t>>;
    if (!make_mjpeg_frames(*dir_) || !make_yuyv_frames(*dir_)) {
      *skip_reason_ = "";
      footage_failed_ = true;
      return;
    }
    for (int i = 0; i < kFrames; ++i) jpegs_->push_back(read_bytes(dir_->file(jpeg_name(i))));
    const auto raw = read_bytes(dir_->file("yuyv.raw"));
    const size_t n = static_cast<size_t>(kW) * kH * 2;
    footage_failed_ = raw.size() != n * kFrames;
    for (int i = 0; !footage_failed_ && i < kFrames; ++i) {
      yuyvs_->emplace_back(raw.begin() + n * i, raw.begin() + n * (i + 1));
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete jpegs_;
    delete yuyvs_;
    delete skip_reason_;
    dir_ = nullptr;
    jpegs_ = yuyvs_ = nullptr;
    skip_reason_ = nullptr;
  }
  void SetUp() override {
    if (!skip_reason_->empty()) GTEST_SKIP() << "V4L2 streaming test skipped: " << *skip_reason_;
    ASSERT_FALSE(footage_failed_) << "ffmpeg could not make MJPEG/YUYV frames from vtest.avi";
    cam_.width = kW;
    cam_.height = kH;
    cam_.payloads[V4L2_PIX_FMT_MJPEG] = *jpegs_;
    cam_.payloads[V4L2_PIX_FMT_YUYV] = *yuyvs_;
  }

  cv::Mat expected_mjpeg(uint32_t seq, int type) {
    cv::Mat m(kH, kW, type);
    MjpegDecoder d;
    const auto& j = (*jpegs_)[seq % jpegs_->size()];
    EXPECT_EQ(d.decode(j.data(), j.size(), m), DecodeStatus::kOk);
    return m;
  }

  static inline TempDir* dir_ = nullptr;
  static inline std::vector<std::vector<uint8_t>>* jpegs_ = nullptr;
  static inline std::vector<std::vector<uint8_t>>* yuyvs_ = nullptr;
  static inline std::string* skip_reason_ = nullptr;
  static inline bool footage_failed_ = false;
  FakeV4l2 cam_;
  V4l2Params params_;
};

TEST_F(V4l2Fake, PrefersMjpegAndDeliversDecodedFramesWithKernelTimestamps) {
  params_.stamp_offset_ms = 5.0;
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  EXPECT_EQ(src.fourcc(), "MJPG");
  EXPECT_EQ(src.info().kind, "v4l2");
  EXPECT_EQ(src.info().uri, "v4l2:/dev/video0");
  EXPECT_TRUE(src.info().live);
  EXPECT_DOUBLE_EQ(src.info().nominal_fps, 30.0);
  EXPECT_EQ(src.info().format, PixelFormat::kGray8);
  Frame f;
  const uint8_t* data = nullptr;
  for (uint32_t i = 0; i < 6; ++i) {
    ASSERT_EQ(src.read(f, 200), SourceStatus::kOk) << "frame " << i;
    if (i == 0) data = f.image.data;
    EXPECT_EQ(f.image.data, data) << "read() must reuse the caller's buffer";
    EXPECT_EQ(f.seq, i);
    EXPECT_EQ(f.format, PixelFormat::kGray8);
    // Kernel timestamp (us resolution) minus the configured receipt offset.
    EXPECT_NEAR(f.stamp_ns, cam_.frame_stamp(i) - 5000000, 1000);
    EXPECT_GE(f.arrival_mono_ns, cam_.frame_stamp(i));
    EXPECT_EQ(cv::norm(f.image, expected_mjpeg(i, CV_8UC1), cv::NORM_INF), 0.0);
  }
  EXPECT_EQ(src.counters().delivered, 6u);
  EXPECT_EQ(src.counters().faults, 0u);
}

TEST_F(V4l2Fake, FrameRateAndControlsAreApplied) {
  params_.fps = 15;
  params_.exposure_us = 5000;
  params_.gain = 300;              // above the camera's range: clamped
  params_.white_balance_k = 4500;  // this camera has no white-balance control
  params_.output = "bgr";
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  EXPECT_DOUBLE_EQ(src.info().nominal_fps, 15.0);
  EXPECT_EQ(cam_.timeperframe.denominator, 15u);
  EXPECT_EQ(cam_.controls_set.at(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(cam_.controls_set.at(V4L2_CID_EXPOSURE_ABSOLUTE), 50);  // 100 us units
  EXPECT_EQ(cam_.controls_set.at(V4L2_CID_GAIN), 255);
  EXPECT_EQ(cam_.controls_set.count(V4L2_CID_WHITE_BALANCE_TEMPERATURE), 0u);
  std::string report;
  for (const auto& l : src.control_report()) report += l + "\n";
  EXPECT_NE(report.find("clamped"), std::string::npos) << report;
  EXPECT_NE(report.find("not supported"), std::string::npos) << report;
  Frame f;
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
  EXPECT_EQ(f.image.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(f.image, expected_mjpeg(0, CV_8UC3), cv::NORM_INF), 0.0);
}

TEST_F(V4l2Fake, FallsBackToYuyvAndConvertsIt) {
  cam_.formats = {V4L2_PIX_FMT_YUYV};
  params_.output = "bgr";
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  EXPECT_EQ(src.fourcc(), "YUYV");
  Frame f;
  for (uint32_t i = 0; i < 4; ++i) {
    ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
    cv::Mat want(kH, kW, CV_8UC3);
    const auto& y = (*yuyvs_)[i % yuyvs_->size()];
    ASSERT_TRUE(yuyv_to_image(y.data(), y.size(), kW, kH, kW * 2, want));
    EXPECT_EQ(cv::norm(f.image, want, cv::NORM_INF), 0.0);
  }
}

TEST_F(V4l2Fake, ForcedFormatTheCameraLacksFailsAtStartupWithAClearMessage) {
  cam_.formats = {V4L2_PIX_FMT_YUYV};
  params_.pixel_format = "mjpeg";
  try {
    V4l2Source src("/dev/video0", params_, kW, kH, cam_);
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera offers: YUYV"), std::string::npos) << e.what();
  }
  EXPECT_EQ(cam_.open_fds, 0) << "the descriptor must be closed on failure";
  EXPECT_THROW(V4l2Source("/dev/video7", V4l2Params{}, kW, kH, cam_), std::runtime_error);
}

TEST_F(V4l2Fake, CorruptMjpegAndErrorFlaggedFramesAreSkippedAndCounted) {
  cam_.truncate_frames = {1, 4};
  cam_.error_flag_frames = {6};
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  Frame f;
  int ok = 0, fault = 0;
  std::vector<uint64_t> seqs;
  for (int i = 0; i < 10; ++i) {
    const SourceStatus s = src.read(f, 200);
    if (s == SourceStatus::kOk) {
      ++ok;
      seqs.push_back(f.seq);
    }
    if (s == SourceStatus::kFault) ++fault;
  }
  EXPECT_EQ(fault, 3);
  EXPECT_EQ(ok, 7);
  EXPECT_EQ(src.counters().faults, 3u);
  EXPECT_EQ(src.stats().corrupt, 3u);
  EXPECT_EQ(src.counters().delivered, 7u);
  for (size_t i = 0; i < seqs.size(); ++i) EXPECT_EQ(seqs[i], i) << "seq is contiguous";
}

TEST_F(V4l2Fake, UnplugIsSurvivedWithBackoffAndStreamingResumes) {
  params_.reopen_backoff_ms = 100;
  params_.reopen_backoff_max_ms = 800;
  const int64_t t0 = cam_.now_ns;
  cam_.unplug_at_ns = t0 + 200000000LL;   // after ~6 frames
  cam_.replug_at_ns = t0 + 2700000000LL;  // 2.5 s later
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  Frame f;
  int ok_before = 0, faults = 0, timeouts = 0, ok_after = 0;
  uint64_t last_seq = 0;
  bool seen_fault = false;
  while (cam_.now_ns < t0 + 5000000000LL) {
    const SourceStatus s = src.read(f, 100);
    if (s == SourceStatus::kOk) {
      if (ok_before + ok_after > 0) {
        EXPECT_GT(f.seq, last_seq);
      }
      last_seq = f.seq;
      (seen_fault ? ok_after : ok_before)++;
    } else if (s == SourceStatus::kFault) {
      seen_fault = true;
      ++faults;
    } else {
      ++timeouts;
    }
  }
  EXPECT_EQ(ok_before, 6);
  EXPECT_EQ(faults, 1);
  EXPECT_GT(timeouts, 10) << "read() keeps returning within its timeout while unplugged";
  // Reopened at ~3.3 s (see below), then 30 fps until 5 s.
  EXPECT_GE(ok_after, 45) << "streaming resumes after the replug";
  const V4l2Stats st = src.stats();
  EXPECT_EQ(st.device_lost, 1u);
  EXPECT_EQ(st.reopened, 1u);
  // Backoff 100, 200, 400, 800, 800, ... ms from 0.2 s to 2.7 s: attempts at about 0.3,
  // 0.5, 0.9, 1.7, 2.5 (fail) and 3.3 s (succeeds) -> 6, not one per read().
  EXPECT_GE(src.counters().reopens, 5u);
  EXPECT_LE(src.counters().reopens, 7u);
  EXPECT_EQ(cam_.open_fds, 1);
  EXPECT_EQ(cam_.mapped, 4) << "old mappings released, new ones made";
}

TEST_F(V4l2Fake, EioReopensImmediatelyOnTheNextAttempt) {
  cam_.eio_frames = {3};
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  Frame f;
  int ok = 0, fault = 0;
  for (int i = 0; i < 20; ++i) {
    const SourceStatus s = src.read(f, 200);
    ok += s == SourceStatus::kOk;
    fault += s == SourceStatus::kFault;
  }
  EXPECT_EQ(fault, 1);
  EXPECT_GE(ok, 17);
  EXPECT_EQ(src.stats().reopened, 1u);
  EXPECT_EQ(cam_.opens, 2);
}

TEST_F(V4l2Fake, SlowConsumerGetsTheNewestFrameAndStaleOnesAreCounted) {
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  Frame f;
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);  // kernel seq 0
  // The consumer stalls for 10 frame periods: 4 buffers fill (seq 1..3 plus one), the rest
  // are dropped by the kernel for want of a queued buffer.
  cam_.advance(10 * cam_.period_ns + 1000);
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
  const V4l2Stats st = src.stats();
  EXPECT_EQ(st.stale_skipped, 3u);
  EXPECT_EQ(f.seq, 1u);
  // The delivered frame is the newest the kernel held (seq 4; us timestamp resolution).
  EXPECT_NEAR(f.stamp_ns, cam_.frame_stamp(4), 1000);
  EXPECT_EQ(st.kernel_dropped, 0u);
  // Frames 5..10 found no queued buffer: the next frame (seq 11) shows the gap.
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
  EXPECT_NEAR(f.stamp_ns, cam_.frame_stamp(11), 1000);
  EXPECT_EQ(src.stats().kernel_dropped, 6u);
}

TEST_F(V4l2Fake, WithoutNewestOnlyTheOldestQueuedFrameComesFirst) {
  params_.newest_only = false;
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  Frame f;
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
  cam_.advance(10 * cam_.period_ns + 1000);
  ASSERT_EQ(src.read(f, 200), SourceStatus::kOk);
  EXPECT_NEAR(f.stamp_ns, cam_.frame_stamp(1), 1000);
  EXPECT_EQ(src.stats().stale_skipped, 0u);
}

TEST_F(V4l2Fake, NoFrameWithinTheTimeoutIsATimeout) {
  V4l2Source src("/dev/video0", params_, kW, kH, cam_);
  cam_.paused = true;
  Frame f;
  const int64_t before = cam_.now_ns;
  EXPECT_EQ(src.read(f, 50), SourceStatus::kTimeout);
  EXPECT_GE(cam_.now_ns - before, 50000000LL);
  EXPECT_EQ(src.counters().timeouts, 1u);
}

TEST_F(V4l2Fake, ListsCaptureNodesWithFormatsSizesAndRates) {
  const auto devs = list_v4l2_devices(cam_);
  ASSERT_EQ(devs.size(), 2u);
  EXPECT_EQ(devs[0].path, "/dev/video0");
  EXPECT_TRUE(devs[0].capture);
  EXPECT_EQ(devs[0].card, "Fake UVC Camera");
  EXPECT_EQ(devs[0].driver, "uvcvideo");
  ASSERT_EQ(devs[0].formats.size(), 2u);
  EXPECT_EQ(devs[0].formats[1].fourcc, "MJPG");
  EXPECT_TRUE(devs[0].formats[1].usable);
  ASSERT_EQ(devs[0].formats[1].sizes.size(), 2u);
  EXPECT_EQ(devs[0].formats[1].sizes[0].width, kW);
  ASSERT_EQ(devs[0].formats[1].sizes[0].fps.size(), 2u);
  EXPECT_DOUBLE_EQ(devs[0].formats[1].sizes[0].fps[0], 30.0);  // highest first
  EXPECT_FALSE(devs[1].capture);
  EXPECT_EQ(devs[1].note, "metadata node, not video");
  EXPECT_EQ(cam_.open_fds, 0);
}

TEST_F(V4l2Fake, DescribeSuggestsTheBestMjpegSizeAndExplainsSkippedNodes) {
  const std::string text = describe_v4l2_devices(list_v4l2_devices(cam_));
  EXPECT_NE(text.find("/dev/video0  Fake UVC Camera  (uvcvideo, usb-fake-1)"), std::string::npos)
      << text;
  EXPECT_NE(text.find("MJPG  Motion-JPEG"), std::string::npos) << text;
  EXPECT_NE(text.find("640x480 "), std::string::npos) << text;
  EXPECT_NE(text.find("30, 15 fps"), std::string::npos) << text;
  EXPECT_NE(text.find("use: --set source=v4l2:/dev/video0 --set v4l2.pixel_format=mjpeg --set "
                      "v4l2.width=640 --set v4l2.height=480"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("skipped: metadata node, not video"), std::string::npos) << text;
  EXPECT_EQ(text.find("no V4L2"), std::string::npos) << text;
}

TEST(V4l2Describe, NoDevicesGivesAClearMessage) {
  const std::string text = describe_v4l2_devices({});
  EXPECT_NE(text.find("no V4L2 video devices"), std::string::npos) << text;
  EXPECT_NE(text.find("USB (UVC) camera"), std::string::npos) << text;
  V4l2DeviceInfo h264_only;
  h264_only.path = "/dev/video4";
  h264_only.capture = true;
  h264_only.note = "offers no format rdslam decodes (MJPG, YUYV, GREY)";
  V4l2FormatInfo f;
  f.fourcc = "H264";
  f.description = "H.264";
  h264_only.formats.push_back(f);
  const std::string t2 = describe_v4l2_devices({h264_only});
  EXPECT_NE(t2.find("H264  H.264  (not decoded by rdslam)"), std::string::npos) << t2;
  EXPECT_NE(t2.find("no V4L2 device here offers a format rdslam can use"), std::string::npos) << t2;
}

// ---- the real kernel: vivid or v4l2loopback, when this machine has one ----

std::string find_kernel_test_device() {
  if (const char* env = std::getenv("RDSLAM_V4L2_TEST_DEVICE")) return env;
  for (const auto& dev : system_v4l2().list_video_devices()) {
    const std::string name = dev.substr(dev.rfind('/') + 1);
    std::ifstream in("/sys/class/video4linux/" + name + "/name");
    std::string card;
    std::getline(in, card);
    if (card.find("vivid") != std::string::npos || card.find("Loopback") != std::string::npos ||
        card.find("rdslam") != std::string::npos) {
      return dev;
    }
  }
  return "";
}

TEST(V4l2Kernel, StreamsFromVividOrLoopbackDevice) {
  const std::string dev = find_kernel_test_device();
  if (dev.empty()) {
    GTEST_SKIP() << "no vivid or v4l2loopback device on this machine (load one with "
                    "`modprobe vivid` or toolchain/v4l2loopback-feed.sh, or set "
                    "RDSLAM_V4L2_TEST_DEVICE=/dev/videoN); the real-kernel path was NOT tested";
  }
  V4l2Params p;
  p.width = 640;
  p.height = 480;
  std::unique_ptr<FrameSource> src;
  try {
    src = open_v4l2_source(dev, p, 640, 480);
  } catch (const std::exception& e) {
    FAIL() << "cannot open " << dev << ": " << e.what();
  }
  Frame f;
  int ok = 0;
  int64_t last = 0;
  for (int i = 0; i < 30 && ok < 10; ++i) {
    if (src->read(f, 1000) != SourceStatus::kOk) continue;
    EXPECT_GT(f.stamp_ns, last);
    last = f.stamp_ns;
    ++ok;
  }
  EXPECT_GE(ok, 10) << "fewer than 10 frames from " << dev;
}

}  // namespace
}  // namespace rdslam
