// The lcm: source (drivers/lcm_image_source.h): bot_core.image_t replayed from a log with the
// real lcm-logplayer reaches rdslam with its pixels and timestamps; newest-wins, faults.
// LCM traffic stays on this host (ttl=0) on a port unique to this test process.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bot_core/image_t.hpp>
#include <chrono>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "drivers/lcm_image_source.h"
#include "drivers/source_factory.h"
#include "tests/support/dataset_fixtures.h"
#include "tests/support/lcm_test_bus.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;

namespace {

std::string test_url(int salt) {
  return rdslam::testing::private_lcm_url(salt);
}

bot_core::image_t make_msg(int64_t utime, const cv::Mat& img, int32_t format, int pad = 0) {
  bot_core::image_t m;
  m.utime = utime;
  m.width = img.cols;
  m.height = img.rows;
  m.pixelformat = format;
  if (format == bot_core::image_t::PIXEL_FORMAT_MJPEG) {
    std::vector<uint8_t> jpg;
    cv::imencode(".jpg", img, jpg, {cv::IMWRITE_JPEG_QUALITY, 95});
    m.row_stride = 0;
    m.data = jpg;
  } else {
    cv::Mat src = img;
    if (format == bot_core::image_t::PIXEL_FORMAT_RGB) cv::cvtColor(img, src, cv::COLOR_BGR2RGB);
    const int row = img.cols * static_cast<int>(img.elemSize());
    m.row_stride = row + pad;  // padded rows, as many drivers deliver them
    m.data.assign(static_cast<size_t>(m.row_stride) * img.rows, 0xEE);
    for (int r = 0; r < img.rows; ++r) {
      std::memcpy(&m.data[static_cast<size_t>(r) * m.row_stride], src.ptr(r), row);
    }
  }
  m.size = static_cast<int32_t>(m.data.size());
  m.nmetadata = 1;
  m.metadata.resize(1);
  m.metadata[0].key = "exposure";
  m.metadata[0].n = 2;
  m.metadata[0].value = {1, 2};
  return m;
}

std::vector<uint8_t> encode(const bot_core::image_t& m) {
  std::vector<uint8_t> buf(static_cast<size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return buf;
}

}  // namespace

TEST(LcmImage, ParserChecksFingerprintAndBounds) {
  const cv::Mat img = random_image(8, 4, CV_8UC1, 1);
  std::vector<uint8_t> buf = encode(make_msg(123, img, bot_core::image_t::PIXEL_FORMAT_GRAY, 3));
  ImageMsgView v;
  ASSERT_TRUE(parse_bot_core_image(buf.data(), buf.size(), v));
  EXPECT_EQ(v.utime, 123);
  EXPECT_EQ(v.width, 8);
  EXPECT_EQ(v.row_stride, 11);
  EXPECT_EQ(v.size, 44);
  EXPECT_EQ(v.data[11], img.at<uint8_t>(1, 0));
  for (size_t len = 0; len < buf.size(); ++len) {  // every truncation is rejected
    EXPECT_FALSE(parse_bot_core_image(buf.data(), len, v)) << len;
  }
  std::vector<uint8_t> bad = buf;
  bad[0] ^= 1;  // another type's fingerprint
  EXPECT_FALSE(parse_bot_core_image(bad.data(), bad.size(), v));
  bad = buf;
  bad[32] = 0x80;  // negative size
  EXPECT_FALSE(parse_bot_core_image(bad.data(), bad.size(), v));
  bad = buf;
  bad[32] = 0x7f;  // size far beyond the message
  EXPECT_FALSE(parse_bot_core_image(bad.data(), bad.size(), v));
}

TEST(LcmImage, LogReplayedWithLcmLogplayerArrivesWithTimestamps) {
  TempDir d;
  const std::string url = test_url(1);
  const std::string log = d.str("camera.lcmlog");
  // Five frames 40 ms apart, as a robot's logger would have written them: grey (padded
  // rows), RGB, MJPEG, plus an unrelated message type on the same channel.
  std::vector<cv::Mat> grey;
  const int64_t t0_us = 1700000000000000LL;
  {
    lcm::LogFile out(log, "w");
    ASSERT_TRUE(out.good());
    for (int i = 0; i < 5; ++i) {
      const cv::Mat bgr = random_image(64, 48, CV_8UC3, 40 + i);
      cv::Mat g;
      cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
      cv::Mat smooth;  // JPEG of smooth content decodes close to the original
      cv::GaussianBlur(bgr, smooth, cv::Size(9, 9), 3.0);
      cv::Mat smooth_g;
      cv::cvtColor(smooth, smooth_g, cv::COLOR_BGR2GRAY);
      bot_core::image_t m;
      if (i % 3 == 0) {
        m = make_msg(t0_us + i * 40000, g, bot_core::image_t::PIXEL_FORMAT_GRAY, 5);
        grey.push_back(g);
      } else if (i % 3 == 1) {
        m = make_msg(t0_us + i * 40000, bgr, bot_core::image_t::PIXEL_FORMAT_RGB);
        grey.push_back(g);
      } else {
        m = make_msg(t0_us + i * 40000, smooth, bot_core::image_t::PIXEL_FORMAT_MJPEG);
        grey.push_back(smooth_g);
      }
      std::vector<uint8_t> bytes = encode(m);
      lcm::LogEvent ev;
      ev.eventnum = i;
      ev.timestamp = t0_us + i * 40000;
      ev.channel = "CAM_FRONT";
      ev.datalen = static_cast<int32_t>(bytes.size());
      ev.data = bytes.data();
      ASSERT_EQ(out.writeEvent(&ev), 0);
      if (i == 2) {
        uint8_t junk[64] = {1, 2, 3};
        lcm::LogEvent j = ev;
        j.timestamp += 10000;
        j.datalen = sizeof(junk);
        j.data = junk;
        ASSERT_EQ(out.writeEvent(&j), 0);
      }
    }
  }
  SourceOptions o;
  o.lcm_url = url;
  o.config_camera.width = 64;
  o.config_camera.height = 48;
  o.config_camera.cx = 32;
  o.config_camera.cy = 24;
  auto src = open_source("lcm:CAM_FRONT", o);  // subscribed before the player starts
  EXPECT_TRUE(src->info().live);
  EXPECT_EQ(src->info().format, PixelFormat::kGray8);

  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string arg = "--lcm-url=" + url;
    execlp("lcm-logplayer", "lcm-logplayer", arg.c_str(), log.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  Frame f;
  f.image.create(48, 64, CV_8UC1);
  std::vector<int64_t> stamps;
  int faults = 0;
  for (int tries = 0; tries < 40 && stamps.size() < 5; ++tries) {
    const SourceStatus st = src->read(f, 250);
    if (st == SourceStatus::kFault) ++faults;
    if (st != SourceStatus::kOk) continue;
    const size_t i = static_cast<size_t>((f.stamp_ns / 1000 - t0_us) / 40000);
    ASSERT_LT(i, grey.size());
    EXPECT_EQ(f.stamp_ns, (t0_us + static_cast<int64_t>(i) * 40000) * 1000);
    if (i % 3 == 2) {  // JPEG: lossy
      cv::Mat diff;
      cv::absdiff(f.image, grey[i], diff);
      double max_diff = 0;
      cv::minMaxLoc(diff, nullptr, &max_diff);
      EXPECT_LE(max_diff, 12.0) << "frame " << i;
    } else {
      // RGB -> grey uses OpenCV's weights, as the reference did.
      EXPECT_TRUE(same_pixels(f.image, grey[i])) << "frame " << i;
    }
    stamps.push_back(f.stamp_ns);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "lcm-logplayer failed";
  // The reader kept up (40 ms spacing), so every frame arrived, in order.
  ASSERT_EQ(stamps.size(), 5u);
  for (size_t i = 0; i < 5; ++i)
    EXPECT_EQ(stamps[i], (t0_us + static_cast<int64_t>(i) * 40000) * 1000);
  EXPECT_EQ(src->counters().skipped, 0u);
  EXPECT_EQ(src->counters().faults, 1u);  // the unrelated message
  EXPECT_EQ(faults, 1);
}

TEST(LcmImage, SlowReaderGetsTheNewestImageAndSkippedAreCounted) {
  const std::string url = test_url(2);
  LcmImageSource src("lcm:CAM", "CAM", url, 32, 16, PixelFormat::kBgr8);
  lcm::LCM pub(url);
  ASSERT_TRUE(pub.good());
  std::vector<cv::Mat> sent;
  for (int i = 0; i < 6; ++i) {
    sent.push_back(random_image(32, 16, CV_8UC3, 70 + i));
    const auto m = make_msg(1000 + i, sent.back(), bot_core::image_t::PIXEL_FORMAT_BGR);
    pub.publish("CAM", &m);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the reader was busy
  Frame f;
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 1005 * 1000);
  EXPECT_EQ(f.seq, 5u);
  EXPECT_TRUE(same_pixels(f.image, sent[5]));
  EXPECT_EQ(src.counters().skipped, 5u);
  EXPECT_EQ(src.counters().delivered, 1u);
  EXPECT_EQ(src.read(f, 20), SourceStatus::kTimeout);
  EXPECT_EQ(src.counters().timeouts, 1u);

  // Wrong size, unsupported format, corrupt JPEG, garbage bytes: faults, never a crash.
  const auto wrong_size =
      make_msg(1, random_image(16, 16, CV_8UC3, 1), bot_core::image_t::PIXEL_FORMAT_BGR);
  pub.publish("CAM", &wrong_size);
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kFault);
  auto yuyv = make_msg(2, random_image(32, 16, CV_8UC3, 1), bot_core::image_t::PIXEL_FORMAT_BGR);
  yuyv.pixelformat = bot_core::image_t::PIXEL_FORMAT_YUYV;
  pub.publish("CAM", &yuyv);
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kFault);
  auto jpeg = make_msg(3, random_image(32, 16, CV_8UC3, 1), bot_core::image_t::PIXEL_FORMAT_MJPEG);
  jpeg.data.resize(jpeg.data.size() / 2);
  jpeg.size = static_cast<int32_t>(jpeg.data.size());
  pub.publish("CAM", &jpeg);
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kFault);
  const uint8_t garbage[7] = {9, 9, 9, 9, 9, 9, 9};
  pub.publish("CAM", garbage, sizeof(garbage));
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kFault);
  EXPECT_EQ(src.counters().faults, 4u);
  // And the next good image is delivered.
  const auto good = make_msg(77, sent[0], bot_core::image_t::PIXEL_FORMAT_BGR);
  pub.publish("CAM", &good);
  ASSERT_EQ(src.read(f, 1000), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 77000);
  EXPECT_TRUE(same_pixels(f.image, sent[0]));
}
