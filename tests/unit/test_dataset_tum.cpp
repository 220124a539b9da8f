#include <gtest/gtest.h>

#include <filesystem>

#include "core/timestamp.h"
#include "drivers/dataset_tum.h"
#include "drivers/source_factory.h"
#include "tests/support/dataset_fixtures.h"

using namespace rdslam;
using rdslam::testing::random_image;
using rdslam::testing::same_pixels;
using rdslam::testing::TempDir;
namespace fs = std::filesystem;

namespace {

const SourceOptions kDefaults;

// A TUM folder as the benchmark ships it: 6-decimal stamps, rgb/ PNGs (colour), a
// groundtruth.txt at a different rate, comments; plus one 9-decimal stamp.
struct TumFixture {
  explicit TumFixture(const TempDir& d, bool with_camera_yaml) {
    std::string list =
        "# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
        "# timestamp filename\n";
    const char* stamps[] = {"1305031102.175304", "1305031102.211214", "1305031102.243211",
                            "1305031102.275326123"};
    for (int i = 0; i < 4; ++i) {
      images.push_back(random_image(64, 48, CV_8UC3, 100 + i));
      const std::string name = std::string("rgb/") + stamps[i] + ".png";
      rdslam::testing::write_png(d.path() / name, images.back());
      list += std::string(stamps[i]) + " " + name + "\r\n";  // CRLF must be tolerated
      int64_t ns = 0;
      parse_seconds_ns(stamps[i], ns);
      stamp_ns.push_back(ns);
    }
    d.write("rgb.txt", list);
    d.write("groundtruth.txt",
            "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
            "1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986\n"
            "1305031098.6758 1.3543 0.6306 1.6360 0.6129 0.5966 -0.3316 -0.3980\n");
    if (with_camera_yaml) {
      d.write("camera.yaml",
              "width: 64\nheight: 48\nfx: 51.7\nfy: 51.6\ncx: 31.5\ncy: 23.5\n"
              "k1: 0.26\nk2: -0.95\np1: -0.005\np2: 0.002\nk3: 1.16\n");
    }
  }
  std::vector<cv::Mat> images;
  std::vector<int64_t> stamp_ns;
};

}  // namespace

TEST(DatasetTum, FramesTimestampsAndGroundTruthRoundTrip) {
  TempDir d;
  TumFixture fx(d, true);
  for (const std::string& uri : {"tum:" + d.str(), d.str()}) {  // explicit and auto-detected
    auto src = open_source(uri, kDefaults);
    EXPECT_EQ(src->info().kind, "tum");
    EXPECT_EQ(src->info().width, 64);
    EXPECT_EQ(src->info().height, 48);
    EXPECT_EQ(src->info().format, PixelFormat::kBgr8);
    EXPECT_EQ(src->info().frame_count, 4);
    EXPECT_FALSE(src->info().live);
    std::vector<cv::Mat> frames;
    std::vector<int64_t> stamps;
    rdslam::testing::read_all(*src, frames, stamps);
    ASSERT_EQ(frames.size(), 4u);
    for (size_t i = 0; i < 4; ++i) {
      EXPECT_TRUE(same_pixels(frames[i], fx.images[i])) << i;
      EXPECT_EQ(stamps[i], fx.stamp_ns[i]) << i;
    }
    EXPECT_EQ(stamps[3], 1305031102275326123LL);  // 9 decimals, exact
    const auto gt = src->ground_truth();
    ASSERT_TRUE(gt.has_value());
    ASSERT_EQ(gt->size(), 2u);
    EXPECT_EQ((*gt)[1].stamp_ns, 1305031098675800000LL);
    EXPECT_DOUBLE_EQ((*gt)[1].p_world_cam.x(), 1.3543);
    // TUM has no calibration file: the camera.yaml beside the data applies.
    const auto cam = src->camera();
    ASSERT_TRUE(cam.has_value());
    EXPECT_DOUBLE_EQ(cam->fx, 51.7);
    EXPECT_DOUBLE_EQ(cam->k3, 1.16);
    EXPECT_EQ(cam->model, "pinhole-radtan");
  }
}

TEST(DatasetTum, WithoutCameraYamlTheConfigCameraApplies) {
  TempDir d;
  TumFixture fx(d, false);
  SourceOptions o;
  o.config_camera.width = 64;
  o.config_camera.height = 48;
  o.config_camera.fx = 77.0;
  o.config_camera.cx = 32;
  o.config_camera.cy = 24;
  auto src = open_source("tum:" + d.str(), o);
  ASSERT_TRUE(src->camera().has_value());
  EXPECT_DOUBLE_EQ(src->camera()->fx, 77.0);
}

