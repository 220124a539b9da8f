// make_slam_stages() on the real pipeline threads (firmware_app/pipeline.h, lossless replay,
// tracker.sync_mapper as `rdslam replay` sets it): the KITTI excerpt meets the same bars as
// the single-thread run.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include "drivers/synth_source.h"
#include "firmware_app/pipeline.h"
#include "slam_test_util.h"

namespace rdslam {
namespace {

TEST(SlamThreaded, KittiThroughPipelineThreads) {
  const std::string dir = std::string(RDSLAM_SHARED_DIR) + "/data/kitti06_excerpt";
  if (!std::filesystem::exists(dir + "/image_l")) GTEST_SKIP() << "KITTI excerpt not found";
  CameraModel cam;
  cam.width = 1226;
  cam.height = 370;
  cam.fx = cam.fy = 707.0912;
  cam.cx = 601.8873;
  cam.cy = 183.1104;
  SlamParams params = test::params_from_env();
  params.tracker.sync_mapper = true;
  SlamStages stages = make_slam_stages(params, cam);
  test::ImageListSource src(test::list_pngs(dir + "/image_l"), 100000000);
  PipelineOptions opt;
  opt.lossless = true;
  const ReplayReport rr = replay_source(src, *stages.tracker, *stages.mapper, opt);
  Trajectory est;
  int tracked = 0;
  for (const auto& f : rr.frames) {
    if (!test::is_tracked(f.result.state)) continue;
    ++tracked;
    StampedPose p;
    p.stamp_ns = f.stamp_ns;
    p.p_world_cam = f.result.p_world_cam;
    p.q_world_cam = f.result.q_world_cam;
    est.push_back(p);
  }
  const Trajectory gt = read_trajectory(dir + "/poses.txt", TrajectoryFormat::kKitti, 100000000);
  ASSERT_EQ(rr.frames.size(), 51u);
  EXPECT_GE(tracked, 49);
  const EvalResult r = evaluate_trajectories(gt, est, EvalParams{});
  ASSERT_TRUE(r.ok) << r.error;
  std::printf("[slam] threaded kitti: tracked %d/51, ATE %.4f m over %.2f m\n", tracked,
              r.ate_m.rmse, r.gt_path_length_m);
  EXPECT_LE(r.ate_m.rmse, 0.001 * r.gt_path_length_m);
}

// The final trajectory (replay_trajectory() with the final map: frames re-anchored on their
// reference keyframes' final poses) has a pose for every tracked frame, is no worse than the online
// trajectory and differs from it (the keyframes moved after the frames were tracked).
TEST(SlamThreaded, FinalTrajectoryReanchorsOnRefinedKeyframes) {
  SourceOptions so;
  so.speed = 0.0;  // as fast as the pipeline takes frames
  auto src = open_synth_source("static_halfsphere", so, 150, 1);
  const CameraModel cam = *src->camera();
  SlamParams params = test::params_from_env();
  params.tracker.sync_mapper = true;
  SlamStages stages = make_slam_stages(params, cam);
  stages.mapper->set_keep_trail(true);
  PipelineOptions opt;
  opt.lossless = true;
  const ReplayReport rr = replay_source(*src, *stages.tracker, *stages.mapper, opt);
  const Trajectory online = replay_trajectory(rr);
  const Trajectory final_est = replay_trajectory(rr, stages.mapper.get());
  ASSERT_GE(online.size(), 120u);
  ASSERT_EQ(final_est.size(), online.size());
  double moved = 0.0;
  for (size_t i = 0; i < online.size(); ++i) {
    EXPECT_EQ(final_est[i].stamp_ns, online[i].stamp_ns);
    moved = std::max(moved, (final_est[i].p_world_cam - online[i].p_world_cam).norm());
  }
  EXPECT_GT(moved, 1e-4);
  const Trajectory gt = *src->ground_truth();
  const EvalResult r_online = evaluate_trajectories(gt, online, EvalParams{});
  const EvalResult r_final = evaluate_trajectories(gt, final_est, EvalParams{});
  ASSERT_TRUE(r_online.ok && r_final.ok);
  std::printf("[slam] static_halfsphere 150 frames: ATE online %.3f%%, final %.3f%% of path\n",
              r_online.ate_pct_path.rmse, r_final.ate_pct_path.rmse);
  EXPECT_LE(r_final.ate_m.rmse, r_online.ate_m.rmse);
}

}  // namespace
}  // namespace rdslam
