// The local bundle adjustment's window while the map is young (core/mapper.h,
// MapperParams::ba_young_*): a young map's keyframes are adjusted in a window of
// ba_young_window keyframes, so that the older keyframes that see the window's points stay
// fixed and hold its scale; the window grows back towards ba.window while its keyframes span
// fewer than ba_young_span_frames tracker frames (fast motion: nearly every frame a keyframe).
//
// Also condition m2 with MapperParams::m2_weak_tracking (the last test).
//
// The real tracker and mapper run alternately in this thread (as run_offline); after each
// keyframe the mapper reports the window of its local BA (MapperStats::last_ba_window). The
// first two keyframes carry their own frame counters (the span the window counts).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "core/mapper.h"
#include "core/slam.h"
#include "core/tracker.h"
#include "drivers/synth_source.h"

namespace rdslam {
namespace {

struct Window {
  int keyframes = 0;  // map keyframes when the BA ran
  int window = 0;
};

std::unique_ptr<FrameSource> open_scene(const std::string& scene, int frames) {
  SourceOptions options;
  return open_synth_source(scene, options, frames);
}

// A synthetic scene through the real tracker and mapper, driven by the test.
struct Loop {
  Loop(const std::string& scene, int frames, const SlamParams& p)
      : src(open_scene(scene, frames)),
        cam(*src->camera()),
        link(make_slam_link(p, 2)),
        tracker(p.tracker, p.features, p.mapper.ba, p.parsac, cam, link, p.mapper.max_points,
                p.mapper.max_keyframes),
        mapper(p.mapper, p.features, cam, link) {
    mapper.set_change_detection(p.dynamic);
  }
  std::unique_ptr<FrameSource> src;
  CameraModel cam;
  std::shared_ptr<SlamLink> link;
  Tracker tracker;
  Mapper mapper;
};

std::vector<Window> windows(const std::string& scene, int frames, const SlamParams& p) {
  Loop loop(scene, frames, p);
  FrameSource* src = loop.src.get();
  Tracker& tracker = loop.tracker;
  Mapper& mapper = loop.mapper;
  const std::shared_ptr<SlamLink>& link = loop.link;
  std::vector<Window> out;
  int accepted = 0;
  Frame frame;
  while (src->read(frame, 1000) == SourceStatus::kOk) {
    tracker.track(frame);
    while (mapper.step(0)) {
      const MapperStats& s = mapper.stats();
      if (s.keyframes_accepted > accepted && accepted >= 2) {
        out.push_back({link->keyframes.load(), s.last_ba_window});
      }
      accepted = s.keyframes_accepted;
    }
  }
  std::printf("%s, young below %d keyframes: window/keyframes", scene.c_str(),
              p.mapper.ba_young_keyframes);
  for (const Window& x : out) std::printf(" %d/%d", x.window, x.keyframes);
  std::printf("\n");
  return out;
}

int young_max(const std::vector<Window>& w, int young_below) {
  int m = 0;
  for (const Window& x : w) {
    if (x.keyframes < young_below) m = std::max(m, x.window);
  }
  return m;
}

TEST(MapperBaWindow, YoungWindowAtThirtyFramesPerSecondGrowsUnderFastMotion) {
  const SlamParams p;
  // Keyframes five frames apart: six of them span 25 frames, past the 15-frame bound. (This
  // room's map stays below 20 keyframes: young for the whole run.)
  const std::vector<Window> room = windows("static_xyz", 200, p);
  ASSERT_GT(room.size(), 15u);
  EXPECT_EQ(young_max(room, p.mapper.ba_young_keyframes), p.mapper.ba_young_window);
  // At 10 Hz and 1-2 m per frame nearly every frame is a keyframe: six keyframes span about
  // six frames, so the window grows.
  const std::vector<Window> road = windows("driving", 80, p);
  ASSERT_GT(road.size(), 10u);
  EXPECT_GT(young_max(road, p.mapper.ba_young_keyframes), p.mapper.ba_young_window);
}

TEST(MapperBaWindow, GrownMapAdjustsTheFullWindow) {
  SlamParams p;
  p.mapper.ba_young_keyframes = 8;
  const std::vector<Window> w = windows("static_xyz", 200, p);
  int grown = 0;
  for (const Window& x : w) {
    if (x.keyframes >= 8) grown = std::max(grown, x.window);
  }
  EXPECT_GT(grown, p.mapper.ba_young_window);
  EXPECT_LE(grown, p.mapper.ba.window);
}

TEST(MapperBaWindow, OffAdjustsTheFullWindowFromTheStart) {
  SlamParams p;
  p.mapper.ba_young_keyframes = 0;
  const std::vector<Window> w = windows("static_xyz", 120, p);
  ASSERT_GT(w.size(), 8u);
  EXPECT_GT(young_max(w, 20), p.mapper.ba_young_window);
}

// The first map's two keyframes carry their own frames' counters: the reference frame's and the
// second frame's, as many frames apart as their stamps (the span a young window counts).
TEST(MapperBaWindow, FirstKeyframesCarryTheirOwnFrameCounters) {
  Loop loop("static_xyz", 40, SlamParams{});
  Mapper& mapper = loop.mapper;
  Frame frame;
  int64_t first_stamp = -1, period = 0;
  while (mapper.map().keyframes.size() < 2 && loop.src->read(frame, 1000) == SourceStatus::kOk) {
    if (first_stamp < 0) {
      first_stamp = frame.stamp_ns;
    } else if (period == 0) {
      period = frame.stamp_ns - first_stamp;
    }
    loop.tracker.track(frame);
    while (mapper.step(0)) {
    }
  }
  ASSERT_GE(mapper.map().keyframes.size(), 2u);
  ASSERT_GT(period, 0);
  const Keyframe& k0 = mapper.map().keyframes.at(0);
  const Keyframe& k1 = mapper.map().keyframes.at(1);
  EXPECT_GT(k1.stamp_ns, k0.stamp_ns);
  EXPECT_EQ(k1.frame_no - k0.frame_no, (k1.stamp_ns - k0.stamp_ns) / period);
  EXPECT_EQ(k0.frame_no, 1 + (k0.stamp_ns - first_stamp) / period) << "the tracker counts from 1";
}

// Condition m2 for a weakly tracked candidate (MapperParams::m2_weak_tracking): every keyframe
// candidate is cut down to `kTracked` tracked points before the mapper takes it, and m2 is set
// out of reach. With the rule on, a candidate that contributes more new points than it tracked
// is kept; off, m2 refuses them all.
TEST(MapperM2, WeakTrackingKeepsACandidateThatMoreThanDoublesItsPoints) {
  constexpr int kTracked = 20;
  int accepted[2] = {0, 0}, rejected[2] = {0, 0};
  for (const bool weak : {false, true}) {
    SlamParams p;
    p.mapper.m2 = 100000;
    p.mapper.m2_weak_tracking = weak;
    Loop loop("static_xyz", 80, p);
    Frame frame;
    while (loop.src->read(frame, 1000) == SourceStatus::kOk) {
      loop.tracker.track(frame);
      if (KeyframeCandidate* c = loop.link->candidates.front()) {
        if (c->kind == KeyframeCandidate::Kind::kKeyframe) {
          int kept = 0;
          for (int64_t& pid : c->point_of) {
            if (pid >= 0 && ++kept > kTracked) pid = -1;
          }
        }
      }
      while (loop.mapper.step(0)) {
      }
    }
    const MapperStats& s = loop.mapper.stats();
    accepted[weak] = s.keyframes_accepted - 2;  // the initial map's two
    rejected[weak] = s.keyframes_rejected;
    std::printf("m2_weak_tracking %d: %d keyframes accepted after the first two, %d refused\n",
                int(weak), accepted[weak], rejected[weak]);
  }
  EXPECT_EQ(accepted[0], 0);
  EXPECT_GT(rejected[0], 2);
  EXPECT_GT(accepted[1], 2);
}

}  // namespace
}  // namespace rdslam
