// MapUpdater (core/map_updater.h) on a small hand-built map: one keyframe looking at a textured
// scene, the current frame from the same pose with a region whose appearance changed. Which
// points Algorithm 1 invalidates then depends only on what is tracked in front of or behind
// them, so each test builds exactly the situation of one branch of the paper's Algorithm 1.
#include <gtest/gtest.h>

#include <functional>
#include <opencv2/imgproc.hpp>

#include "core/map_updater.h"

using namespace rdslam;

namespace {

constexpr int kW = 320, kH = 240;
const cv::Rect kRegion(0, 0, 200, 240);  // the part of the view whose appearance changes

PinholeIntrinsics intrinsics() {
  PinholeIntrinsics K;
  K.fx = K.fy = 200;
  K.cx = 160;
  K.cy = 120;
  return K;
}

cv::Mat textured(uint64_t seed, int lo, int hi) {
  cv::Mat img(kH, kW, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, lo, hi);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  return img;
}

// The current image: the keyframe image with kRegion replaced by a dark, different texture.
cv::Mat changed_image(const cv::Mat& kf_image) {
  cv::Mat cur = kf_image.clone();
  textured(99, 0, 60)(kRegion).copyTo(cur(kRegion));
  return cur;
}

void resize_features(Features& f, int n) {
  f.count = n;
  f.width = kW;
  f.height = kH;
  f.kps.assign(n, cv::KeyPoint());
  f.un.assign(n, cv::Point2f());
  f.scale.assign(n, 1.f);
  f.level.assign(n, 0);
}

struct Scene {
  Map map;
  std::vector<int64_t> object_ids;  // points inside kRegion (their surface may change)
  std::vector<int64_t> static_ids;  // points outside kRegion (unchanged appearance)
  cv::Mat kf_image;
  // Current frame: tracked features.
  Features cur;
  std::vector<int64_t> cur_point_of;
};

int64_t add_point(Map& map, int kf, int feat, const Eigen::Vector3d& p) {
  MapPoint mp;
  mp.id = map.next_point_id++;
  mp.p_world = p;
  mp.first_kf = kf;
  const int64_t id = mp.id;
  map.points.emplace(id, mp);
  map.add_observation(id, kf, feat);
  return id;
}

// Keyframe 0 at the identity pose sees points on a grid every 24 px: depth `object_depth`
// inside kRegion, 2.0 outside.
Scene make_scene(double object_depth) {
  Scene s;
  const PinholeIntrinsics K = intrinsics();
  s.kf_image = textured(7, 0, 255);
  Keyframe kf;
  kf.id = s.map.next_kf_id++;
  kf.image = s.kf_image;
  std::vector<Eigen::Vector2d> px;
  for (int v = 24; v < kH - 12; v += 24) {
    for (int u = 24; u < kW - 12; u += 24) px.emplace_back(u, v);
  }
  resize_features(kf.features, static_cast<int>(px.size()));
  kf.point_of.assign(px.size(), -1);
  for (size_t i = 0; i < px.size(); ++i) {
    kf.features.kps[i].pt = cv::Point2f(float(px[i].x()), float(px[i].y()));
    kf.features.un[i] = kf.features.kps[i].pt;
  }
  s.map.keyframes.emplace(kf.id, kf);
  ++s.map.kf_seq;
  for (size_t i = 0; i < px.size(); ++i) {
    const bool in_region = kRegion.contains(cv::Point(int(px[i].x()), int(px[i].y())));
    const double z = in_region ? object_depth : 2.0;
    const int64_t id =
        add_point(s.map, kf.id, static_cast<int>(i), K.unproject(px[i].x(), px[i].y()) * z);
    (in_region ? s.object_ids : s.static_ids).push_back(id);
  }
  resize_features(s.cur, 0);
  return s;
}

// Adds, for every object point, a tracked point of the current frame 8 px to its right at
// depth `depth` (a map point observed only by the current frame's tracker).
void track_neighbours(Scene& s, double depth) {
  const PinholeIntrinsics K = intrinsics();
  const Keyframe* kf = s.map.keyframe(0);
  std::vector<Eigen::Vector2d> px;
  for (int64_t id : s.object_ids) {
    const Eigen::Vector2d x = K.project(kf->T_cam_world * s.map.point(id)->p_world);
    px.push_back(x + Eigen::Vector2d(8, 0));
  }
  resize_features(s.cur, static_cast<int>(px.size()));
  s.cur_point_of.assign(px.size(), -1);
  for (size_t i = 0; i < px.size(); ++i) {
    s.cur.un[i] = cv::Point2f(float(px[i].x()), float(px[i].y()));
    s.cur.kps[i].pt = s.cur.un[i];
    MapPoint mp;
    mp.id = s.map.next_point_id++;
    mp.p_world = K.unproject(px[i].x(), px[i].y()) * depth;
    mp.first_kf = 0;
    s.map.points.emplace(mp.id, mp);
    s.cur_point_of[i] = mp.id;
  }
}

// The paper's Algorithm 1 as listed: histogram trigger 1, every point checked (the test map's
// points have one observation), a change verdict acts at once, no counters. The tests of the
// additions (established points, confirmation, counters, lighting) start from this too.
ChangeDetectionParams paper_params() {
  ChangeDetectionParams p;
  p.histogram_threshold = 1.0;
  p.min_observations = 1;
  p.confirm_checks = 1;
  p.landmark_counters = false;
  p.temporal_check = false;  // the paper's Algorithm 1: no evidence about what replaced X
  p.ray_search = false;
  p.prune_unmatched = false;
  return p;
}

int count_invalid(const Map& map, const std::vector<int64_t>& ids) {
  int n = 0;
  for (int64_t id : ids) n += !map.points.at(id).valid;
  return n;
}

}  // namespace

