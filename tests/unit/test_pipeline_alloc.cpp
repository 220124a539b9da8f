// Zero heap allocation on the capture-to-publish path in steady state (issue 9, item 3).
//
// This binary counts every allocation of every thread (tests/unit/alloc_counting.h: global
// operator new/delete and the C allocator, so LCM, glib and OpenCV's fastMalloc count too).
// The same proof with the real SLAM tracker is tests/unit/test_tracker_alloc.cpp.
//
// Measured window: from the moment the publisher hands frame kWarmup to the sinks until it
// hands frame kWarmup + kMeasured - 1, i.e. kMeasured = 1,000 frames that each went through
// capture (FrameSource::read into a pool slot), the capture->tracker ring, the pass-through
// tracker (ground-truth lookup, keyframe hand-off to the mapper every 10th frame), the
// mapper thread, the tracker->publisher ring, the LCM publisher (rdslam.pose_t encode +
// lcm_publish on a ttl=0 URL, bot_core.pose_t too) and the periodic status (status_t +
// the stats log line), with all four pipeline threads running.
//
// Excluded, by construction (outside the window):
// - start-up: frame pool and ring allocation, thread creation (std::thread), lcm_create(),
//   the first kWarmup frames (first-touch of lazily allocated library state);
// - shutdown: joining threads, destroying the pipeline;
// - the test's own main thread, which only waits on a condition variable inside the window.
// Nothing inside the window is excluded.
#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>

#include "firmware_app/lcm_publisher.h"
#include "firmware_app/passthrough_stages.h"
#include "firmware_app/pipeline.h"
#include "tests/support/lcm_test_bus.h"
#include "tests/unit/alloc_counting.h"
#include "tests/unit/pipeline_fakes.h"

namespace rdslam {
namespace {

constexpr uint64_t kWarmup = 1000;
constexpr uint64_t kMeasured = 1000;

// Runs on the publisher thread (after the LCM sink): samples the counters at the edges of
// the measured window and wakes the test when the window is closed.
class WindowSink : public PipelineSink {
 public:
  void on_frame(const FrameResult& r) override {
    ++frames_;
    if (r.seq == kWarmup) {
      new0_ = g_new_calls.load();
      malloc0_ = g_malloc_calls.load();
      first_ = r.seq;
      statuses0_ = statuses_;
    }
    if (r.seq == kWarmup + kMeasured - 1) {
      new1_ = g_new_calls.load();
      malloc1_ = g_malloc_calls.load();
      frames_in_window_ = frames_;
      statuses1_ = statuses_;
      {
        std::lock_guard<std::mutex> lock(m_);
        done_ = true;
      }
      cv_.notify_all();
    }
  }
  void on_status(const PipelineStatus&) override { ++statuses_; }
  void wait_done() {
    std::unique_lock<std::mutex> lock(m_);
    cv_.wait(lock, [&] { return done_; });
  }
  uint64_t new0_ = 0, new1_ = 0, malloc0_ = 0, malloc1_ = 0;
  uint64_t frames_ = 0, frames_in_window_ = 0, first_ = 0;
  int statuses_ = 0, statuses0_ = 0, statuses1_ = 0;

 private:
  std::mutex m_;
  std::condition_variable cv_;
  bool done_ = false;
};

TEST(PipelineAlloc, CountingAllocatorSeesAllocations) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  // The instrument itself must work, or a zero below would prove nothing.
  const uint64_t n0 = g_new_calls.load(), m0 = g_malloc_calls.load();
  auto* v = new std::vector<int>(1000);
  void* c = std::malloc(64);
  EXPECT_GE(g_new_calls.load() - n0, 2u);
  EXPECT_GE(g_malloc_calls.load() - m0, 3u);
  std::free(c);
  delete v;
#endif
}

TEST(PipelineAlloc, ZeroAllocationsOverOneThousandSteadyStateFrames) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  const uint64_t total = kWarmup + kMeasured + 200;
  // Paced at 2 kHz so the 1,000-frame window spans about 0.5 s and contains several
  // periodic status reports (status_t encode + publish, stats log line).
  const int64_t period_ns = 500000;
  testing_fakes::CountingSource source(static_cast<int64_t>(total), 640, 480, period_ns,
                                       /*paced=*/true);
  Trajectory gt;
  for (uint64_t i = 0; i < total; ++i) {
    StampedPose p;
    p.stamp_ns = static_cast<int64_t>(i) * period_ns;
    p.p_world_cam = Eigen::Vector3d(0.01 * i, 0, 0);
    gt.push_back(p);
  }
  PassthroughStages stages(std::move(gt));
  LcmParams lp;
  lp.url = testing::private_lcm_url();
  lp.pose_channel = "RDSLAM_POSE_ALLOC_TEST";
  lp.status_channel = "RDSLAM_STATUS_ALLOC_TEST";
  lp.publish_bot_core_pose = true;
  lp.bot_core_pose_channel = "POSE_BODY_ALLOC_TEST";
  LcmPublisher lcm(lp);
  WindowSink window;
  PipelineOptions o;
  o.lossless = true;               // every frame reaches the publisher: the window is exact
  o.params.stats_period_ms = 100;  // several status reports inside the window
  Pipeline p(source, stages.tracker(), stages.mapper(), o);
  p.add_sink(&lcm);
  p.add_sink(&window);
  p.start();
  window.wait_done();
  p.join();

  EXPECT_EQ(window.first_, kWarmup);
  EXPECT_EQ(window.frames_in_window_ - kWarmup, kMeasured);
  EXPECT_GE(lcm.poses_published() + lcm.send_failures(), total);
  EXPECT_GE(window.statuses1_ - window.statuses0_, 2) << "status reports inside the window";
  EXPECT_EQ(window.new1_ - window.new0_, 0u) << "operator new calls on the frame path";
  EXPECT_EQ(window.malloc1_ - window.malloc0_, 0u) << "C allocations on the frame path";
  std::printf(
      "[ measured ] %llu frames, %d status reports in the window: %llu operator new, "
      "%llu malloc-family calls; lcm poses published %llu, send failures %llu\n",
      static_cast<unsigned long long>(kMeasured), window.statuses1_ - window.statuses0_,
      static_cast<unsigned long long>(window.new1_ - window.new0_),
      static_cast<unsigned long long>(window.malloc1_ - window.malloc0_),
      static_cast<unsigned long long>(lcm.poses_published()),
      static_cast<unsigned long long>(lcm.send_failures()));
#endif
}

}  // namespace
}  // namespace rdslam
