// LcmPublisher (firmware_app/lcm_publisher.h): what goes on the wire decodes with the
// generated C++ types and carries the pipeline's values. In-process subscriber, ttl=0 URL
// on a bus and channels of its own (tests/support/lcm_test_bus.h).
#include <gtest/gtest.h>
#include <lcm/lcm.h>

#include <string>

#include "bot_core/pose_t.hpp"
#include "firmware_app/lcm_publisher.h"
#include "rdslam/pose_t.hpp"
#include "rdslam/status_t.hpp"
#include "tests/support/lcm_test_bus.h"

namespace rdslam {
namespace {

const std::string kUrl = testing::private_lcm_url();
const std::string kPose = testing::private_channel("T_POSE");
const std::string kStatus = testing::private_channel("T_STATUS");
const std::string kBot = testing::private_channel("T_BOT");

struct Received {
  int poses = 0, statuses = 0, bot = 0;
  ::rdslam::pose_t pose;
  ::rdslam::status_t status;
  ::bot_core::pose_t bot_pose;
};

void on_msg(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* r = static_cast<Received*>(user);
  const std::string ch = channel;
  if (ch == kPose) {
    if (r->pose.decode(rbuf->data, 0, rbuf->data_size) > 0) ++r->poses;
  } else if (ch == kStatus) {
    if (r->status.decode(rbuf->data, 0, rbuf->data_size) > 0) ++r->statuses;
  } else if (ch == kBot) {
    if (r->bot_pose.decode(rbuf->data, 0, rbuf->data_size) > 0) ++r->bot;
  }
}

TEST(LcmPublisher, PoseStatusAndBotCorePoseDecodeWithTheGeneratedTypes) {
  lcm_t* sub = lcm_create(kUrl.c_str());
  ASSERT_NE(sub, nullptr);
  Received got;
  lcm_subscribe(sub, "T_.*", on_msg, &got);

  LcmParams p;
  p.url = kUrl;
  p.pose_channel = kPose;
  p.status_channel = kStatus;
  p.publish_bot_core_pose = true;
  p.bot_core_pose_channel = kBot;
  LcmPublisher pub(p);

  FrameResult fr;
  fr.seq = 42;
  fr.stamp_ns = 1403715273262142976LL;
  fr.arrival_mono_ns = 1000000;
  fr.publish_mono_ns = 3500000;
  fr.result.state = TrackingState::kTracking;
  fr.result.p_world_cam = Eigen::Vector3d(1.5, -2.0, 0.25);
  fr.result.q_world_cam = Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5);
  fr.result.inliers = 123;
  fr.result.quality = 0.75;
  for (int i = 0; i < 36; ++i) fr.result.covariance[size_t(i)] = 0.01 * i;
  fr.result.epoch = 3;
  pub.on_frame(fr);
  PipelineStatus s;
  s.mono_ns = 5000000000LL;
  s.state = TrackingState::kLost;
  s.fps = 29.5;
  s.frames_captured = 100;
  s.frames_processed = 97;
  s.frames_dropped = 3;
  s.keyframes = 7;
  s.cpu_s[kTrackerThread] = 1.25;
  pub.on_status(s);

  for (int i = 0; i < 50 && (got.poses < 1 || got.statuses < 1 || got.bot < 1); ++i) {
    lcm_handle_timeout(sub, 100);
  }
  lcm_destroy(sub);
  ASSERT_EQ(got.poses, 1);
  ASSERT_EQ(got.statuses, 1);
  ASSERT_EQ(got.bot, 1);
  EXPECT_EQ(pub.poses_published(), 1u);
  EXPECT_EQ(pub.statuses_published(), 1u);
  EXPECT_EQ(pub.send_failures(), 0u);

  EXPECT_EQ(got.pose.utime, 1403715273262142LL);
  EXPECT_EQ(got.pose.seq, 42);
  EXPECT_EQ(got.pose.position[0], 1.5);
  EXPECT_EQ(got.pose.position[1], -2.0);
  EXPECT_EQ(got.pose.position[2], 0.25);
  EXPECT_EQ(got.pose.orientation[0], 0.5);  // w first
  EXPECT_EQ(got.pose.orientation[2], -0.5);
  EXPECT_EQ(got.pose.version, ::rdslam::pose_t::VERSION);
  EXPECT_EQ(got.pose.version, 2);
  EXPECT_EQ(got.pose.map_epoch, 3);
  EXPECT_EQ(got.pose.covariance[0], 0.0);
  EXPECT_EQ(got.pose.covariance[7], 0.01 * 7);
  EXPECT_EQ(got.pose.covariance[35], 0.01 * 35);
  EXPECT_EQ(got.pose.quality, 0.75);
  EXPECT_EQ(got.pose.inliers, 123);
  EXPECT_EQ(got.pose.state, int8_t{::rdslam::pose_t::STATE_TRACKING});
  EXPECT_EQ(got.pose.latency_us, 2500);

  EXPECT_EQ(got.status.utime, 5000000);
  EXPECT_EQ(got.status.state, int8_t{::rdslam::pose_t::STATE_LOST});
  EXPECT_EQ(got.status.fps, 29.5);
  EXPECT_EQ(got.status.frames_processed, 97);
  EXPECT_EQ(got.status.frames_dropped, 3);
  EXPECT_EQ(got.status.keyframes, 7);
  EXPECT_EQ(got.status.cpu_tracker_s, 1.25);

  EXPECT_EQ(got.bot_pose.utime, 1403715273262142LL);
  EXPECT_EQ(got.bot_pose.pos[0], 1.5);
  EXPECT_EQ(got.bot_pose.orientation[0], 0.5);
}

TEST(LcmPublisher, UnusableUrlIsAStartUpError) {
  LcmParams p;
  p.url = "nosuchprovider://x";
  EXPECT_THROW(LcmPublisher{p}, std::runtime_error);
}

}  // namespace
}  // namespace rdslam
