// Synthetic scenes (drivers/synth_*): issue 7's bars on static scenes (init by frame 10 since
// issue 22, >= 99% of later frames tracked, ATE <= 0.3% of the path), no initialization from a
// fixed camera watching people, relocalization after a one-second blackout, and issue 23's dim
// light (synth:dim and synth:dim_dark: exposure falling to 15% or 8% and back) and its turn
// on the spot (synth:turn_in_place, _offset: rotation-only tracking, core/tracker.h).
#include <gtest/gtest.h>

#include "drivers/synth_source.h"
#include "slam_test_util.h"

namespace rdslam {
namespace {

// Wraps a source and replaces frames [from, to) by black images (camera covered).
class BlackoutSource : public FrameSource {
 public:
  BlackoutSource(std::unique_ptr<FrameSource> inner, uint64_t from, uint64_t to)
      : inner_(std::move(inner)), from_(from), to_(to) {}
  SourceStatus read(Frame& out, int timeout_ms) override {
    const SourceStatus s = inner_->read(out, timeout_ms);
    if (s == SourceStatus::kOk && out.seq >= from_ && out.seq < to_) out.image.setTo(0);
    return s;
  }
  const SourceInfo& info() const override { return inner_->info(); }

 private:
  std::unique_ptr<FrameSource> inner_;
  uint64_t from_, to_;
};

struct SynthRun {
  OfflineRun run;
  Trajectory gt;
  test::RunSummary s;
};

SynthRun run_synth(const std::string& scenario, int frames, uint64_t black_from = 0,
                   uint64_t black_to = 0) {
  SourceOptions opt;
  std::unique_ptr<FrameSource> src = open_synth_source(scenario, opt, frames);
  const CameraModel cam = *src->camera();
  SynthRun r;
  r.gt = *src->ground_truth();
  if (black_to > black_from) {
    src = std::make_unique<BlackoutSource>(std::move(src), black_from, black_to);
  }
  const SlamParams params = test::params_from_env();
  r.run = run_offline(*src, params, cam);
  r.s = test::summarize(r.run, r.gt, (scenario + " " + params.features.mode).c_str());
  return r;
}

// Initialized by frame `max_first`; at least `min_tracked` of the frames from then on have a
// pose; Sim(3) ATE of the whole trajectory at most `max_ate` of the path.
void expect_bars(const SynthRun& r, int max_first, double min_tracked, double max_ate) {
  ASSERT_GE(r.s.first_tracked, 0) << "never initialized";
  EXPECT_LE(r.s.first_tracked, max_first);
  int later = 0, tracked = 0;
  for (size_t i = r.s.first_tracked; i < r.run.frames.size(); ++i) {
    ++later;
    tracked += test::is_tracked(r.run.frames[i].result.state);
  }
  EXPECT_GE(tracked, min_tracked * later);
  ASSERT_TRUE(r.s.eval_ok);
  EXPECT_LE(r.s.ate_rmse_m, max_ate * r.s.path_m);
}

// Issue 22: the map starts by frame 10 (it waited for the motion gate until frame 13 on
// static_xyz; ORB-SLAM2 starts at frame 1).
void expect_static_bars(const SynthRun& r) {
  expect_bars(r, 10, 0.99, 0.003);
}

TEST(SlamSynth, StaticXyz) {
  expect_static_bars(run_synth("static_xyz", 240));
}

TEST(SlamSynth, StaticHalfsphere) {
  expect_static_bars(run_synth("static_halfsphere", 240));
}

// Issue 23, dim and changing light: at least 95% of the frames after the first map have a
// pose, and one Sim(3) alignment of the whole trajectory gives ATE <= 1% of the path.
// The first map is made in full light (frames 0-59).
TEST(SlamSynth, DimLight) {
  expect_bars(run_synth("dim", 360), 59, 0.95, 0.01);
}

// The same bars in the darker member of the family (exposure down to 8%), where the per-cell
// FAST fallback decides: without it (features.min_fast_threshold = the FAST threshold) 77%
// of the frames after the first map keep a pose, with it 100% (docs/synthetic.md).
TEST(SlamSynth, DimDarkLight) {
  expect_bars(run_synth("dim_dark", 360), 59, 0.95, 0.01);
}

// Issue 23 item 3: a robot drives 1 m, turns 360 degrees on the spot (out of its map and back
// into it), then drives 1.2 m on. At least 95% of the frames after the first map have a pose,
// one Sim(3) alignment gives ATE <= `max_ate` of the path, and the map is kept (one map epoch,
// no reset); the turn is bridged by rotation-only poses.
void expect_turn_bars(const char* scenario, double max_ate) {
  const SynthRun r = run_synth(scenario, 450);
  expect_bars(r, 75, 0.95, max_ate);  // the first map while driving (the turn starts at frame 75)
  uint32_t max_epoch = 0;
  for (const auto& f : r.run.frames) max_epoch = std::max(max_epoch, f.result.epoch);
  EXPECT_EQ(max_epoch, 0u) << "the map was reset";
  EXPECT_GT(r.run.tracker.rotation_frames, 0) << "the turn never needed rotation-only poses";
  std::printf("[slam] %s: %d rotation-only frames, %d rotation keyframes\n", scenario,
              r.run.tracker.rotation_frames, r.run.tracker.rotation_keyframes);
}

// Camera centre on the rotation axis (pure rotation): the bar, ATE <= 1% (measured
// 0.21%; 100% of the frames after the first map posed, 68.8% without rotation-only tracking).
TEST(SlamSynth, TurnInPlaceKeepsOneMap) {
  expect_turn_bars("turn_in_place", 0.01);
}

// Camera 0.1 m ahead of the axis: posed and one map, but the 1% ATE bar is NOT met
// (measured 3.0%: the centre is held through the turn while it really moves on a 0.1 m circle;
// docs/slam.md "Pure rotation"). This bound only guards against regressions (9.5% without
// rotation-only tracking, when the full pose at the end of the turn locked 0.9 m off).
TEST(SlamSynth, TurnInPlaceOffsetKeepsOneMap) {
  expect_turn_bars("turn_in_place_offset", 0.04);
}

TEST(SlamSynth, FixedCameraWithWalkingPeopleDoesNotInitialize) {
  const SynthRun r = run_synth("stationary_camera_people", 150);
  // Either never initialized, or the published motion stays below 1% of the scene depth
  // (the room is several metres deep; a map from moving people would drift far more).
  double max_motion = 0.0;
  for (const auto& f : r.run.frames) {
    if (!test::is_tracked(f.result.state)) continue;
    max_motion = std::max(max_motion, f.result.p_world_cam.norm());
  }
  EXPECT_EQ(r.s.tracked, 0) << "initialized; max published motion " << max_motion;
}

TEST(SlamSynth, RelocalizesAfterOneSecondBlackout) {
  // 30 black frames (1 s at 30 fps) starting at frame 120.
  const SynthRun r = run_synth("static_xyz", 240, 120, 150);
  ASSERT_GE(r.s.first_tracked, 0);
  int first_back = -1;
  for (size_t i = 150; i < r.run.frames.size(); ++i) {
    if (test::is_tracked(r.run.frames[i].result.state)) {
      first_back = static_cast<int>(i);
      break;
    }
  }
  ASSERT_GE(first_back, 0) << "never relocalized";
  EXPECT_LE(first_back, 160);
  ASSERT_TRUE(r.s.eval_ok);
  EXPECT_LE(r.s.ate_rmse_m, 0.003 * r.s.path_m);
}

}  // namespace
}  // namespace rdslam
