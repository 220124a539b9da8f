// The common --json report keys (issue 3) and their computation from per-frame results.
#include "firmware_app/report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

using rdslam::RunReport;
using rdslam::TrackingState;

namespace {
const TrackingState I = TrackingState::kInitializing;
const TrackingState T = TrackingState::kTracking;
const TrackingState L = TrackingState::kLost;
const TrackingState R = TrackingState::kRelocalized;
}  // namespace

TEST(Report, TrackingStatsFromStates) {
  RunReport r;
  rdslam::compute_tracking_stats({I, I, T, T, L, R, T, L}, r);
  EXPECT_EQ(r.frames, 8);
  EXPECT_EQ(r.tracked_frames, 4);  // T, T, R, T
  EXPECT_DOUBLE_EQ(r.tracked_ratio, 0.5);
  EXPECT_EQ(r.initialized_frame, 2);
  EXPECT_DOUBLE_EQ(r.tracked_ratio_after_init, 4.0 / 6.0);
}

TEST(Report, NeverInitialized) {
  RunReport r;
  rdslam::compute_tracking_stats({I, I, I}, r);
  EXPECT_EQ(r.frames, 3);
  EXPECT_EQ(r.tracked_frames, 0);
  EXPECT_EQ(r.initialized_frame, -1);
  EXPECT_DOUBLE_EQ(r.tracked_ratio, 0.0);
  EXPECT_DOUBLE_EQ(r.tracked_ratio_after_init, 0.0);
  rdslam::compute_tracking_stats({}, r);
  EXPECT_EQ(r.frames, 0);
  EXPECT_DOUBLE_EQ(r.tracked_ratio, 0.0);
}

