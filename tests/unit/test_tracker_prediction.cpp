// Time-aware motion prediction (core/tracker.h, TrackerParams::prediction_max_scale; issue 23
// item 4). A live pipeline that falls behind drops frames ("newest frame wins"), so the
// tracker sees gaps of several frame periods. The constant-velocity model spans the stamp
// interval between the last two tracked frames; after a gap it must predict the whole gap.
//
// The real tracker and mapper run alternately in this thread (as run_offline) on the
// synthetic `static_xyz` scene; after the map is built, frames are dropped in an irregular
// pattern (gaps of 1 to 4 frames). The same frames are fed twice: with their recorded stamps,
// and with stamps rewritten to one period per fed frame (what a per-frame motion model sees).
// The prediction error after a gap, relative to the camera's motion over the gap, is the
// behaviour under test: it must be much smaller with the recorded stamps.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <vector>

#include "core/mapper.h"
#include "core/slam.h"
#include "core/tracker.h"
#include "drivers/preloaded_frames.h"
#include "drivers/synth_source.h"

namespace rdslam {
namespace {

constexpr int kFrames = 160;
constexpr int kDropFrom = 60;                      // frames before this are all fed
constexpr int kGaps[] = {1, 3, 1, 4, 2, 1, 3, 2};  // recorded frames between fed frames

struct GapStats {
  int fed_after_drops = 0, tracked_after_drops = 0;
  int gap_frames = 0;  // fed frames that follow a gap of 2 or more
  // Summed prediction error (camera centre) over the summed camera motion across the gaps,
  // on the gap frames (a ratio of sums: a frame where the camera hardly moves adds little).
  double rel_err = 0;
};

bool tracked(TrackingState s) {
  return s == TrackingState::kTracking || s == TrackingState::kRelocalized;
}

// `frames`: the scene rendered once for both runs.
GapStats run(const PreloadedFrames& frames, bool recorded_stamps) {
  PreloadedFrames::Reader src(frames);
  const CameraModel cam = *src.camera();
  SlamParams p;  // defaults: ORB, PARSAC per frame
  auto link = make_slam_link(p, 2);
  Tracker tracker(p.tracker, p.features, p.mapper.ba, p.parsac, cam, link, p.mapper.max_points,
                  p.mapper.max_keyframes);
  Mapper mapper(p.mapper, p.features, cam, link);
  mapper.set_change_detection(p.dynamic);

  GapStats g;
  Frame frame;
  int64_t period = 0, prev_stamp = 0;
  int next_fed = 0, gap_index = 0, fed = 0, last_gap = 1;
  bool have_prev_pose = false;
  Pose prev_T;
  double err_sum = 0, motion_sum = 0;
  for (int i = 0; i < kFrames; ++i) {
    if (src.read(frame, 1000) != SourceStatus::kOk) break;
    if (i == 1) period = frame.stamp_ns - prev_stamp;
    prev_stamp = frame.stamp_ns;
    if (i < next_fed) continue;  // dropped
    int gap = 1;
    if (i >= kDropFrom) {
      gap = kGaps[gap_index++ % (sizeof(kGaps) / sizeof(kGaps[0]))];
    }
    next_fed = i + gap;
    // Per-frame view: one period per fed frame, whatever was dropped in between.
    if (!recorded_stamps) frame.stamp_ns = static_cast<int64_t>(fed) * period;
    ++fed;
    const TrackResult r = tracker.track(frame);
    while (mapper.step(0)) {
    }
    const bool ok = tracked(r.state);
    if (i > kDropFrom) {
      ++g.fed_after_drops;
      if (ok) ++g.tracked_after_drops;
      if (ok && have_prev_pose && last_gap >= 2) {
        // r is T_world_cam; the tracker's poses are T_cam_world.
        Pose Twc;
        Twc.R = r.q_world_cam.toRotationMatrix();
        Twc.t = r.p_world_cam;
        const Pose T = Twc.inverse();
        const double motion = (T.centre() - prev_T.centre()).norm();
        const double err = (tracker.stats().predicted.centre() - T.centre()).norm();
        err_sum += err;
        motion_sum += motion;
        ++g.gap_frames;
      }
    }
    // The gap that precedes the NEXT fed frame.
    last_gap = gap;
    have_prev_pose = ok;
    if (ok) {
      Pose Twc;
      Twc.R = r.q_world_cam.toRotationMatrix();
      Twc.t = r.p_world_cam;
      prev_T = Twc.inverse();
    }
  }
  if (motion_sum > 0) g.rel_err = err_sum / motion_sum;
  return g;
}

TEST(TrackerPrediction, ScalesTheLastMotionByTheStampIntervalAfterDroppedFrames) {
  SourceOptions so;
  const PreloadedFrames frames(*open_synth_source("static_xyz", so, kFrames));
  ASSERT_EQ(frames.size(), static_cast<size_t>(kFrames));
  const GapStats timed = run(frames, true);
  const GapStats per_frame = run(frames, false);
  std::printf(
      "recorded stamps: %d/%d tracked after drops, prediction error %.3f of the gap's "
      "motion on %d gap frames\n",
      timed.tracked_after_drops, timed.fed_after_drops, timed.rel_err, timed.gap_frames);
  std::printf(
      "per-frame stamps: %d/%d tracked after drops, prediction error %.3f on %d gap "
      "frames\n",
      per_frame.tracked_after_drops, per_frame.fed_after_drops, per_frame.rel_err,
      per_frame.gap_frames);
  ASSERT_GT(timed.fed_after_drops, 30);
  EXPECT_EQ(timed.tracked_after_drops, timed.fed_after_drops);
  ASSERT_GT(timed.gap_frames, 15);
  ASSERT_GT(per_frame.gap_frames, 15);
  EXPECT_LT(timed.rel_err, 0.5 * per_frame.rel_err);
}

}  // namespace
}  // namespace rdslam