TEST(MapUpdater, ChangedRegionTriggersHistogramCheck) {
  Scene s = make_scene(1.5);
  ColorHistogram a, b;
  compute_color_histogram(s.kf_image, 4, a);
  compute_color_histogram(changed_image(s.kf_image), 4, b);
  ASSERT_GT(histogram_difference(a, b), 1.0) << "test scene must trigger the check";
}

TEST(MapUpdater, UnchangedFrameChecksNothing) {
  Scene s = make_scene(1.5);
  MapUpdater u(paper_params(), intrinsics());
  const MapUpdateStats st = u.update(s.map, s.kf_image.clone(), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.keyframes_selected, 1);
  EXPECT_EQ(st.keyframes_triggered, 0);
  EXPECT_EQ(st.points_checked, 0);
  EXPECT_EQ(s.map.count_valid_points(), static_cast<int>(s.map.points.size()));
}

TEST(MapUpdater, SurfaceGoneWithBackgroundTrackedBehindInvalidates) {
  // The object at depth 1.5 was removed: the tracked background (depth 3) shows through.
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  MapUpdater u(paper_params(), intrinsics());
  std::vector<int64_t> inv;
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of, &inv);
  EXPECT_EQ(st.keyframes_triggered, 1);
  const int n_obj = static_cast<int>(s.object_ids.size());
  EXPECT_EQ(count_invalid(s.map, s.object_ids), n_obj);
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
  EXPECT_EQ(st.decisions[int(PointDecision::kInvalidNothingInFront)], n_obj);
  EXPECT_EQ(static_cast<int>(inv.size()), n_obj);
  EXPECT_EQ(st.points_invalidated, n_obj);
  // Tracked points were observed in this frame: never checked.
  for (int64_t id : s.cur_point_of) EXPECT_TRUE(s.map.points.at(id).valid);
}

TEST(MapUpdater, CheckLogHoldsOneRecordPerVerdict) {
  // Diagnostics (MapUpdater::set_check_log): one record per Algorithm 1 verdict, agreeing
  // with the call's decision counts; nothing is logged without a log.
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  std::vector<CheckRecord> log;
  MapUpdater u(paper_params(), intrinsics());
  u.set_check_log(&log);
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  ASSERT_EQ(static_cast<int>(log.size()), st.points_checked);
  int invalid = 0;
  for (const CheckRecord& r : log) {
    EXPECT_TRUE(s.map.points.count(r.id)) << r.id;
    EXPECT_GT(r.depth, 0.f);
    invalid += r.decision == PointDecision::kInvalidNothingInFront;
  }
  EXPECT_EQ(invalid, st.decisions[int(PointDecision::kInvalidNothingInFront)]);
  EXPECT_EQ(invalid, static_cast<int>(s.object_ids.size()));
  u.set_check_log(nullptr);
  u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(static_cast<int>(log.size()), st.points_checked);
}

TEST(MapUpdater, OccludedByUntrackedMovingObjectIsKept) {
  // Nothing is tracked where the appearance changed: a moving object covers the points.
  Scene s = make_scene(1.5);
  MapUpdater u(paper_params(), intrinsics());
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), 0);
  EXPECT_EQ(st.decisions[int(PointDecision::kKeepOccludedMoving)],
            static_cast<int>(s.object_ids.size()));
  EXPECT_GT(st.decisions[int(PointDecision::kKeepSameAppearance)], 0);
  EXPECT_TRUE(s.map.keyframe(0)->valid);
}

TEST(MapUpdater, NoOcclusionHandlingInvalidatesOccludedPoints) {
  Scene s = make_scene(1.5);
  ChangeDetectionParams p = paper_params();
  p.occlusion_handling = false;
  MapUpdater u(p, intrinsics());
  u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), static_cast<int>(s.object_ids.size()));
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
}

TEST(MapUpdater, NearerPointOnSameObjectInvalidates) {
  // The surface moved towards the camera: tracked points in front project, in the keyframe
  // where X first appeared, within r2 of X.
  Scene s = make_scene(2.0);
  track_neighbours(s, 1.0);
  MapUpdater u(paper_params(), intrinsics());
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), static_cast<int>(s.object_ids.size()));
  EXPECT_EQ(st.decisions[int(PointDecision::kInvalidSameObject)],
            static_cast<int>(s.object_ids.size()));
}

TEST(MapUpdater, NearerPointFarInFirstKeyframeIsStaticOcclusion) {
  // Same, but with r2 tighter than the 8 px offset of the tracked points: a static occluder.
  Scene s = make_scene(2.0);
  track_neighbours(s, 1.0);
  ChangeDetectionParams p = paper_params();
  p.r2 = 4.0;
  MapUpdater u(p, intrinsics());
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), 0);
  EXPECT_EQ(st.decisions[int(PointDecision::kKeepOccludedStatic)],
            static_cast<int>(s.object_ids.size()));
}