TEST(Report, PercentilesInterpolateLikeNumpy) {
  EXPECT_DOUBLE_EQ(rdslam::percentile({4, 1, 3, 2}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(rdslam::percentile({4, 1, 3, 2}, 0.99), 3.97);  // 1 + 0.99 * 3 -> 3.97
  EXPECT_DOUBLE_EQ(rdslam::percentile({7}, 0.99), 7.0);
  EXPECT_DOUBLE_EQ(rdslam::percentile({}, 0.5), 0.0);
  RunReport r;
  std::vector<double> lat;
  for (int i = 1; i <= 100; ++i) lat.push_back(i);
  rdslam::compute_latency_stats(lat, r);
  EXPECT_DOUBLE_EQ(r.latency_p50_ms, 50.5);
  EXPECT_DOUBLE_EQ(r.latency_p99_ms, 99.01);
}

TEST(Report, TrackerTimeWhileInitializing) {
  // init_tracker_ms of the replay report: the frames whose result was INITIALIZING only.
  const rdslam::StateTiming t =
      rdslam::tracker_ms_in_state({I, I, I, T, L, I, T}, {10, 30, 20, 1, 2, 40, 3}, I);
  EXPECT_EQ(t.frames, 4);
  ASSERT_TRUE(t.p50_ms && t.p99_ms);
  EXPECT_DOUBLE_EQ(*t.p50_ms, 25.0);                // of {10, 20, 30, 40}
  EXPECT_DOUBLE_EQ(*t.p99_ms, 10 + 0.99 * 3 * 10);  // 39.7
  const rdslam::StateTiming none = rdslam::tracker_ms_in_state({T, T}, {1, 2}, I);
  EXPECT_EQ(none.frames, 0);
  EXPECT_FALSE(none.p50_ms.has_value());
  EXPECT_FALSE(none.p99_ms.has_value());
}

TEST(Report, TrackerTimeWhileLost) {
  // lost_tracker_ms: the frames after a LOST result (relocalization ran on them), whatever
  // their own result; the frame that lost tracking was processed while TRACKING.
  const rdslam::StateTiming t =
      rdslam::tracker_ms_while_lost({T, L, L, L, R, T, L, I, I}, {1, 2, 30, 10, 20, 3, 4, 40, 5});
  EXPECT_EQ(t.frames, 4);  // 30 (L), 10 (L), 20 (R), 40 (I, a reset)
  ASSERT_TRUE(t.p50_ms && t.p99_ms);
  EXPECT_DOUBLE_EQ(*t.p50_ms, 25.0);
  EXPECT_DOUBLE_EQ(*t.p99_ms, 10 + 0.99 * 3 * 10);
  const rdslam::StateTiming none = rdslam::tracker_ms_while_lost({T, L}, {1, 2});
  EXPECT_EQ(none.frames, 0);
  EXPECT_FALSE(none.p50_ms.has_value());
}

TEST(Report, JsonHasTheCommonKeysInOrder) {
  RunReport r;
  r.frames = 10;
  r.tracked_frames = 9;
  r.tracked_ratio = 0.9;
  r.initialized_frame = 1;
  r.tracked_ratio_after_init = 1.0;
  r.ate_rmse_m = 0.0123;
  r.fps = 29.5;
  r.latency_p50_ms = 4.25;
  r.latency_p99_ms = 9.5;
  r.peak_rss_mb = 88;
  EXPECT_EQ(r.to_json(),
            "{\n"
            "  \"frames\": 10,\n"
            "  \"tracked_frames\": 9,\n"
            "  \"tracked_ratio\": 0.9,\n"
            "  \"initialized_frame\": 1,\n"
            "  \"tracked_ratio_after_init\": 1,\n"
            "  \"ate_rmse_m\": 0.0123,\n"
            "  \"ate_rmse_pct_path\": null,\n"
            "  \"fps\": 29.5,\n"
            "  \"latency_ms\": {\n"
            "    \"p50\": 4.25,\n"
            "    \"p99\": 9.5\n"
            "  },\n"
            "  \"peak_rss_mb\": 88\n"
            "}\n");
}

TEST(Report, JsonWriterEscapesAndNests) {
  rdslam::JsonWriter w;
  w.begin_object()
      .value("name", "a \"quoted\"\\path\n")
      .value("ok", true)
      .value("nan", std::nan(""))
      .begin_array("xs")
      .element(1.5)
      .element(-2)
      .end_array()
      .begin_object("empty")
      .end_object()
      .end_object();
  EXPECT_EQ(w.str(),
            "{\n"
            "  \"name\": \"a \\\"quoted\\\"\\\\path\\n\",\n"
            "  \"ok\": true,\n"
            "  \"nan\": null,\n"
            "  \"xs\": [\n"
            "    1.5,\n"
            "    -2\n"
            "  ],\n"
            "  \"empty\": {}\n"
            "}\n");
  rdslam::JsonWriter open;
  open.begin_object();
  EXPECT_THROW(open.str(), std::logic_error);
}

TEST(Report, AteFromTrackedPosesAlignsWithSim3) {
  rdslam::Trajectory gt;
  rdslam::Trajectory est;
  for (int k = 0; k < 20; ++k) {
    rdslam::StampedPose p;
    p.stamp_ns = k * 33333333LL;
    p.p_world_cam = Eigen::Vector3d(0.1 * k, std::sin(0.3 * k), 0.05 * k * k / 20.0);
    gt.push_back(p);
    if (k % 4 == 3) continue;  // frames that were not tracked have no pose
    p.p_world_cam = 0.5 * p.p_world_cam + Eigen::Vector3d(1, 2, 3);
    if (k == 10) p.p_world_cam.x() += 0.05;  // one wrong pose
    est.push_back(p);
  }
  RunReport r;
  EXPECT_EQ(rdslam::compute_ate(gt, est, r), "");
  ASSERT_TRUE(r.ate_rmse_m.has_value());
  ASSERT_TRUE(r.ate_rmse_pct_path.has_value());
  EXPECT_GT(*r.ate_rmse_m, 0.0);
  EXPECT_LT(*r.ate_rmse_m, 0.05);  // the 0.05 (x 2 after scaling) outlier spread over 15 poses
  EXPECT_GT(*r.ate_rmse_pct_path, 0.0);

  EXPECT_EQ(rdslam::compute_ate({}, est, r), "no ground truth");
  EXPECT_FALSE(r.ate_rmse_m.has_value());
  EXPECT_EQ(rdslam::compute_ate(gt, {}, r), "no tracked pose");
  EXPECT_FALSE(r.ate_rmse_pct_path.has_value());
}

TEST(Report, PeakRssGrowsWithTouchedMemory) {
  const double before = rdslam::peak_rss_mb();
  EXPECT_GT(before, 0.0);
  std::vector<char> block(64u << 20);
  std::memset(block.data(), 1, block.size());  // touch every page
  const double after = rdslam::peak_rss_mb();
  EXPECT_GE(after, before + 48.0) << "64 MiB touched; peak RSS " << before << " -> " << after;
  EXPECT_EQ(block[12345], 1);
}
