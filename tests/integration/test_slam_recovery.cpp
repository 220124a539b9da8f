// Issue 23 item 1, recovery (docs/slam.md "Recovery: map epochs and merges"): LOST in unmapped
// space starts a new map epoch (tracker.new_map_after_s) while the earlier map is kept; a
// keyframe of the new map recognized in the earlier map merges the two by a Sim(3).
//
// synth:lost_unmapped: the camera is covered for 2 s while it turns to a wall it never saw.
// synth:two_rooms: the light goes out in a doorway while the camera walks into an unmapped
// room; it comes back into the first room later. Acceptance (issue): at least 95% of the frames
// after the first map have a pose, and on two_rooms a single Sim(3) alignment of the whole
// (final) trajectory gives ATE <= 1% of the path, with at least one merge when there is more
// than one epoch. The frames of a covered or dark camera (exposure 0.002: sensor noise only) cannot
// have a pose and are left out of the 95% (the count with them is printed).
#include <gtest/gtest.h>

#include <set>

#include "drivers/synth_sequence.h"
#include "drivers/synth_source.h"
#include "slam_test_util.h"

namespace rdslam {
namespace {

struct RecoveryRun {
  OfflineRun run;
  Trajectory gt;
  std::vector<double> exposure;  // per frame; 0 = covered camera
  int first_map = -1;            // first tracked frame
  int seen = 0, seen_posed = 0;  // frames after the first map with light, and with a pose
  int after = 0, after_posed = 0;
  std::set<uint32_t> epochs;  // of the tracked frames
  int merges = 0;
};

RecoveryRun run_recovery(const std::string& name) {
  SourceOptions opt;
  std::unique_ptr<FrameSource> src = open_synth_source(name, opt);
  const CameraModel cam = *src->camera();
  RecoveryRun r;
  r.gt = *src->ground_truth();
  r.exposure = SynthSequence(name).scene().exposure;
  const SlamParams params = test::params_from_env();
  r.run = run_offline(*src, params, cam);
  test::summarize(r.run, r.gt, (name + " (online poses)").c_str());
  for (size_t i = 0; i < r.run.frames.size(); ++i) {
    const TrackResult& res = r.run.frames[i].result;
    const bool posed = test::is_tracked(res.state);
    if (posed && r.first_map < 0) r.first_map = static_cast<int>(i);
    if (posed) r.epochs.insert(res.epoch);
    if (r.first_map < 0) continue;
    ++r.after;
    r.after_posed += posed;
    if (i < r.exposure.size() && r.exposure[i] >= 0.01) {
      ++r.seen;
      r.seen_posed += posed;
    }
  }
  r.merges = r.run.frames.empty() ? 0 : r.run.frames.back().result.map_merges;
  std::printf(
      "[ measured ] %s: first map at frame %d; posed %d of %d frames after it with light "
      "(%.1f%%), %d of %d with the dark ones; %zu epochs, %d merges; mapper: %d maps started, %d "
      "kept, %d merge checks\n",
      name.c_str(), r.first_map, r.seen_posed, r.seen, 100.0 * r.seen_posed / std::max(1, r.seen),
      r.after_posed, r.after, r.epochs.size(), r.merges, r.run.mapper.maps_started,
      r.run.mapper.maps_kept, r.run.mapper.merge_attempts);
  return r;
}

// Sim(3) ATE of `est` (one alignment) as a fraction of the associated ground-truth path.
double ate_fraction(const Trajectory& gt, const Trajectory& est, const char* what) {
  EvalParams ep;
  ep.align = Alignment::kSim3;
  const EvalResult e = evaluate_trajectories(gt, est, ep);
  EXPECT_TRUE(e.ok) << what << ": " << e.error;
  if (!e.ok || e.gt_path_length_m <= 0) return 1e9;
  std::printf("[ measured ] %s: Sim(3) ATE %.4f m over %.2f m (%.3f%%), %zu poses\n", what,
              e.ate_m.rmse, e.gt_path_length_m, 100.0 * e.ate_m.rmse / e.gt_path_length_m,
              e.est_poses);
  return e.ate_m.rmse / e.gt_path_length_m;
}

TEST(SlamRecovery, LostInUnmappedSpaceStartsANewMap) {
  const RecoveryRun r = run_recovery("lost_unmapped");
  ASSERT_GE(r.first_map, 0) << "never initialized";
  // Covered for 2 s (> tracker.new_map_after_s) in front of a wall never seen: a new epoch.
  EXPECT_GE(r.epochs.size(), 2u);
  EXPECT_GE(r.seen_posed, 0.95 * r.seen);
  // The poses of the new map are a consistent trajectory in their own frame (one Sim(3)).
  Trajectory last;
  const uint32_t e = *r.epochs.rbegin();
  for (const auto& f : r.run.frames) {
    if (!test::is_tracked(f.result.state) || f.result.epoch != e) continue;
    StampedPose p;
    p.stamp_ns = f.stamp_ns;
    p.p_world_cam = f.result.p_world_cam;
    p.q_world_cam = f.result.q_world_cam;
    last.push_back(p);
  }
  ASSERT_GE(last.size(), 100u);
  EXPECT_LE(ate_fraction(r.gt, last, "lost_unmapped, last epoch"), 0.01);
}

TEST(SlamRecovery, TwoRoomsMergesTheNewMapIntoTheFirst) {
  const RecoveryRun r = run_recovery("two_rooms");
  ASSERT_GE(r.first_map, 0) << "never initialized";
  // The light is out for 1.5 s in the doorway (> tracker.new_map_after_s): room B is mapped in a
  // new epoch, which is merged into the first map when the camera is back in room A.
  EXPECT_GE(r.epochs.size(), 2u);
  if (r.epochs.size() > 1) {
    EXPECT_GE(r.merges, 1);
  }
  EXPECT_GE(r.seen_posed, 0.95 * r.seen);
  // After the merge the poses continue in the first map's frame (its epoch).
  ASSERT_FALSE(r.run.frames.empty());
  EXPECT_EQ(r.run.frames.back().result.epoch, *r.epochs.begin());
  EXPECT_LE(ate_fraction(r.gt, r.run.final_trajectory, "two_rooms, final trajectory"), 0.01);
}

}  // namespace
}  // namespace rdslam