TEST(MapUpdater, PointsInViewOfNoSelectedKeyframeAreCheckedAgainstTheirOwn) {
  // The only selected keyframe (closest_keyframes 1) is a newer one at the current pose that
  // holds none of the points; the points' own keyframe 0 sits 2 mm away. The paper's selection
  // never checks them; check_all_in_view judges each against keyframe 0.
  for (const bool all : {false, true}) {
    Scene s = make_scene(1.5);
    s.map.keyframe(0)->T_cam_world.t = Eigen::Vector3d(0.002, 0, 0);
    Keyframe newer;
    newer.id = s.map.next_kf_id++;
    newer.image = s.kf_image;
    resize_features(newer.features, 0);
    s.map.keyframes.emplace(newer.id, newer);
    track_neighbours(s, 3.0);
    ChangeDetectionParams p = paper_params();
    p.closest_keyframes = 1;
    p.check_all_in_view = all;
    MapUpdater u(p, intrinsics());
    const MapUpdateStats st =
        u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
    EXPECT_EQ(st.keyframes_selected, 1);
    const int n_obj = static_cast<int>(s.object_ids.size());
    EXPECT_EQ(count_invalid(s.map, s.object_ids), all ? n_obj : 0) << "check_all_in_view " << all;
    EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
    EXPECT_EQ(st.points_unselected, all ? n_obj + int(s.static_ids.size()) : 0);
  }
}

TEST(MapUpdater, MapUpdateOffDoesNothing) {
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  ChangeDetectionParams p = paper_params();
  p.map_update = false;
  MapUpdater u(p, intrinsics());
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.points_checked, 0);
  EXPECT_EQ(s.map.count_valid_points(), static_cast<int>(s.map.points.size()));
}

TEST(MapUpdater, KeyframeInvalidatedAboveNinetyPercent) {
  // The object points (removed surface) are 50-90% of the keyframe's points: the paper's 90%
  // keeps the keyframe, a 50% ratio invalidates it.
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  const double fraction = 0.5;  // object points are ~60% of the keyframe's points
  const double frac = double(s.object_ids.size()) / (s.object_ids.size() + s.static_ids.size());
  ASSERT_GT(frac, 0.5);
  ASSERT_LT(frac, 0.9);
  {
    MapUpdater u(paper_params(), intrinsics());  // 90%: stays valid
    Scene s90 = make_scene(1.5);
    track_neighbours(s90, 3.0);
    const MapUpdateStats st =
        u.update(s90.map, changed_image(s90.kf_image), Pose{}, s90.cur, s90.cur_point_of);
    EXPECT_EQ(st.keyframes_invalidated, 0);
    EXPECT_TRUE(s90.map.keyframe(0)->valid);
  }
  MapUpdater u(paper_params(), intrinsics(), fraction);
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.keyframes_invalidated, 1);
  EXPECT_FALSE(s.map.keyframe(0)->valid);
  // An invalid keyframe is no longer selected.
  const MapUpdateStats st2 =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st2.keyframes_selected, 0);
}

TEST(MapUpdater, KeyframeBehindOrLookingAwayIsNotSelected) {
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  MapUpdater u(paper_params(), intrinsics());
  Pose turned;
  turned.R = exp_so3(Eigen::Vector3d(0, M_PI / 3, 0));  // 60 deg yaw > 30 deg
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), turned, s.cur, s.cur_point_of);
  EXPECT_EQ(st.keyframes_selected, 0);
  EXPECT_EQ(s.map.count_valid_points(), static_cast<int>(s.map.points.size()));
}

TEST(MapUpdater, BadInputDoesNotCrash) {
  Scene s = make_scene(1.5);
  MapUpdater u(paper_params(), intrinsics());
  EXPECT_EQ(u.update(s.map, cv::Mat(), Pose{}, s.cur, s.cur_point_of).points_checked, 0);
  cv::Mat grey(kH, kW, CV_8UC1, cv::Scalar(0));  // channel mismatch: keyframe not comparable
  EXPECT_EQ(u.update(s.map, grey, Pose{}, s.cur, s.cur_point_of).keyframes_selected, 0);
  // point_of shorter than the feature count, ids of erased points.
  Features f;
  resize_features(f, 3);
  std::vector<int64_t> ids = {123456, -1};
  EXPECT_NO_FATAL_FAILURE(u.update(s.map, changed_image(s.kf_image), Pose{}, f, ids));
  Map empty;
  EXPECT_EQ(u.update(empty, s.kf_image, Pose{}, f, ids).keyframes_selected, 0);
}

TEST(MapUpdater, PointsSeenByFewKeyframesAreNotChecked) {
  // Default min_observations = 3: the scene's one-view points are not established.
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  ChangeDetectionParams p = paper_params();
  p.min_observations = ChangeDetectionParams{}.min_observations;
  ASSERT_GT(p.min_observations, 1);
  MapUpdater u(p, intrinsics());
  const MapUpdateStats st =
      u.update(s.map, changed_image(s.kf_image), Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.points_checked, 0);
  EXPECT_GT(st.points_not_established, 0);
  EXPECT_EQ(s.map.count_valid_points(), static_cast<int>(s.map.points.size()));
}