TEST(DatasetTum, MissingImageIsAFaultAndReplayContinues) {
  TempDir d;
  TumFixture fx(d, true);
  fs::remove(d.path() / "rgb/1305031102.211214.png");
  auto src = open_source("tum:" + d.str(), kDefaults);
  Frame f;
  std::vector<SourceStatus> st;
  for (int i = 0; i < 5; ++i) st.push_back(src->read(f, 100));
  EXPECT_EQ(st,
            (std::vector<SourceStatus>{SourceStatus::kOk, SourceStatus::kFault, SourceStatus::kOk,
                                       SourceStatus::kOk, SourceStatus::kEndOfStream}));
  EXPECT_EQ(src->counters().faults, 1u);
  EXPECT_EQ(src->counters().delivered, 3u);
}

TEST(DatasetTum, WrongSizeOrCorruptImageIsAFault) {
  TempDir d;
  TumFixture fx(d, true);
  rdslam::testing::write_png(d.path() / "rgb/1305031102.211214.png",
                             random_image(32, 48, CV_8UC3, 1));
  d.write("rgb/1305031102.243211.png", "not a png at all");
  auto src = open_source("tum:" + d.str(), kDefaults);
  Frame f;
  EXPECT_EQ(src->read(f, 0), SourceStatus::kOk);
  EXPECT_EQ(src->read(f, 0), SourceStatus::kFault);
  EXPECT_EQ(src->read(f, 0), SourceStatus::kFault);
  EXPECT_EQ(src->read(f, 0), SourceStatus::kOk);
  EXPECT_TRUE(same_pixels(f.image, fx.images[3]));
  EXPECT_EQ(src->counters().faults, 2u);
}

TEST(DatasetTum, MalformedListNamesFileAndLine) {
  TempDir d;
  TumFixture fx(d, true);
  d.write("rgb.txt", "# c\n1305031102.175304 rgb/a.png\n1305031102.2x rgb/b.png\n");
  try {
    read_tum_dataset(d.str());
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("rgb.txt:3:"), std::string::npos) << e.what();
  }
  d.write("rgb.txt", "1305031102.175304\n");
  EXPECT_THROW(read_tum_dataset(d.str()), std::runtime_error);
  d.write("rgb.txt", "# nothing\n");
  EXPECT_THROW(read_tum_dataset(d.str()), std::runtime_error);
  d.write("rgb.txt", "1305031102.175304 rgb/1305031102.175304.png\n");
  d.write("camera.yaml", "width: 64\nheight: 48\nfx: 50\nfy: 50\ncx: 32\ncy: 24\nfoo: 1\n");
  try {
    open_source("tum:" + d.str(), kDefaults);
    FAIL() << "unknown camera.yaml key accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("foo"), std::string::npos) << e.what();
  }
  d.write("camera.yaml", "width: 64\nheight: 48\nfx: -50\nfy: 50\ncx: 32\ncy: 24\n");
  EXPECT_THROW(open_source("tum:" + d.str(), kDefaults), std::runtime_error);
  d.write("camera.yaml", "width: 64\nheight: 48\nfx: 50\ncx: 32\ncy: 24\n");
  EXPECT_THROW(open_source("tum:" + d.str(), kDefaults), std::runtime_error);
}

TEST(DatasetTum, PacedReplayFollowsTheRecordedTimestamps) {
  TempDir d;
  TumFixture fx(d, true);
  SourceOptions o;
  o.speed = 4.0;  // the fixture spans 100 ms: 25 ms at 4x
  auto src = open_source("tum:" + d.str(), o);
  EXPECT_TRUE(src->info().live);
  Frame f;
  std::vector<int64_t> arrival;
  while (src->read(f, 1000) == SourceStatus::kOk) arrival.push_back(f.arrival_mono_ns);
  ASSERT_EQ(arrival.size(), 4u);
  // arrival_mono_ns is the due time: exactly the recorded spacing divided by the speed.
  for (size_t i = 1; i < 4; ++i) {
    EXPECT_NEAR(static_cast<double>(arrival[i] - arrival[0]),
                static_cast<double>(fx.stamp_ns[i] - fx.stamp_ns[0]) / 4.0, 1.0);
  }
}
