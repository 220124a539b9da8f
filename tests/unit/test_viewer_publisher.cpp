// ViewerPublisher (firmware_app/viewer_publisher.h): the recycling debug sink lends records
// only when due and free, and its thread publishes a downscaled JPEG bot_core.image_t and an
// rdslam.map_t whose point sample respects viewer.map_max_points (at most a quarter of it
// invalidated points) and carries the keyframe poses. In-process subscriber, ttl=0 URL on a
// bus and channel names of its own (tests/support/lcm_test_bus.h).
#include <gtest/gtest.h>
#include <lcm/lcm.h>

#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>

#include "bot_core/image_t.hpp"
#include "firmware_app/viewer_publisher.h"
#include "rdslam/map_t.hpp"
#include "tests/support/lcm_test_bus.h"

namespace rdslam {
namespace {

// A bus and channel names of this process only (tests/support/lcm_test_bus.h).
const std::string kUrl = testing::private_lcm_url();
const std::string kImageChannel = testing::private_channel("T_IMAGE");
const std::string kMapChannel = testing::private_channel("T_MAP");

struct Received {
  int images = 0, maps = 0;
  bot_core::image_t image;
  ::rdslam::map_t map;
};

void on_msg(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* r = static_cast<Received*>(user);
  const std::string ch = channel;
  if (ch == kImageChannel && r->image.decode(rbuf->data, 0, rbuf->data_size) > 0) ++r->images;
  if (ch == kMapChannel && r->map.decode(rbuf->data, 0, rbuf->data_size) > 0) ++r->maps;
}

CameraModel camera_1280x720() {
  CameraModel c;
  c.width = 1280;
  c.height = 720;
  c.fx = c.fy = 900;
  c.cx = 639.5;
  c.cy = 359.5;
  return c;
}

std::shared_ptr<const MapSnapshot> snapshot(int points, int invalid) {
  auto s = std::make_shared<MapSnapshot>();
  for (int i = 0; i < points; ++i) {
    s->ids.push_back(i);
    s->p_world.emplace_back(0.01 * (i % 50) - 0.25, 0.01 * (i / 50) - 0.1, 2.0);
  }
  for (int i = 0; i < invalid; ++i) {
    s->invalid_ids.push_back(10000 + i);
    s->invalid_p_world.emplace_back(0.0, 0.0, 3.0 + i);
  }
  for (int k = 0; k < 3; ++k) {
    Pose T;  // T_cam_world: camera centre at (0.1 k, 0, 0)
    T.t = Eigen::Vector3d(-0.1 * k, 0, 0);
    s->kf_ids.push_back(k);
    s->kf_pose.push_back(T);
  }
  return s;
}

void fill(DebugFrame& d, uint64_t seq, const std::shared_ptr<const MapSnapshot>& snap) {
  d.seq = seq;
  d.stamp_ns = 1'000'000'000LL * static_cast<int64_t>(seq + 1);
  d.result.state = TrackingState::kTracking;
  d.has_pose = true;
  d.T_cam_world = Pose();
  d.image.create(720, 1280, CV_8UC3);
  cv::randu(d.image, 0, 255);
  d.features.assign(3, DebugFeature{100.f, 100.f, DebugFeatureKind::kInlier});
  d.snapshot = snap;
}

TEST(ViewerPublisher, LendsRecordsWhenDueAndPublishesAScaledJpegAndACappedMap) {
  lcm_t* sub = lcm_create(kUrl.c_str());
  ASSERT_NE(sub, nullptr);
  Received got;
  lcm_subscribe(sub, "T_.*", on_msg, &got);

  LcmParams lp;
  lp.url = kUrl;
  lp.image_channel = kImageChannel;
  lp.map_channel = kMapChannel;
  ViewerParams vp;
  vp.image_hz = 5;  // a record every 200 ms
  vp.map_hz = 5;
  vp.map_max_points = 100;
  ViewerPublisher pub(lp, vp, camera_1280x720());
  ASSERT_TRUE(pub.recycles_records());
  const auto snap = snapshot(1000, 60);
  Frame frame;

  DebugFrame* a = pub.acquire_record(frame);
  ASSERT_NE(a, nullptr) << "the first frame is due";
  EXPECT_EQ(pub.acquire_record(frame), nullptr) << "not due again within the period";
  fill(*a, 7, snap);
  pub.submit_record(a);
  std::this_thread::sleep_for(std::chrono::milliseconds(250));
  DebugFrame* b = pub.acquire_record(frame);
  ASSERT_NE(b, nullptr) << "due again after the period";
  fill(*b, 8, snap);
  pub.submit_record(b);
  for (int i = 0; i < 50 && (got.images < 2 || got.maps < 2); ++i) lcm_handle_timeout(sub, 100);
  pub.stop();
  lcm_destroy(sub);

  const ViewerPublisherStats st = pub.stats();
  EXPECT_EQ(st.records, 2u);
  ASSERT_EQ(got.images, 2);
  ASSERT_EQ(got.maps, 2);
  EXPECT_EQ(st.images, 2u);
  EXPECT_EQ(st.maps, 2u);

  // Header (48 px) + 1280x720 image, downscaled to viewer.image_max_width = 640.
  EXPECT_EQ(got.image.pixelformat, bot_core::image_t::PIXEL_FORMAT_MJPEG);
  EXPECT_EQ(got.image.width, 640);
  EXPECT_EQ(got.image.height, 384);
  EXPECT_EQ(got.image.utime, 9'000'000);
  const cv::Mat jpg = cv::imdecode(got.image.data, cv::IMREAD_COLOR);
  EXPECT_EQ(jpg.cols, 640);
  EXPECT_EQ(jpg.rows, 384);

  const ::rdslam::map_t& m = got.map;
  EXPECT_EQ(m.seq, 8);
  EXPECT_EQ(m.total_points, 1000);
  ASSERT_EQ(m.num_points, 100) << "capped at viewer.map_max_points";
  int invalid = 0;
  for (int8_t v : m.point_valid) invalid += v == 0;
  EXPECT_EQ(invalid, 25) << "the newest invalidated points, at most a quarter of the cap";
  EXPECT_FLOAT_EQ(m.point_position.back()[2], 3.0f + 59) << "the newest invalidation last";
  EXPECT_FLOAT_EQ(m.point_position.front()[2], 2.0f);
  ASSERT_EQ(m.num_keyframes, 3);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(m.keyframe_position[size_t(k)][0], 0.1 * k, 1e-12);
    EXPECT_NEAR(m.keyframe_orientation[size_t(k)][0], 1.0, 1e-12);  // w of the identity
    EXPECT_EQ(m.keyframe_id[size_t(k)], k);
  }
}

TEST(ViewerPublisher, SkipsAndCountsWhenNoRecordIsFree) {
  LcmParams lp;
  lp.url = kUrl;
  lp.image_channel = kImageChannel;
  lp.map_channel = kMapChannel;
  ViewerParams vp;
  vp.image_hz = 30;
  vp.map_hz = 0;
  ViewerPublisher pub(lp, vp, camera_1280x720());
  Frame frame;
  DebugFrame* held[2] = {nullptr, nullptr};
  for (auto& h : held) {
    for (int i = 0; i < 40 && !h; ++i) {
      h = pub.acquire_record(frame);
      if (!h) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ASSERT_NE(h, nullptr);
  }
  EXPECT_NE(held[0], held[1]);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(pub.acquire_record(frame), nullptr) << "both records are lent";
  EXPECT_EQ(pub.stats().skipped_busy, 1u);
  for (auto* h : held) {
    fill(*h, 1, nullptr);
    pub.submit_record(h);
  }
  pub.stop();
  EXPECT_EQ(pub.stats().records, 2u);
}

}  // namespace
}  // namespace rdslam