TEST(MapUpdater, ChangeNeedsConsecutiveVerdicts) {
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  ChangeDetectionParams p = paper_params();
  p.confirm_checks = 2;
  p.histogram_threshold = 0.0;  // the unchanged frame is checked too
  MapUpdater u(p, intrinsics());
  const cv::Mat changed = changed_image(s.kf_image);
  // Changed, then unchanged (a passing glitch), then changed: not yet two in a row.
  EXPECT_EQ(u.update(s.map, changed, Pose{}, s.cur, s.cur_point_of).points_invalidated, 0);
  EXPECT_EQ(u.update(s.map, s.kf_image, Pose{}, s.cur, s.cur_point_of).points_invalidated, 0);
  EXPECT_EQ(u.update(s.map, changed, Pose{}, s.cur, s.cur_point_of).points_invalidated, 0);
  const MapUpdateStats st = u.update(s.map, changed, Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.points_invalidated, static_cast<int>(s.object_ids.size()));
  EXPECT_EQ(count_invalid(s.map, s.object_ids), static_cast<int>(s.object_ids.size()));
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
}

TEST(MapUpdater, PersistentUntrackedChangeIsDiscardedByTheMissCounter) {
  // Nothing tracked near the changed region (Alg. 1 keeps: "a moving object"). A moving
  // occluder passes; the same verdict miss_threshold + 1 checks in a row discards the point.
  Scene s = make_scene(1.5);
  ChangeDetectionParams p = paper_params();
  p.landmark_counters = true;
  p.count_missed = true;
  p.miss_threshold = 3;
  p.histogram_threshold = 0.0;  // the unchanged frame is checked too
  MapUpdater u(p, intrinsics());
  const cv::Mat changed = changed_image(s.kf_image);
  for (int k = 0; k < 3; ++k) u.update(s.map, changed, Pose{}, s.cur, s.cur_point_of);
  // Seen unchanged once: the counts restart.
  u.update(s.map, s.kf_image, Pose{}, s.cur, s.cur_point_of);
  for (int k = 0; k < 3; ++k) u.update(s.map, changed, Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), 0);
  std::vector<InvalidationRecord> rec;
  UpdateFrame f;
  f.image = &changed;
  const MapUpdateStats st = u.update(s.map, f, nullptr, &rec);
  EXPECT_EQ(count_invalid(s.map, s.object_ids), static_cast<int>(s.object_ids.size()));
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
  EXPECT_EQ(st.counter_discards, static_cast<int>(s.object_ids.size()));
  ASSERT_EQ(rec.size(), s.object_ids.size());
  EXPECT_EQ(rec[0].cause, InvalidationCause::kMissed);
}

TEST(MapUpdater, UnchangedDuplicatesTheTrackerNeverMatchesArePruned) {
  // The frame is the keyframe's view, unchanged: every point is in view and looks the same.
  // Half the static points are tracked in every frame. Each of the others has a twin: another
  // map point, 1 px away, that the tracker matches instead (a surface mapped twice). Those
  // duplicates are erased after miss_threshold + 1 checks; a point tracked once restarts its
  // count; a point seen from beyond the distance range the tracker matches it at is not
  // counted; untracked points without a tracked feature near them (the object points) stay.
  Scene s = make_scene(1.5);
  ChangeDetectionParams p = paper_params();
  p.histogram_threshold = 0.0;  // the unchanged frame is checked
  p.prune_unmatched = true;
  p.miss_threshold = 3;
  const PinholeIntrinsics K = intrinsics();
  std::vector<int64_t> tracked, dups, twins;
  for (size_t i = 0; i < s.static_ids.size(); ++i) {
    (i % 2 == 0 ? tracked : dups).push_back(s.static_ids[i]);
  }
  for (int64_t id : dups) {
    const Eigen::Vector2d x = K.project(s.map.points.at(id).p_world) + Eigen::Vector2d(1, 0);
    MapPoint mp;
    mp.id = s.map.next_point_id++;
    mp.p_world = K.unproject(x.x(), x.y()) * 2.0;
    mp.first_kf = 0;
    s.map.points.emplace(mp.id, mp);
    twins.push_back(mp.id);
  }
  for (auto& [id, mp] : s.map.points) mp.normal = -mp.p_world.normalized();  // point -> camera
  const int64_t once = dups[0];  // tracked itself in the third frame
  const int64_t far = dups[1];   // outside its matching distance range
  s.map.points.at(far).max_dist = 1.0f;
  const Map map_copy = s.map;  // for the run with pruning off
  auto frame = [&](bool with_once) {
    std::vector<int64_t> ids = tracked;
    ids.insert(ids.end(), twins.begin(), twins.end());
    if (with_once) ids.push_back(once);
    resize_features(s.cur, static_cast<int>(ids.size()));
    s.cur_point_of = ids;
    for (size_t i = 0; i < ids.size(); ++i) {
      const Eigen::Vector2d x = K.project(s.map.points.at(ids[i]).p_world);
      s.cur.un[i] = cv::Point2f(float(x.x()), float(x.y()));
      s.cur.kps[i].pt = s.cur.un[i];
    }
  };
  MapUpdater u(p, intrinsics());
  int pruned = 0;
  for (int k = 0; k < 3; ++k) {
    frame(k == 2);
    pruned += u.update(s.map, s.kf_image, Pose{}, s.cur, s.cur_point_of).points_pruned;
  }
  EXPECT_EQ(pruned, 0);
  frame(false);
  const size_t before = s.map.points.size();
  MapUpdateStats st = u.update(s.map, s.kf_image, Pose{}, s.cur, s.cur_point_of);
  EXPECT_EQ(st.points_invalidated, 0);  // pruning is not an invalidation
  // Fourth check: the duplicates except `once` (one unmatched check since) and `far` exceed
  // miss_threshold = 3.
  EXPECT_EQ(st.points_pruned, static_cast<int>(dups.size()) - 2);
  EXPECT_EQ(s.map.points.size(), before - st.points_pruned);
  for (int64_t id : tracked) EXPECT_TRUE(s.map.points.count(id)) << id;
  for (int64_t id : twins) EXPECT_TRUE(s.map.points.count(id)) << id;
  for (int64_t id : s.object_ids) EXPECT_TRUE(s.map.points.count(id)) << id;
  EXPECT_FALSE(s.map.points.count(dups[2]));
  EXPECT_TRUE(s.map.points.count(once));
  EXPECT_TRUE(s.map.points.count(far));
  // Erased from its keyframe too.
  for (int64_t pid : s.map.keyframe(0)->point_of) EXPECT_NE(pid, dups[2]);
  for (int k = 0; k < 3; ++k) {
    frame(false);
    u.update(s.map, s.kf_image, Pose{}, s.cur, s.cur_point_of);
  }
  EXPECT_FALSE(s.map.points.count(once));
  EXPECT_TRUE(s.map.points.count(far));
  // Switched off: the same frames erase nothing.
  Map m = map_copy;
  p.prune_unmatched = false;
  MapUpdater off(p, intrinsics());
  for (int k = 0; k < 8; ++k) {
    frame(false);
    EXPECT_EQ(off.update(m, s.kf_image, Pose{}, s.cur, s.cur_point_of).points_pruned, 0);
  }
  EXPECT_EQ(m.points.size(), map_copy.points.size());
}

