#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>

#include "drivers/dataset_kitti.h"
#include "drivers/source_factory.h"
#include "tests/support/dataset_fixtures.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;
namespace fs = std::filesystem;

namespace {

const SourceOptions kDefaults;

// KITTI's P0 scaled by 1/10 to fit the small fixture images (120x37).
const char* kCalibOfficial =
    "P0: 7.070912000000e+01 0.000000000000e+00 6.018873000000e+01 0.000000000000e+00 "
    "0.000000000000e+00 7.070912000000e+01 1.831104000000e+01 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
    "P1: 7.070912000000e+02 0.000000000000e+00 6.018873000000e+02 -3.798145000000e+02 "
    "0.000000000000e+00 7.070912000000e+02 1.831104000000e+02 0.000000000000e+00 "
    "0.000000000000e+00 0.000000000000e+00 1.000000000000e+00 0.000000000000e+00\n"
    "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n";

// Official layout: dataset/sequences/06/{image_0,calib.txt,times.txt}, dataset/poses/06.txt.
struct KittiFixture {
  KittiFixture(const TempDir& d, bool with_times) {
    dir = d.str("dataset/sequences/06");
    for (int i = 0; i < 12; ++i) {  // 12 frames: natural order 000009 < 000010 < 000011
      char name[32];
      std::snprintf(name, sizeof(name), "%06d.png", i);
      images.push_back(random_image(120, 37, CV_8UC1, 300 + i));
      rdslam::testing::write_png(fs::path(dir) / "image_0" / name, images.back());
    }
    d.write("dataset/sequences/06/calib.txt", kCalibOfficial);
    if (with_times) {
      std::string t;
      for (int i = 0; i < 12; ++i) {
        char buf[32];
        std::snprintf(buf, sizeof(buf), "%e\n", 0.1036822 * i);
        t += buf;
      }
      d.write("dataset/sequences/06/times.txt", t);
    }
    std::string poses;
    for (int i = 0; i < 13; ++i) {  // one more pose than images (an excerpt)
      poses += "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(0.5 * i) + "\n";
    }
    d.write("dataset/poses/06.txt", poses);
  }
  std::string dir;
  std::vector<cv::Mat> images;
};

}  // namespace

TEST(DatasetKitti, OfficialLayoutWithTimesCalibAndPoses) {
  TempDir d;
  KittiFixture fx(d, true);
  auto src = open_source(fx.dir, kDefaults);  // auto-detected
  EXPECT_EQ(src->info().kind, "kitti");
  EXPECT_EQ(src->info().width, 120);
  EXPECT_EQ(src->info().height, 37);
  std::vector<cv::Mat> frames;
  std::vector<int64_t> stamps;
  rdslam::testing::read_all(*src, frames, stamps);
  ASSERT_EQ(frames.size(), 12u);
  for (size_t i = 0; i < 12; ++i) {
    EXPECT_TRUE(same_pixels(frames[i], fx.images[i])) << i;
    // times.txt "%e" keeps 7 significant digits.
    EXPECT_NEAR(static_cast<double>(stamps[i]), 0.1036822e9 * static_cast<double>(i), 1e3) << i;
  }
  const CameraModel cam = *src->camera();
  EXPECT_DOUBLE_EQ(cam.fx, 70.70912);
  EXPECT_DOUBLE_EQ(cam.fy, 70.70912);
  EXPECT_DOUBLE_EQ(cam.cx, 60.18873);
  EXPECT_DOUBLE_EQ(cam.cy, 18.31104);
  EXPECT_FALSE(cam.has_distortion());
  EXPECT_EQ(cam.width, 120);
  const Trajectory gt = *src->ground_truth();
  ASSERT_EQ(gt.size(), 12u);  // cut to the images
  for (size_t i = 0; i < 12; ++i) {
    EXPECT_EQ(gt[i].stamp_ns, stamps[i]);  // pose i has image i's time
    EXPECT_DOUBLE_EQ(gt[i].p_world_cam.z(), 0.5 * static_cast<double>(i));
  }
}

TEST(DatasetKitti, WithoutTimesTheRateApplies) {
  TempDir d;
  KittiFixture fx(d, false);
  SourceOptions o;
  o.kitti_rate_hz = 20.0;
  auto src = open_source("kitti:" + fx.dir, o);
  EXPECT_NEAR(src->info().nominal_fps, 20.0, 1e-9);
  auto src2 = open_source("kitti:" + fx.dir + "?rate_hz=5", o);  // URI parameter wins
  Frame f;
  for (int i = 0; i < 3; ++i) ASSERT_EQ(src2->read(f, 0), SourceStatus::kOk);
  EXPECT_EQ(f.stamp_ns, 400000000);
  EXPECT_EQ((*src2->ground_truth())[2].stamp_ns, 400000000);
}

TEST(DatasetKitti, BadFilesAreReportedWithFileAndLine) {
  TempDir d;
  KittiFixture fx(d, true);
  d.write("dataset/sequences/06/times.txt", "0.0\n0.1\n");
  EXPECT_THROW(open_source("kitti:" + fx.dir, kDefaults),
               std::runtime_error);  // 2 times, 12 images
  d.write("dataset/sequences/06/times.txt", "0.0\nzero\n");
  try {
    read_kitti_times(fx.dir + "/times.txt");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("times.txt:2:"), std::string::npos) << e.what();
  }
  d.write("dataset/sequences/06/calib.txt", "P0: 1 2 3\n");
  EXPECT_THROW(read_kitti_calib(fx.dir + "/calib.txt", 120, 37), std::runtime_error);
  d.write("dataset/sequences/06/calib.txt", "P1: 1 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_THROW(read_kitti_calib(fx.dir + "/calib.txt", 120, 37), std::runtime_error);
}

TEST(DatasetKitti, SharedExcerptOfSequence06) {
  const std::string dir = std::string(RDSLAM_SHARED_DIR) + "/data/kitti06_excerpt";
  if (!fs::exists(dir + "/image_l")) {
    GTEST_SKIP() << "shared data not found at " << dir << " (../shared/data is absent)";
  }
  auto src = open_source("kitti:" + dir, kDefaults);
  EXPECT_EQ(src->info().width, 1226);
  EXPECT_EQ(src->info().height, 370);
  EXPECT_EQ(src->info().frame_count, 51);
  EXPECT_EQ(src->info().format, PixelFormat::kGray8);
  const CameraModel cam = *src->camera();
  EXPECT_DOUBLE_EQ(cam.fx, 707.0912);
  EXPECT_DOUBLE_EQ(cam.cx, 601.8873);
  EXPECT_DOUBLE_EQ(cam.cy, 183.1104);
  Frame f;
  int n = 0;
  while (src->read(f, 0) == SourceStatus::kOk) {
    EXPECT_EQ(f.stamp_ns, n * 100000000LL);  // no times.txt: 10 Hz
    if (n == 50) {
      EXPECT_TRUE(
          same_pixels(f.image, cv::imread(dir + "/image_l/000050.png", cv::IMREAD_UNCHANGED)));
    }
    ++n;
  }
  EXPECT_EQ(n, 51);
  const Trajectory gt = *src->ground_truth();
  ASSERT_EQ(gt.size(), 51u);
  // SOURCE.md: frame 1 at t = (-0.01402, -0.02820, 1.19900); ~59.9 m driven.
  EXPECT_NEAR(gt[1].p_world_cam.x(), -0.01402, 1e-5);
  EXPECT_NEAR(gt[1].p_world_cam.z(), 1.19900, 1e-5);
  EXPECT_EQ(gt[50].stamp_ns, 5000000000LL);
}
