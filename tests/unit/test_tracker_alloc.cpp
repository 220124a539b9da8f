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
#include <opencv2/imgproc.hpp>

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
// Runs `scenario`'s first `frames` frames through the tracker and mapper and asserts that
// the tracker's track() calls after the warm-up do not allocate.
void expect_no_allocation_after_warm_up(const char* scenario, int frames) {
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_synth_source(scenario, so, frames);
  const CameraModel cam = *src->camera();
  SlamParams params;  // the defaults: ORB features, PARSAC per frame
  SlamStages stages = make_slam_stages(params, cam);
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

}  // namespace
}  // namespace rdslam