TEST(MapUpdater, PointsRejectedByTheRobustEstimatorAreDiscardedAfterMovedThreshold) {
  Scene s = make_scene(1.5);
  ChangeDetectionParams p = paper_params();
  p.landmark_counters = true;
  p.moved_threshold = 2;
  MapUpdater u(p, intrinsics());
  const int64_t a = s.static_ids[0], b = s.static_ids[1];
  const int64_t rejected[2] = {a, b};
  const cv::Point2f px[1] = {cv::Point2f(10, 10)};
  const int64_t tracked_b[1] = {b};
  UpdateFrame f;
  f.image = &s.kf_image;
  f.rejected = rejected;
  f.rejected_count = 2;
  u.update(s.map, f);
  u.update(s.map, f);
  // b is matched and consistent once: its moved count restarts.
  UpdateFrame g;
  g.image = &s.kf_image;
  g.un = px;
  g.point_of = tracked_b;
  g.count = 1;
  u.update(s.map, g);
  EXPECT_TRUE(s.map.points.at(a).valid);
  const MapUpdateStats st = u.update(s.map, f);
  EXPECT_FALSE(s.map.points.at(a).valid);  // third rejection in a row > 2
  EXPECT_TRUE(s.map.points.at(b).valid);
  EXPECT_EQ(st.counter_discards, 1);
}

TEST(MapUpdater, LightingChangeIsNotASceneChange) {
  // The whole frame brighter and with more contrast (an exposure step), the background
  // tracked behind: with the normalised eq. (2) nothing changed; the paper's plain SAD
  // invalidates the object points.
  Scene s = make_scene(1.5);
  track_neighbours(s, 3.0);
  cv::Mat bright;
  s.kf_image.convertTo(bright, -1, 1.6, 25.0);
  ChangeDetectionParams p = paper_params();
  p.histogram_threshold = 0.0;
  ASSERT_TRUE(p.normalise_appearance);
  {
    MapUpdater u(p, intrinsics());
    const MapUpdateStats st = u.update(s.map, bright, Pose{}, s.cur, s.cur_point_of);
    EXPECT_GT(st.points_checked, 0);
    EXPECT_EQ(st.points_invalidated, 0);
    // A real change is still seen under the new exposure.
    cv::Mat changed_bright;
    changed_image(s.kf_image).convertTo(changed_bright, -1, 1.6, 25.0);
    const MapUpdateStats st2 = u.update(s.map, changed_bright, Pose{}, s.cur, s.cur_point_of);
    EXPECT_EQ(st2.points_invalidated, static_cast<int>(s.object_ids.size()));
  }
  Scene s2 = make_scene(1.5);
  track_neighbours(s2, 3.0);
  p.normalise_appearance = false;
  MapUpdater plain(p, intrinsics());
  EXPECT_GT(plain.update(s2.map, bright, Pose{}, s2.cur, s2.cur_point_of).points_invalidated, 0);
}

