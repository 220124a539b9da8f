// Image-folder and video-file sources, and open_source's URI parsing and auto-detection.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <opencv2/videoio.hpp>

#include "drivers/image_folder_source.h"
#include "drivers/source_factory.h"
#include "drivers/video_source.h"
#include "tests/support/dataset_fixtures.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;
namespace fs = std::filesystem;

namespace {
const SourceOptions kDefaults;
}

TEST(ImageFolder, NaturalOrderAndFpsStamps) {
  std::vector<std::string> names = {"img10.png", "img2.png", "img1.png", "img002b.png"};
  std::sort(names.begin(), names.end(), natural_less);
  EXPECT_EQ(names, (std::vector<std::string>{"img1.png", "img2.png", "img002b.png", "img10.png"}));
  TempDir d;
  std::vector<cv::Mat> imgs;
  for (int i : {1, 2, 10}) {
    imgs.push_back(random_image(20, 10, CV_8UC1, i));
    rdslam::testing::write_png(d.path() / ("frame" + std::to_string(i) + ".png"), imgs.back());
  }
  d.write("notes.txt", "not an image");
  auto src = open_source(d.str(), kDefaults);  // auto-detected
  EXPECT_EQ(src->info().kind, "images");
  std::vector<cv::Mat> frames;
  std::vector<int64_t> stamps;
  rdslam::testing::read_all(*src, frames, stamps);
  ASSERT_EQ(frames.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_TRUE(same_pixels(frames[i], imgs[i])) << i;
  EXPECT_EQ(stamps, (std::vector<int64_t>{0, 33333333, 66666667}));  // default 30 Hz
  auto src2 = open_source("images:" + d.str() + "?fps=4", kDefaults);
  stamps.clear();
  frames.clear();
  rdslam::testing::read_all(*src2, frames, stamps);
  EXPECT_EQ(stamps, (std::vector<int64_t>{0, 250000000, 500000000}));
}

TEST(ImageFolder, StampsFromTimestampNames) {
  TempDir d;
  for (const char* n : {"1305031102.175304.png", "1305031102.211214.png"}) {
    rdslam::testing::write_png(d.path() / "s" / n, random_image(8, 8, CV_8UC3, 1));
  }
  for (const char* n : {"1403715273262142976.png", "1403715273312143104.png"}) {
    rdslam::testing::write_png(d.path() / "ns" / n, random_image(8, 8, CV_8UC1, 1));
  }
  Frame f;
  auto s = open_source("images:" + d.str("s"), kDefaults);
  ASSERT_EQ(s->read(f, 0), SourceStatus::kOk);
  ASSERT_EQ(s->read(f, 0), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 1305031102211214000LL);
  auto ns = open_source("images:" + d.str("ns"), kDefaults);
  ASSERT_EQ(ns->read(f, 0), SourceStatus::kOk);
  ASSERT_EQ(ns->read(f, 0), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 1403715273312143104LL);
}

TEST(VideoFile, FramesAndStampsFromAWrittenVideo) {
  TempDir d;
  const std::string path = d.str("clip.avi");
  {
    // Lossless-enough fixture: MJPG at high quality, smooth content, 15 fps.
    cv::VideoWriter w(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 15.0, cv::Size(64, 48));
    ASSERT_TRUE(w.isOpened());
    for (int i = 0; i < 20; ++i) w.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(10 * i, 100, 200)));
  }
  auto src = open_source(path, kDefaults);  // auto-detected by extension
  EXPECT_EQ(src->info().kind, "video");
  EXPECT_EQ(src->info().width, 64);
  EXPECT_NEAR(src->info().nominal_fps, 15.0, 1e-6);
  Frame f;
  int n = 0;
  while (src->read(f, 0) == SourceStatus::kOk) {
    EXPECT_EQ(f.stamp_ns, std::llround(n * 1e9 / 15.0));
    EXPECT_NEAR(f.image.at<cv::Vec3b>(20, 20)[0], 10 * n, 3) << n;  // blue channel ramps
    ++n;
  }
  EXPECT_EQ(n, 20);
  EXPECT_EQ(src->read(f, 0), SourceStatus::kEndOfStream);
}

