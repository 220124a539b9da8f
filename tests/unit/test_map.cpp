// Map bookkeeping: observations on both sides and Sec. 4's 90% keyframe rule (Map::redundancy),
// the one rule the mapper's culling and the map updater's keyframe check share; local bundle
// adjustment on a map (core/bundle_adjustment.h), with and without its stop predicate, and
// its gauge rule for a map with a single fixed keyframe (keep_scale).
#include <gtest/gtest.h>

#include <random>

#include "core/bundle_adjustment.h"
#include "core/map.h"

namespace rdslam {
namespace {

// One keyframe with `n` features, each with a point; the first `invalid` points are invalid
// and the next `shared` are observed by 3 more keyframes.
Map keyframe_with_points(int n, int invalid, int shared) {
  Map m;
  for (int k = 0; k < 4; ++k) {
    Keyframe& kf = m.keyframes[k];
    kf.id = k;
    kf.point_of.assign(n, -1);
  }
  for (int i = 0; i < n; ++i) {
    MapPoint& p = m.points[i];
    p.id = i;
    p.valid = i >= invalid;
    EXPECT_TRUE(m.add_observation(i, 0, i));
    if (i >= invalid && i < invalid + shared) {
      for (int k = 1; k < 4; ++k) EXPECT_TRUE(m.add_observation(i, k, i));
    }
  }
  return m;
}

TEST(MapRedundancy, CountsInvalidAndSharedPoints) {
  const Map m = keyframe_with_points(100, 40, 50);
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 100);
  EXPECT_EQ(r.redundant, 90);
  // "larger than 90% of its total point number": 90 of 100 is not, 91 is.
  EXPECT_FALSE(r.exceeds(0.9));
  const Map m91 = keyframe_with_points(100, 41, 50);
  EXPECT_TRUE(m91.redundancy(m91.keyframes.at(0)).exceeds(0.9));
}

TEST(MapRedundancy, PointsSeenByTwoOtherKeyframesAreNotShared) {
  Map m = keyframe_with_points(10, 0, 0);
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(m.add_observation(i, 1, i));
    ASSERT_TRUE(m.add_observation(i, 2, i));  // 3 observations in all
  }
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 10);
  EXPECT_EQ(r.redundant, 0);
}

TEST(MapRedundancy, FeaturesWithoutPointsAndErasedPointsDoNotCount) {
  Map m = keyframe_with_points(10, 10, 0);
  m.keyframes.at(0).point_of.resize(20, -1);  // 10 features without a point
  m.erase_point(0);
  const Map::Redundancy r = m.redundancy(m.keyframes.at(0));
  EXPECT_EQ(r.total, 9);
  EXPECT_EQ(r.redundant, 9);
  EXPECT_TRUE(r.exceeds(0.9));
  EXPECT_FALSE(Map{}.redundancy(Keyframe{}).exceeds(0.0));  // no points: never redundant
}

// Five keyframes looking at 300 points, the first two held fixed (the gauge); the others' poses
// and every point perturbed. A full local BA brings the reprojection error back to the pixel
// noise; a BA told to stop after its first iteration stops there (stats.stopped, the second pass
// skipped) and still keeps what that iteration gained: a lower cost than at the start, written
// back to the map.
struct BaScene {
  Map map;
  PinholeIntrinsics K{500, 500, 320, 240};
  std::vector<Eigen::Vector3d> truth;
};

BaScene ba_scene() {
  BaScene s;
  std::mt19937 rng(3);
  std::normal_distribution<double> px(0.0, 0.5), perturb(0.0, 0.02);
  std::uniform_real_distribution<double> ux(-2, 2), uz(4, 8);
  const int n = 300;
  for (int i = 0; i < n; ++i) s.truth.emplace_back(ux(rng), ux(rng), uz(rng));
  for (int k = 0; k < 5; ++k) {
    Keyframe& kf = s.map.keyframes[k];
    kf.id = k;
    kf.fixed = k < 2;
    kf.T_cam_world.R = Eigen::Matrix3d::Identity();
    kf.T_cam_world.t = Eigen::Vector3d(-0.3 * k, 0.05 * k, 0.0);
    kf.features.count = n;
    kf.features.un.resize(n);
    kf.features.scale.assign(n, 1.0f);
    kf.point_of.assign(n, -1);
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d u = s.K.project(kf.T_cam_world * s.truth[i]);
      kf.features.un[i] = cv::Point2f(float(u.x() + px(rng)), float(u.y() + px(rng)));
    }
    if (k >= 2) kf.T_cam_world.t += Eigen::Vector3d(perturb(rng), perturb(rng), perturb(rng));
  }
  for (int i = 0; i < n; ++i) {
    MapPoint& p = s.map.points[i];
    p.id = i;
    p.p_world = s.truth[i] + 5 * Eigen::Vector3d(perturb(rng), perturb(rng), perturb(rng));
    for (int k = 0; k < 5; ++k) EXPECT_TRUE(s.map.add_observation(i, k, i));
  }
  return s;
}

double point_rmse(const BaScene& s) {
  double e = 0;
  for (const auto& [id, p] : s.map.points) e += (p.p_world - s.truth[id]).squaredNorm();
  return std::sqrt(e / s.map.points.size());
}