// The temporal check (dynamic.temporal_check, default on) on rendered views of fronto-parallel
// planes: a background plane at depth 3 and, where the keyframe saw it, an object plane at
// depth 1.5 covering the left part of the view. The camera translates along x, so a plane at
// depth Z moves by fx * tx / Z pixels: the views are exact shifts of the textures. Nothing is
// tracked, so Algorithm 1 alone would call every changed point "occluded by a moving object".
namespace temporal {

constexpr double kBgDepth = 3.0, kObjDepth = 1.5;
constexpr int kMargin = 80;  // texture margin for the shifts

struct Planes {
  cv::Mat bg = textured_wide(11);
  cv::Mat obj = textured_wide(12);
  static cv::Mat textured_wide(uint64_t seed) {
    cv::Mat img(kH, kW + 2 * kMargin, CV_8UC3);
    cv::RNG rng(seed);
    rng.fill(img, cv::RNG::UNIFORM, 0, 255);
    cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
    return img;
  }
};

// The view from camera centre (tx, 0, 0). `front` (optional) is a plane at `front_depth`
// covering what the keyframe saw as the object (world x < its edge) - a static occluder when
// the same texture is passed every frame, a moving one when it changes every frame.
cv::Mat render(const Planes& pl, double tx, bool object, const cv::Mat* front = nullptr,
               double front_depth = 0.8) {
  const PinholeIntrinsics K = intrinsics();
  const double edge_x = (kRegion.br().x - K.cx) / K.fx;  // object edge, world x / depth
  cv::Mat out(kH, kW, CV_8UC3);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      auto sample = [&](const cv::Mat& tex, double z) {
        const int su = static_cast<int>(std::lround(u + K.fx * tx / z)) + kMargin;
        return tex.at<cv::Vec3b>(v, std::clamp(su, 0, tex.cols - 1));
      };
      const double xn = (u - K.cx) / K.fx;  // ray direction x / z in the camera
      cv::Vec3b c = sample(pl.bg, kBgDepth);
      if (object && xn * kObjDepth + tx < edge_x * kObjDepth) c = sample(pl.obj, kObjDepth);
      if (front != nullptr && xn * front_depth + tx < edge_x * kBgDepth) {
        c = sample(*front, front_depth);
      }
      out.at<cv::Vec3b>(v, u) = c;
    }
  }
  return out;
}

Pose camera_at(double tx) {
  Pose T;
  T.t = Eigen::Vector3d(-tx, 0, 0);  // T_cam_world of a camera at (tx, 0, 0), no rotation
  return T;
}

// Keyframe at tx = 0 with the object; map points on the planes at the grid pixels.
Scene make_planes_scene(const Planes& pl) {
  Scene s = make_scene(kObjDepth);
  const PinholeIntrinsics K = intrinsics();
  s.kf_image = render(pl, 0.0, true);
  s.map.keyframe(0)->image = s.kf_image;
  for (int64_t id : s.static_ids) {
    MapPoint* p = s.map.point(id);
    p->p_world = p->p_world / p->p_world.z() * kBgDepth;
  }
  (void)K;
  return s;
}

// Runs the frames (camera x positions, 1/30 s apart): the object points invalidated and the
// decisions summed over the frames.
struct Outcome {
  int invalid = 0;
  int decisions[10] = {};
};
Outcome run_frames(Scene& s, const std::vector<std::pair<double, cv::Mat>>& frames,
                   ChangeDetectionParams p = ChangeDetectionParams()) {
  p.histogram_threshold = 0.0;
  p.min_observations = 1;  // the hand-built map's points have one observation
  p.landmark_counters = false;
  MapUpdater u(p, intrinsics());
  int64_t stamp = 1'000'000'000;
  Outcome out;
  for (const auto& f : frames) {
    UpdateFrame uf;
    uf.image = &f.second;
    uf.T_cam_world = camera_at(f.first);
    uf.un = s.cur.un.data();
    uf.point_of = s.cur_point_of.data();
    uf.count = 0;
    uf.stamp_ns = stamp;
    stamp += 33'333'333;
    const MapUpdateStats st = u.update(s.map, uf);
    for (int d = 0; d < 10; ++d) out.decisions[d] += st.decisions[d];
    if (std::getenv("RDSLAM_TEST_VERBOSE")) {
      std::printf("tx %.2f checked %d:", f.first, st.points_checked);
      for (int d = 0; d < 10; ++d) std::printf(" %d", st.decisions[d]);
      std::printf("\n");
    }
  }
  out.invalid = count_invalid(s.map, s.object_ids);
  return out;
}

std::vector<std::pair<double, cv::Mat>> sweep(double from, double step, int n,
                                              const std::function<cv::Mat(double, int)>& view) {
  std::vector<std::pair<double, cv::Mat>> frames;
  for (int k = 0; k < n; ++k) frames.emplace_back(from + k * step, view(from + k * step, k));
  return frames;
}

}  // namespace temporal

TEST(MapUpdaterTemporal, RemovedObjectRevealingStaticBackgroundIsInvalidated) {
  using namespace temporal;
  const Planes pl;
  Scene s = make_planes_scene(pl);
  // The object is gone; the camera sweeps 30 cm in 5 cm steps (enough baseline to tell the
  // background's depth from the object's).
  const auto frames = sweep(-0.30, 0.05, 7, [&](double tx, int) { return render(pl, tx, false); });
  const Outcome o = run_frames(s, frames);
  // Most object points go (their windows stay in view), by the temporal check's verdict.
  EXPECT_GT(o.invalid, static_cast<int>(s.object_ids.size()) / 2)
      << o.invalid << " of " << s.object_ids.size();
  EXPECT_GT(o.decisions[int(PointDecision::kInvalidStaticChange)], 0);
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
  // The paper's Algorithm 1 (no temporal evidence): nothing tracked, so all are kept.
  Scene s2 = make_planes_scene(pl);
  ChangeDetectionParams paper;
  paper.temporal_check = false;
  EXPECT_EQ(run_frames(s2, frames, paper).invalid, 0);
}

TEST(MapUpdaterTemporal, MovingOccluderKeepsThePoints) {
  using namespace temporal;
  const Planes pl;
  Scene s = make_planes_scene(pl);
  // A new texture in front every frame (a moving object), same sweep.
  const auto frames = sweep(-0.30, 0.05, 7, [&](double tx, int k) {
    const cv::Mat mover = Planes::textured_wide(100 + k);
    return render(pl, tx, true, &mover);
  });
  const Outcome o = run_frames(s, frames);
  EXPECT_EQ(o.invalid, 0);
  EXPECT_EQ(count_invalid(s.map, s.static_ids), 0);
  EXPECT_GT(o.decisions[int(PointDecision::kKeepOccludedMoving)], 0);
}