TEST(VideoFile, SharedVtestFirstFramesAndPacedSkipping) {
  const std::string path = std::string(RDSLAM_SHARED_DIR) + "/data/opencv_vtest/vtest.avi";
  if (!fs::exists(path)) {
    GTEST_SKIP() << "shared data not found: " << path << " (../shared/data is absent)";
  }
  auto src = open_source("video:" + path, kDefaults);
  EXPECT_EQ(src->info().width, 768);
  EXPECT_EQ(src->info().height, 576);
  EXPECT_EQ(src->info().format, PixelFormat::kBgr8);
  EXPECT_NEAR(src->info().nominal_fps, 10.0, 1e-6);
  EXPECT_EQ(src->info().frame_count, 795);        // SOURCE.md
  EXPECT_FALSE(src->camera()->has_distortion());  // no intrinsics: the config's camera
  // Reference: frame 5 decoded directly by OpenCV.
  cv::VideoCapture cap(path, cv::CAP_FFMPEG);
  cv::Mat ref;
  for (int i = 0; i <= 5; ++i) cap.read(ref);
  Frame f;
  for (int i = 0; i <= 5; ++i) ASSERT_EQ(src->read(f, 0), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 500000000);
  EXPECT_TRUE(same_pixels(f.image, ref));
  // Paced at 20x (200 fps): a reader that sleeps 30 ms between reads gets the newest frame
  // and the grabbed-but-skipped ones are counted; its frames still match OpenCV's.
  SourceOptions o;
  o.speed = 20.0;
  auto paced = open_source("video:" + path, o);
  ASSERT_EQ(paced->read(f, 1000), SourceStatus::kOk);
  struct timespec ts {
    0, 30000000
  };
  nanosleep(&ts, nullptr);
  ASSERT_EQ(paced->read(f, 1000), SourceStatus::kOk);
  EXPECT_GE(f.dataset_index, 5);
  EXPECT_EQ(paced->counters().skipped, static_cast<uint64_t>(f.dataset_index - 1));
  cv::VideoCapture cap2(path, cv::CAP_FFMPEG);
  for (int64_t i = 0; i <= f.dataset_index; ++i) cap2.read(ref);
  EXPECT_TRUE(same_pixels(f.image, ref));
}

TEST(SourceFactory, UriErrorsNameTheProblem) {
  TempDir d;
  rdslam::testing::write_png(d.path() / "a.png", random_image(8, 8, CV_8UC1, 1));
  auto expect_msg = [](const std::string& uri, const std::string& needle) {
    try {
      open_source(uri, kDefaults);
      ADD_FAILURE() << uri << ": no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << uri << ": " << e.what();
    }
  };
  expect_msg("nosuch:" + d.str(), "unknown scheme 'nosuch'");
  expect_msg("images:" + d.str() + "?color=1", "unknown parameter 'color'");
  expect_msg("images:" + d.str() + "?fps=-3", "fps=-3");
  expect_msg("images:" + d.str() + "?fps", "not key=value");
  expect_msg(d.str("missing"), "no such file or folder");
  expect_msg("tum:" + d.str(), "rgb.txt");
  expect_msg("euroc:" + d.str(), "not an EuRoC");
  expect_msg("kitti:" + d.str(), "not a KITTI");
  d.write("clip.avi", "not a video container");
  expect_msg("video:" + d.str("clip.avi"), "cannot open as a video");
  expect_msg(d.str("clip.avi"), "cannot open as a video");  // auto-detected by extension
  d.write("empty/readme.md", "x");
  expect_msg(d.str("empty"), "holds no images");
  SourceOptions o;
  o.speed = -1;
  EXPECT_THROW(open_source("images:" + d.str(), o), std::runtime_error);
}

TEST(SourceFactory, CameraYamlBesideTheDataAndOverride) {
  TempDir d;
  rdslam::testing::write_png(d.path() / "a.png", random_image(16, 16, CV_8UC1, 1));
  // No camera.yaml: the config camera.
  SourceOptions o;
  o.config_camera.fx = 111.0;
  EXPECT_DOUBLE_EQ(open_source(d.str(), o)->camera()->fx, 111.0);
  d.write("camera.yaml",
          "model: pinhole-equidistant\nwidth: 16\nheight: 16\nfx: 5\nfy: 6\ncx: 8\ncy: 8\n"
          "k1: 0.1\nk2: 0.01\nk3: 0.001\nk4: 0.0001\n");
  const CameraModel c = *open_source(d.str(), o)->camera();
  EXPECT_EQ(c.model, "pinhole-equidistant");
  EXPECT_DOUBLE_EQ(c.fx, 5.0);
  EXPECT_DOUBLE_EQ(c.k4, 0.0001);
  o.camera_overridden = true;
  EXPECT_DOUBLE_EQ(open_source(d.str(), o)->camera()->fx, 111.0);
}
