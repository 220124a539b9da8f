// KITTI odometry 06, frames 0-50 (../shared/data/kitti06_excerpt): issue 7's real-data bar.
// Tracked >= 96% of frames, ATE (Sim3, all tracked frames) <= 0.1% of the path length.
#include <gtest/gtest.h>

#include <filesystem>

#include "slam_test_util.h"

namespace rdslam {
namespace {

std::string kitti_dir() {
  return std::string(RDSLAM_SHARED_DIR) + "/data/kitti06_excerpt";
}

CameraModel kitti_camera() {
  CameraModel c;
  c.width = 1226;
  c.height = 370;
  c.fx = c.fy = 707.0912;
  c.cx = 601.8873;
  c.cy = 183.1104;
  return c;
}

TEST(SlamKitti, TracksAndMeetsAteBar) {
  if (!std::filesystem::exists(kitti_dir() + "/image_l")) {
    GTEST_SKIP() << "KITTI excerpt not found at " << kitti_dir();
  }
  test::ImageListSource src(test::list_pngs(kitti_dir() + "/image_l"), 100000000);
  const SlamParams params = test::params_from_env();
  const OfflineRun run = run_offline(src, params, kitti_camera());
  const Trajectory gt =
      read_trajectory(kitti_dir() + "/poses.txt", TrajectoryFormat::kKitti, 100000000);
  const test::RunSummary s = test::summarize(run, gt, ("kitti06 " + params.features.mode).c_str());
  ASSERT_TRUE(s.eval_ok);
  EXPECT_GE(s.tracked_frac, 0.96);
  EXPECT_LE(s.ate_rmse_m, 0.001 * s.path_m);
}

}  // namespace
}  // namespace rdslam
