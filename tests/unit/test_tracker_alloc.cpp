// Zero heap allocation in the REAL SLAM tracker after warm-up (the project rule; issue 10).
//
// Every allocation of the process is counted (tests/unit/alloc_counting.h: operator new and
// the C allocator, so OpenCV, Eigen and Ceres allocations count too). The tracker and the
// mapper of make_slam_stages() run alternately in this thread on the synthetic static scene
// `static_xyz` at 640x480 in the default (ORB) mode; the measured window is the sum of the
// tracker's track() calls over the frames after warm-up, i.e. the whole tracker part of the
// capture-to-publish path: colour conversion, pyramid, FAST, bucketing, descriptors, motion
// and local-map matching, PARSAC, eq. (1) refinement, the keyframe decision and the
// keyframe hand-off to the mapper (features copied into a preallocated ring slot).
// The mapper's step() calls (another thread in the pipeline; keyframe work, not per-frame)
// and the source's rendering are outside the window. The rest of the path (capture ring,
// publisher, LCM) is covered by test_pipeline_alloc. The same on `walking_xyz_fisheye`: a
// lens (features undistorted through the extractor's precomputed table) and people walking.
//
// Set RDSLAM_ALLOC_TRACE=1 to print the call stack of every allocation in the window.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/debug_frame.h"
#include "core/slam.h"
#include "drivers/synth_source.h"
#include "tests/unit/alloc_counting.h"

namespace rdslam {
namespace {

constexpr int kFrames = 150;
constexpr int kWarmup = 60;  // initialization (OpenCV model fitting) and first keyframes

TEST(TrackerAlloc, CountingAllocatorSeesAllocations) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  const uint64_t m0 = g_malloc_calls.load();
  void* p = std::malloc(32);
  auto* v = new std::vector<int>(10);
  EXPECT_GE(g_malloc_calls.load() - m0, 3u);
  delete v;
  std::free(p);
  // Allocations inside OpenCV (cv::fastMalloc) are seen too: a new output image.
  const cv::Mat img(48, 64, CV_8UC1, cv::Scalar(7));
  const uint64_t m1 = g_malloc_calls.load();
  {
    cv::Mat out;
    cv::GaussianBlur(img, out, cv::Size(7, 7), 2.0);
  }
  EXPECT_GE(g_malloc_calls.load() - m1, 1u);
#endif
}

#if RDSLAM_ALLOC_COUNTING
// A recycling debug sink as the live viewer's (firmware_app/viewer_publisher.h): one record,
// lent every third frame, handed back at once.
class RecyclingSink final : public DebugFrameSink {
 public:
  RecyclingSink() { record_.features.reserve(10000 + 64); }
  void on_debug_frame(DebugFrame&& /*frame*/) override { ++legacy_calls; }
  bool recycles_records() const override { return true; }
  DebugFrame* acquire_record(const Frame& /*frame*/) override {
    return (asked++ % 3 == 0) ? &record_ : nullptr;
  }
  void submit_record(DebugFrame* record) override {
    ++filled;
    if (record == &record_ && !record->image.empty() && !record->features.empty()) ++complete;
    if (record->has_pose && record->snapshot) ++with_map;
  }
  int asked = 0, filled = 0, complete = 0, with_map = 0, legacy_calls = 0;

 private:
  DebugFrame record_;
};

// Runs `scenario`'s first `frames` frames through the tracker and mapper and asserts that
// the tracker's track() calls after the warm-up do not allocate (with `debug_sink`, also the
// filling of its records).
void expect_no_allocation_after_warm_up(const char* scenario, int frames,
                                        RecyclingSink* debug_sink = nullptr) {
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_synth_source(scenario, so, frames);
  const CameraModel cam = *src->camera();
  SlamParams params;  // the defaults: ORB features, PARSAC per frame
  SlamStages stages = make_slam_stages(params, cam);
  if (debug_sink) {
    ASSERT_TRUE(stages.tracker->set_debug_sink(debug_sink));
  }
  const bool trace = std::getenv("RDSLAM_ALLOC_TRACE") != nullptr;

  Frame frame;
  uint64_t window_mallocs = 0, window_news = 0;
  int measured = 0, tracked = 0, keyframe_frames = 0, last_keyframes = 0;
  int max_per_frame = 0;
  for (int i = 0; i < frames; ++i) {
    if (src->read(frame, 1000) != SourceStatus::kOk) break;
    const bool in_window = i >= kWarmup;
    const uint64_t m0 = g_malloc_calls.load(), n0 = g_new_calls.load();
    if (in_window && trace) g_alloc_trace = true;
    const TrackResult r = stages.tracker->track(frame);
    g_alloc_trace = false;
    const uint64_t dm = g_malloc_calls.load() - m0, dn = g_new_calls.load() - n0;
    while (stages.mapper->step(0)) {
    }
    if (!in_window) continue;
    ++measured;
    window_mallocs += dm;
    window_news += dn;
    max_per_frame = std::max(max_per_frame, static_cast<int>(dm));
    tracked += r.state == TrackingState::kTracking;
    keyframe_frames += r.keyframes != last_keyframes;
    last_keyframes = r.keyframes;
  }
  ASSERT_EQ(measured, frames - kWarmup) << scenario;
  // The window must exercise the real path: tracking, and keyframes handed to the mapper.
  EXPECT_EQ(tracked, measured) << scenario << ": every measured frame tracked";
  EXPECT_GE(keyframe_frames, 1) << scenario << ": keyframes were created inside the window";
  std::printf(
      "[ measured ] %s: %d tracked frames (%d with a new keyframe): %llu malloc-family "
      "calls, %llu operator new, at most %d in one frame\n",
      scenario, measured, keyframe_frames, static_cast<unsigned long long>(window_mallocs),
      static_cast<unsigned long long>(window_news), max_per_frame);
  EXPECT_EQ(window_mallocs, 0u) << scenario << ": C allocations in track() after warm-up";
  EXPECT_EQ(window_news, 0u) << scenario << ": operator new calls in track() after warm-up";
}
#endif

TEST(TrackerAlloc, SlamTrackerDoesNotAllocateAfterWarmUp) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  expect_no_allocation_after_warm_up("static_xyz", kFrames);
#endif
}

