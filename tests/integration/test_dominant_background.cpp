// Issue 22 item 4, stage 1 (docs/slam.md "Stage 1: why the background is not mapped before the
// onset"): synth:dominant_object's panel is still for frames 0-30, and a rule that keeps the
// pose on the background once the panel moves needs background map points made in that time
// by correct poses. This counts them against the renderer's depth maps: a map point is
// background when the nearest surface within 3 px of its pixel in its first keyframe is more
// than 2.2 m away (1.5x the panel's 1.45 m, so corners on the panel's silhouette do not count),
// and its depth error is measured after fitting the map's scale on all points.
//
// With the default front end the background is mapped on seeds 1, 3 and 4 only (47-74 points
// by frame 31; 6-11 on seeds 2, 5 and 6): its low-contrast corners are rarely detected again
// 15-30 frames later, so the keyframe pairs wide enough for the 1 degree triangulation angle
// find no match. With the per-cell FAST fallback ranked cell by cell
// (features.fallback_last: false) the background is mapped on every seed; this test holds that
// measurement (the precondition of a tracker rule built on that front end). The per-seed
// counts are fragile (a front-end change that alters the initialization moves a seed between
// 6 and 160 points, docs/slam.md): a failure here says which seed lost its background.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include "core/slam.h"
#include "drivers/synth_sequence.h"
#include "drivers/synth_source.h"

namespace rdslam {
namespace {

struct BackgroundCount {
  int points = 0;            // background map points
  double depth_error = 0.0;  // their median relative depth error (map scale fitted)
};

// Tracks and maps frames 0..frames-1 of dominant_object (seed) offline, then checks every map
// point's depth in its first keyframe against the rendered depth there.
BackgroundCount count_background(const SlamParams& params, int64_t seed, int frames) {
  SourceOptions so;
  std::unique_ptr<FrameSource> src = open_synth_source("dominant_object", so, frames, seed);
  SynthSequence seq("dominant_object", frames, seed);
  const CameraModel cam = *src->camera();
  auto link = make_slam_link(params, 8);
  Tracker tracker(params.tracker, params.features, params.mapper.ba, params.parsac, cam, link,
                  params.mapper.max_points, params.mapper.max_keyframes);
  Mapper mapper(params.mapper, params.features, cam, link);
  Frame frame;
  while (src->read(frame, 1000) == SourceStatus::kOk) {
    tracker.track(frame);
    while (mapper.step(0)) {
    }
  }
  const Map& m = mapper.map();
  std::map<int, cv::Mat> depth;
  SynthFrame sf;
  for (const auto& [id, k] : m.keyframes) {
    const int index = static_cast<int>(std::llround(k.stamp_ns * seq.fps() / 1e9));
    EXPECT_TRUE(seq.render(index, sf));
    depth[id] = sf.depth.clone();
  }
  struct Sample {
    double truth, map;
  };
  std::vector<Sample> samples;
  std::vector<double> ratio;
  for (const auto& [pid, p] : m.points) {
    const Observation& o = p.obs.front();
    const Keyframe& k = m.keyframes.at(o.kf);
    const cv::Point2f& px = k.features.kps[o.feat].pt;
    const cv::Mat& d = depth[o.kf];
    const int x = static_cast<int>(std::lround(px.x)), y = static_cast<int>(std::lround(px.y));
    double truth = 1e9;  // the nearest surface within 3 px
    for (int v = std::max(0, y - 3); v <= std::min(d.rows - 1, y + 3); ++v) {
      for (int u = std::max(0, x - 3); u <= std::min(d.cols - 1, x + 3); ++u) {
        const float t = d.at<float>(v, u);
        if (t > 0.f) truth = std::min(truth, static_cast<double>(t));
      }
    }
    const double z = (k.T_cam_world * p.p_world).z();
    if (truth > 1e8 || z <= 0.0) continue;
    samples.push_back({truth, z});
    ratio.push_back(truth / z);
  }
  BackgroundCount out;
  if (ratio.empty()) return out;
  std::nth_element(ratio.begin(), ratio.begin() + ratio.size() / 2, ratio.end());
  const double scale = ratio[ratio.size() / 2];
  std::vector<double> err;
  for (const Sample& s : samples) {
    if (s.truth <= 2.2) continue;
    ++out.points;
    err.push_back(std::abs(s.map * scale - s.truth) / s.truth);
  }
  if (!err.empty()) {
    std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
    out.depth_error = err[err.size() / 2];
  }
  return out;
}

TEST(DominantObjectBackground, CellByCellFallbackMapsTheBackgroundWhileThePanelIsStill) {
  // Frames 0-31 (the panel moves from frame 30 on, by less than a pixel until 31). Measured
  // (2026-12-04): 149, 79, 184, 85, 195, 43 points, depth errors 0.07-0.33 (median 0.13).
  SlamParams params;
  params.features.fallback_last = false;
  std::vector<double> errors;
  for (int seed = 1; seed <= 6; ++seed) {
    const BackgroundCount c = count_background(params, seed, 32);
    std::printf("seed %d: %d background points, median depth error %.3f\n", seed, c.points,
                c.depth_error);
    EXPECT_GE(c.points, 30) << "seed " << seed;
    errors.push_back(c.depth_error);
  }
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.2);
}

}  // namespace
}  // namespace rdslam
