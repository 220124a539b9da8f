// Issue 7: no initialization from noise or from moving people. A camera at rest (EuRoC
// V1_01 excerpt: the MAV sits still) and a fixed camera watching pedestrians (OpenCV's
// vtest.avi) must stay INITIALIZING, or the published motion must stay below 1% of the scene
// depth (with unit median depth after initialization: 0.01).
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "slam_test_util.h"

namespace rdslam {
namespace {

std::string shared_data(const char* sub) {
  return std::string(RDSLAM_SHARED_DIR) + "/data/" + sub;
}

class VideoFileSource : public FrameSource {
 public:
  explicit VideoFileSource(const std::string& path) : cap_(path) { info_.kind = "video"; }
  SourceStatus read(Frame& out, int) override {
    if (!cap_.read(bgr_)) return SourceStatus::kEndOfStream;
    cv::cvtColor(bgr_, out.image, cv::COLOR_BGR2GRAY);
    out.stamp_ns = static_cast<int64_t>(seq_) * 100000000;  // 10 fps
    out.seq = seq_++;
    return SourceStatus::kOk;
  }
  const SourceInfo& info() const override { return info_; }
  bool opened() const { return cap_.isOpened(); }

 private:
  cv::VideoCapture cap_;
  cv::Mat bgr_;
  uint64_t seq_ = 0;
  SourceInfo info_;
};

// Largest published camera displacement from the first tracked pose (map units: the
// initial median scene depth is 1).
double max_published_motion(const OfflineRun& run, int* tracked) {
  *tracked = 0;
  bool have = false;
  Eigen::Vector3d first(0, 0, 0);
  double m = 0;
  for (const auto& f : run.frames) {
    if (!test::is_tracked(f.result.state)) continue;
    ++*tracked;
    if (!have) {
      first = f.result.p_world_cam;
      have = true;
    }
    m = std::max(m, (f.result.p_world_cam - first).norm());
  }
  return m;
}

TEST(SlamNoMotion, CameraAtRestDoesNotInitialize) {
  const std::string dir = shared_data("euroc_V1_01_micro/mav0/cam0/data");
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "EuRoC excerpt not found at " << dir;
  CameraModel cam;  // cam0 of mav0/cam0/sensor.yaml
  cam.width = 752;
  cam.height = 480;
  cam.fx = 458.654;
  cam.fy = 457.296;
  cam.cx = 367.215;
  cam.cy = 248.375;
  cam.k1 = -0.28340811;
  cam.k2 = 0.07395907;
  cam.p1 = 0.00019359;
  cam.p2 = 1.76187114e-05;
  test::ImageListSource src(test::list_pngs(dir), 50000000);
  const OfflineRun run = run_offline(src, test::params_from_env(), cam);
  int tracked = 0;
  const double motion = max_published_motion(run, &tracked);
  std::printf("[slam] euroc at rest: %zu frames, %d tracked, max motion %.4f\n", run.frames.size(),
              tracked, motion);
  EXPECT_TRUE(tracked == 0 || motion < 0.01) << tracked << " tracked, motion " << motion;
}

TEST(SlamNoMotion, FixedCameraWithPedestriansDoesNotInitialize) {
  const std::string path = shared_data("opencv_vtest/vtest.avi");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "vtest.avi not found at " << path;
  VideoFileSource src(path);
  ASSERT_TRUE(src.opened());
  CameraModel cam;  // no calibration shipped: a plausible 768x576 pinhole
  cam.width = 768;
  cam.height = 576;
  cam.fx = cam.fy = 700;
  cam.cx = 383.5;
  cam.cy = 287.5;
  const OfflineRun run = run_offline(src, test::params_from_env(), cam, 300);
  int tracked = 0;
  const double motion = max_published_motion(run, &tracked);
  std::printf("[slam] vtest: %zu frames, %d tracked, max motion %.4f\n", run.frames.size(), tracked,
              motion);
  EXPECT_TRUE(tracked == 0 || motion < 0.01) << tracked << " tracked, motion " << motion;
}

}  // namespace
}  // namespace rdslam