// The live viewer's image and map come from debug records the tracker fills in place
// (core/debug_frame.h, recycling sinks): no allocation on the tracker thread either.
TEST(TrackerAlloc, RecyclingDebugSinkDoesNotAllocateAfterWarmUp) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  RecyclingSink sink;
  expect_no_allocation_after_warm_up("static_xyz", kFrames, &sink);
  EXPECT_EQ(sink.asked, kFrames) << "asked once per frame";
  EXPECT_EQ(sink.filled, kFrames / 3) << "filled only when lent";
  EXPECT_EQ(sink.complete, sink.filled) << "every record has the image and the features";
  EXPECT_GT(sink.with_map, sink.filled / 2) << "records carry the pose and the map snapshot";
  EXPECT_EQ(sink.legacy_calls, 0) << "a recycling sink gets no allocated records";
#endif
}

TEST(TrackerAlloc, SlamTrackerThroughALensDoesNotAllocateAfterWarmUp) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  expect_no_allocation_after_warm_up("walking_xyz_fisheye", kFrames);
#endif
}

// synth:dim while the light fades to 15% (frames 60-150) and stays there (150-180): the
// per-cell FAST fallback re-detects most grid cells, with its own buffers.
TEST(TrackerAlloc, DimFramesWithTheCellFallbackDoNotAllocate) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  expect_no_allocation_after_warm_up("dim", 180);
#endif
}

TEST(TrackerAlloc, SlamTrackerDoesNotAllocateWhileLost) {
#if !RDSLAM_ALLOC_COUNTING
  GTEST_SKIP() << "allocation counting is disabled under sanitizers";
#else
  // Relocalization (issue 23): static_xyz is tracked for 120 frames; then 8 frames of
  // textured noise (features everywhere, no place of the map) make the tracker LOST and run
  // place recognition and matching without success; then the sequence starts again from its
  // first frame (a jump back), where the tracker relocalizes. The measured window is every
  // track() call made while LOST (the frame after a LOST result), the successful one included.
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_synth_source("static_xyz", so, 120);
  const CameraModel cam = *src->camera();
  SlamParams params;  // the defaults: ORB features with the place-recognition vocabulary
  SlamStages stages = make_slam_stages(params, cam);
  const bool trace = std::getenv("RDSLAM_ALLOC_TRACE") != nullptr;
  Frame frame;
  TrackingState last = TrackingState::kInitializing;
  int64_t stamp = 0;
  uint64_t window_mallocs = 0, window_news = 0;
  int lost_frames = 0, relocalized = -1, n = 0;
  auto step = [&](const Frame& f) {
    const bool in_window = last == TrackingState::kLost;
    const uint64_t m0 = g_malloc_calls.load(), n0 = g_new_calls.load();
    if (in_window && trace) g_alloc_trace = true;
    const TrackResult r = stages.tracker->track(f);
    g_alloc_trace = false;
    if (in_window) {
      window_mallocs += g_malloc_calls.load() - m0;
      window_news += g_new_calls.load() - n0;
      ++lost_frames;
      if (r.state == TrackingState::kRelocalized && relocalized < 0) relocalized = n;
    }
    while (stages.mapper->step(0)) {
    }
    last = r.state;
    ++n;
  };
  while (src->read(frame, 1000) == SourceStatus::kOk) {
    stamp = frame.stamp_ns;
    step(frame);
  }
  ASSERT_EQ(last, TrackingState::kTracking) << "static_xyz tracked before the jump";
  cv::Mat noise(frame.image.size(), frame.image.type());
  for (int i = 0; i < 8; ++i) {
    cv::randu(noise, 0, 255);
    cv::GaussianBlur(noise, noise, cv::Size(5, 5), 1.2);
    noise.copyTo(frame.image);
    frame.stamp_ns = stamp += 33'333'333;
    ++frame.seq;
    step(frame);
  }
  EXPECT_EQ(last, TrackingState::kLost) << "noise frames are not a place of the map";
  std::unique_ptr<FrameSource> again = open_synth_source("static_xyz", so, 30);
  const uint64_t seq0 = frame.seq + 1;
  while (again->read(frame, 1000) == SourceStatus::kOk) {
    frame.stamp_ns = stamp += 33'333'333;
    frame.seq += seq0;
    step(frame);
  }
  std::printf(
      "[ measured ] %d frames processed while LOST (relocalized at frame %d): %llu "
      "malloc-family calls, %llu operator new\n",
      lost_frames, relocalized, static_cast<unsigned long long>(window_mallocs),
      static_cast<unsigned long long>(window_news));
  EXPECT_GE(lost_frames, 8) << "the window must contain the failed relocalization attempts";
  EXPECT_GT(relocalized, 0) << "the jump back must relocalize";
  EXPECT_EQ(window_mallocs, 0u) << "C allocations in track() while LOST";
  EXPECT_EQ(window_news, 0u) << "operator new calls in track() while LOST";
#endif
}

}  // namespace
}  // namespace rdslam