TEST(MapUpdaterTemporal, StaticOccluderInFrontKeepsThePoints) {
  using namespace temporal;
  const Planes pl;
  Scene s = make_planes_scene(pl);
  // A static board at depth 0.8 in front of the object; the camera moves 1 cm per frame, so
  // the board stays put between frames and the widest recent baseline (5-10 cm) places it
  // in front of the object points.
  const cv::Mat board = Planes::textured_wide(200);
  const auto frames =
      sweep(-0.10, 0.01, 11, [&](double tx, int) { return render(pl, tx, true, &board); });
  const Outcome o = run_frames(s, frames);
  EXPECT_EQ(o.invalid, 0);
  EXPECT_GT(o.decisions[int(PointDecision::kKeepOccludedStatic)], 0);
  // Without the check the verdict is Alg. 1's "moving occluder" (nothing tracked): also kept,
  // for a different reason.
  Scene s2 = make_planes_scene(pl);
  ChangeDetectionParams paper;
  paper.temporal_check = false;
  const Outcome q = run_frames(s2, frames, paper);
  EXPECT_EQ(q.invalid, 0);
  EXPECT_EQ(q.decisions[int(PointDecision::kKeepOccludedStatic)], 0);
}

// dynamic.check_new_points: a point the mapper triangulates from two keyframes must look the
// same at its projection into the oldest recent frame. A point on an object that moved between
// the two keyframes (along the epipolar line) gets a depth its surface does not have; seen
// from a third view it lands elsewhere.
TEST(MapUpdaterTemporal, NewPointMustLookTheSameInARecentFrame) {
  using namespace temporal;
  const Planes pl;
  Scene s = make_planes_scene(pl);
  ChangeDetectionParams p;
  p.histogram_threshold = 0.0;
  p.min_observations = 1;
  MapUpdater u(p, intrinsics());
  const PinholeIntrinsics K = intrinsics();
  const Eigen::Vector2d x(260.0, 120.0);  // background only (the object covers u < 200)
  const cv::Mat kf_image = render(pl, 0.0, false);
  const int64_t kf_stamp = 2'000'000'000;
  auto point_at = [&](double depth) { return Eigen::Vector3d(K.unproject(x.x(), x.y()) * depth); };
  // No recent frame yet: undecidable, kept.
  EXPECT_TRUE(u.recent_frames_agree(point_at(kObjDepth), kf_image, x, kObjDepth, kf_stamp));
  // Recent frames from x = -10 cm to -2 cm (the keyframe is at 0).
  int64_t stamp = kf_stamp - 300'000'000;
  for (double tx = -0.10; tx < -0.015; tx += 0.02) {
    const cv::Mat img = render(pl, tx, false);
    UpdateFrame uf;
    uf.image = &img;
    uf.T_cam_world = camera_at(tx);
    uf.un = s.cur.un.data();
    uf.point_of = s.cur_point_of.data();
    uf.count = 0;
    uf.stamp_ns = stamp;
    stamp += 60'000'000;
    u.update(s.map, uf);
  }
  // At the background's depth the window is found again; at half of it (what a feature on an
  // object moving with the camera triangulates to) it is 200 * 0.1 / 3 = 6.7 px off.
  EXPECT_TRUE(u.recent_frames_agree(point_at(kBgDepth), kf_image, x, kBgDepth, kf_stamp));
  EXPECT_FALSE(u.recent_frames_agree(point_at(kObjDepth), kf_image, x, kObjDepth, kf_stamp));
  // Frames newer than the keyframe are not used; the check can be turned off.
  EXPECT_TRUE(u.recent_frames_agree(point_at(kObjDepth), kf_image, x, kObjDepth, 0));
  p.check_new_points = false;
  MapUpdater off(p, intrinsics());
  EXPECT_TRUE(off.recent_frames_agree(point_at(kObjDepth), kf_image, x, kObjDepth, kf_stamp));
}

// A lens (core/camera.h, radial-tangential k1 = -0.3, k2 = 0.1): eq. (2) windows must be taken
// at the distorted projection of X in the raw image, warped by the lens's local stretch.
// A textured plane at depth 2 seen through the lens from a keyframe at x = 0 and from the
// current frame at x = 0.3 m (a 30 px shift in ideal pixels, more near the centre than at the
// border in raw pixels); in the current frame the left part of the image shows another texture.
// Appearance alone decides (occlusion_handling off): points whose surface is unchanged stay,
// points on the replaced part go. The same scene judged as if the camera had no lens (the
// appearance test at the undistorted projection, as before lenses were handled) calls static
// points changed.
namespace lens {

constexpr double kPlaneDepth = 2.0;
constexpr double kTx = 0.3;
constexpr int kChangedBelowX = 110;  // raw columns [0, kChangedBelowX) replaced in the view

CameraModel camera() {
  CameraModel c;
  c.width = kW;
  c.height = kH;
  c.fx = c.fy = 200;
  c.cx = 160;
  c.cy = 120;
  c.k1 = -0.3;
  c.k2 = 0.1;
  return c;
}

// Texture on the plane: 200 texels per metre, covering x, y in [-3, 3] m.
cv::Mat plane_texture(uint64_t seed) {
  cv::Mat img(1200, 1200, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(7, 7), 2.0);
  return img;
}

// The raw image of the plane from a camera at (tx, 0, 0) looking along z: each raw pixel's
// ray (through the lens) meets the plane; `other` fills raw columns below kChangedBelowX.
cv::Mat render(const CameraModel& cam, double tx, const cv::Mat& tex, const cv::Mat* other) {
  cv::Mat mx(kH, kW, CV_32F), my(kH, kW, CV_32F);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      Eigen::Vector2d ideal;
      EXPECT_TRUE(cam.undistort(Eigen::Vector2d(u, v), &ideal));
      const double X = (ideal.x() - cam.cx) / cam.fx * kPlaneDepth + tx;
      const double Y = (ideal.y() - cam.cy) / cam.fy * kPlaneDepth;
      mx.at<float>(v, u) = static_cast<float>((X + 3.0) * 200.0 - 0.5);
      my.at<float>(v, u) = static_cast<float>((Y + 3.0) * 200.0 - 0.5);
    }
  }
  cv::Mat out, changed;
  cv::remap(tex, out, mx, my, cv::INTER_LINEAR);
  if (other != nullptr) {
    cv::remap(*other, changed, mx, my, cv::INTER_LINEAR);
    changed.colRange(0, kChangedBelowX).copyTo(out.colRange(0, kChangedBelowX));
  }
  return out;
}