TEST(BundleAdjust, ConvergesAndStopsWhenAskedKeepingTheFirstIteration) {
  const std::vector<int> window{0, 1, 2, 3, 4};
  BundleAdjustmentParams params;
  BaScene full = ba_scene();
  const double rmse0 = point_rmse(full);
  const BundleAdjustmentStats a = bundle_adjust(full.map, full.K, window, params);
  EXPECT_FALSE(a.stopped);
  EXPECT_LT(a.final_cost, 0.1 * a.initial_cost);
  EXPECT_LT(point_rmse(full), 0.3 * rmse0);

  BaScene early = ba_scene();
  int asked = 0;
  const BundleAdjustmentStats b =
      bundle_adjust(early.map, early.K, window, params, [&asked] { return ++asked >= 2; });
  EXPECT_TRUE(b.stopped);
  EXPECT_EQ(asked, 2) << "asked after iteration 0 (the start) and 1, then stopped";
  EXPECT_DOUBLE_EQ(b.initial_cost, a.initial_cost);
  EXPECT_LT(b.final_cost, b.initial_cost) << "the first iteration's gain is kept";
  EXPECT_GT(b.final_cost, a.final_cost);
  EXPECT_LT(point_rmse(early), rmse0) << "written back to the map";

  BaScene never = ba_scene();  // a predicate that never fires changes nothing
  const BundleAdjustmentStats c =
      bundle_adjust(never.map, never.K, window, params, [] { return false; });
  EXPECT_FALSE(c.stopped);
  EXPECT_DOUBLE_EQ(c.final_cost, a.final_cost);
}

// Sum of squared reprojection errors (pixels) over every observation in the map.
double reprojection_sq(const BaScene& s) {
  double e = 0;
  for (const auto& [id, p] : s.map.points) {
    for (const auto& o : p.obs) {
      const Keyframe& kf = s.map.keyframes.at(o.kf);
      const Eigen::Vector2d u = s.K.project(kf.T_cam_world * p.p_world);
      const cv::Point2f& x = kf.features.un[o.feat];
      e += (u - Eigen::Vector2d(x.x, x.y)).squaredNorm();
    }
  }
  return e;
}

// With only the first keyframe fixed, a uniform scaling of everything else about its centre
// leaves every reprojection unchanged: the scale of the solution is a gauge. keep_scale scales
// the solution back so that the optimised keyframes keep the scale they had before (least
// squares over their centres): the same reprojection error as without it, the keyframes'
// scale unchanged, and the two solutions one scaling (stats.rescale) apart. With two fixed
// keyframes the scale is not free and keep_scale changes nothing.
TEST(BundleAdjust, KeepScaleRemovesOnlyTheGaugeScaleOfASingleFixedKeyframe) {
  const std::vector<int> window{0, 1, 2, 3, 4};
  auto gauge_scene = [] {
    BaScene s = ba_scene();
    s.map.keyframes.at(1).fixed = false;
    // The free part starts 4% too large: the optimiser has no reason to undo that.
    for (int k = 1; k < 5; ++k) {
      Keyframe& kf = s.map.keyframes.at(k);
      const Eigen::Vector3d c = 1.04 * kf.T_cam_world.centre();
      kf.T_cam_world.t = -(kf.T_cam_world.R * c);
    }
    for (auto& [id, p] : s.map.points) p.p_world *= 1.04;
    return s;
  };
  BaScene before = gauge_scene();
  BaScene free_scale = gauge_scene();
  BundleAdjustmentParams params;
  params.keep_scale = false;
  const BundleAdjustmentStats a = bundle_adjust(free_scale.map, free_scale.K, window, params);
  EXPECT_DOUBLE_EQ(a.rescale, 1.0);
  BaScene kept = gauge_scene();
  params.keep_scale = true;
  const BundleAdjustmentStats b = bundle_adjust(kept.map, kept.K, window, params);
  EXPECT_EQ(b.fixed, 1);
  EXPECT_NE(b.rescale, 1.0);
  EXPECT_NEAR(reprojection_sq(kept), reprojection_sq(free_scale),
              1e-6 * reprojection_sq(free_scale));
  double num = 0, den = 0;
  for (int k = 1; k < 5; ++k) {
    const Eigen::Vector3d c_before = before.map.keyframes.at(k).T_cam_world.centre();
    const Eigen::Vector3d c_kept = kept.map.keyframes.at(k).T_cam_world.centre();
    const Eigen::Vector3d c_free = free_scale.map.keyframes.at(k).T_cam_world.centre();
    EXPECT_LT((c_kept - b.rescale * c_free).norm(), 1e-9) << "keyframe " << k;
    num += c_before.dot(c_kept);
    den += c_kept.squaredNorm();
  }
  EXPECT_NEAR(num / den, 1.0, 1e-9) << "the keyframes keep their scale (first centre at 0)";
  for (const auto& [id, p] : kept.map.points) {
    EXPECT_LT((p.p_world - b.rescale * free_scale.map.points.at(id).p_world).norm(), 1e-9);
  }

  BaScene two_fixed = ba_scene();  // keyframes 0 and 1 fixed: the scale is not a gauge
  BaScene two_fixed_ref = ba_scene();
  const BundleAdjustmentStats c = bundle_adjust(two_fixed.map, two_fixed.K, window, params);
  params.keep_scale = false;
  bundle_adjust(two_fixed_ref.map, two_fixed_ref.K, window, params);
  EXPECT_EQ(c.fixed, 2);
  EXPECT_DOUBLE_EQ(c.rescale, 1.0);
  for (int k = 2; k < 5; ++k) {
    EXPECT_EQ(two_fixed.map.keyframes.at(k).T_cam_world.t,
              two_fixed_ref.map.keyframes.at(k).T_cam_world.t);
  }
}

}  // namespace
}  // namespace rdslam