struct Outcome {
  int static_checked = 0, static_invalid = 0, changed_checked = 0, changed_invalid = 0;
};

// Keyframe 0 at the origin with map points on the plane at raw feature pixels every 16 px;
// the current frame at (kTx, 0, 0), nothing tracked. `updater_camera` is what the map
// updater is told about the lens.
Outcome run(const CameraModel& updater_camera) {
  const CameraModel cam = camera();
  const cv::Mat tex = plane_texture(21), other = plane_texture(22);
  Map map;
  Keyframe kf;
  kf.id = map.next_kf_id++;
  kf.image = render(cam, 0.0, tex, nullptr);
  std::vector<Eigen::Vector2d> raw, ideal;
  for (int v = 16; v < kH - 8; v += 16) {
    for (int u = 16; u < kW - 8; u += 16) {
      Eigen::Vector2d un;
      EXPECT_TRUE(cam.undistort(Eigen::Vector2d(u, v), &un));
      raw.emplace_back(u, v);
      ideal.push_back(un);
    }
  }
  resize_features(kf.features, static_cast<int>(raw.size()));
  kf.point_of.assign(raw.size(), -1);
  for (size_t i = 0; i < raw.size(); ++i) {
    kf.features.kps[i].pt = cv::Point2f(float(raw[i].x()), float(raw[i].y()));
    kf.features.un[i] = cv::Point2f(float(ideal[i].x()), float(ideal[i].y()));
  }
  map.keyframes.emplace(kf.id, kf);
  ++map.kf_seq;
  const PinholeIntrinsics K{cam.fx, cam.fy, cam.cx, cam.cy};
  std::vector<int64_t> ids;
  for (size_t i = 0; i < raw.size(); ++i)
    ids.push_back(add_point(map, kf.id, static_cast<int>(i),
                            K.unproject(ideal[i].x(), ideal[i].y()) * kPlaneDepth));
  const cv::Mat cur = render(cam, kTx, tex, &other);
  Features none;
  resize_features(none, 0);
  ChangeDetectionParams p = paper_params();
  p.histogram_threshold = 0.0;
  p.occlusion_handling = false;  // eq. (2) alone decides
  std::vector<CheckRecord> log;
  MapUpdater u(p, updater_camera);
  u.set_check_log(&log);
  Pose T;
  T.t = Eigen::Vector3d(-kTx, 0, 0);
  u.update(map, cur, T, none, {});
  Outcome o;
  for (const CheckRecord& r : log) {
    // Where X really is in the current raw image; points whose window straddles the
    // replaced columns' edge are neither.
    const Eigen::Vector2d x = cam.project(T.R * map.points.at(r.id).p_world + T.t);
    const bool changed = x.x()<kChangedBelowX - 10, unchanged = x.x()> kChangedBelowX + 10;
    const bool invalid = !map.points.at(r.id).valid;
    if (changed) {
      ++o.changed_checked;
      o.changed_invalid += invalid;
    } else if (unchanged) {
      ++o.static_checked;
      o.static_invalid += invalid;
    }
  }
  return o;
}

}  // namespace lens

TEST(MapUpdater, LensWindowsAtTheDistortedProjectionKeepStaticPoints) {
  const lens::Outcome o = lens::run(lens::camera());
  std::printf("lens: static %d/%d invalidated, changed %d/%d invalidated\n", o.static_invalid,
              o.static_checked, o.changed_invalid, o.changed_checked);
  ASSERT_GT(o.static_checked, 100);
  ASSERT_GT(o.changed_checked, 20);
  EXPECT_EQ(o.static_invalid, 0);
  EXPECT_GE(o.changed_invalid, 0.9 * o.changed_checked);
  // Told nothing about the lens (windows at the undistorted projection, unwarped), the
  // updater calls static points changed: the scene above does test the lens handling.
  CameraModel no_lens = lens::camera();
  no_lens.k1 = no_lens.k2 = 0.0;
  const lens::Outcome blind = lens::run(no_lens);
  std::printf("no lens: static %d/%d invalidated\n", blind.static_invalid, blind.static_checked);
  EXPECT_GT(blind.static_invalid, 0.2 * blind.static_checked);
}
