// core/map_merge.h: Sim(3) RANSAC over 3D-3D pairs with outliers, the camera-pose transform,
// and the merge of one map into another (id offsets, transformed geometry, fused points).
#include "core/map_merge.h"

#include <gtest/gtest.h>

#include <random>

namespace rdslam {
namespace {

Sim3 example_sim3() {
  Sim3 S;
  S.s = 1.7;
  S.R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, 1.0, -0.3).normalized()).toRotationMatrix();
  S.t = Eigen::Vector3d(0.5, -1.2, 2.0);
  return S;
}

Pose camera_at(const Eigen::Vector3d& centre) {
  Pose T;  // looking along +z of the world
  T.t = -centre;
  return T;
}

TEST(MapMerge, Sim3InverseAndCameraTransform) {
  const Sim3 S = example_sim3();
  const Eigen::Vector3d x(0.3, -0.2, 4.0);
  EXPECT_LT((S.inverse() * (S * x) - x).norm(), 1e-12);
  // A camera moved by S sees the moved point at the same pixel.
  const PinholeIntrinsics K{500, 500, 320, 240};
  Pose T;
  T.R = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.t = Eigen::Vector3d(0.1, 0.0, 0.2);
  const Pose T2 = S.camera(T);
  EXPECT_LT((K.project(T * x) - K.project(T2 * (S * x))).norm(), 1e-9);
  EXPECT_LT((T2.centre() - S * T.centre()).norm(), 1e-9);
}

TEST(MapMerge, RansacRecoversTheSimilarityDespiteOutliers) {
  const Sim3 S = example_sim3();
  const PinholeIntrinsics K{500, 500, 320, 240};
  const Pose Ta = camera_at(Eigen::Vector3d(0, 0, 0));
  const Pose Tb = S.camera(Ta);  // the same camera in the target frame
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> px(0.0, 0.5);
  std::vector<Sim3Pair, Eigen::aligned_allocator<Sim3Pair>> pairs;
  for (int i = 0; i < 100; ++i) {
    Sim3Pair q;
    q.a = Eigen::Vector3d(u(rng), u(rng), 3.0 + u(rng));
    q.b = S * q.a;
    if (i % 3 == 0) q.b += Eigen::Vector3d(u(rng), u(rng), u(rng));  // a third are wrong
    q.xa = K.project(Ta * q.a) + Eigen::Vector2d(px(rng), px(rng));
    q.xb = K.project(Tb * (S * q.a)) + Eigen::Vector2d(px(rng), px(rng));
    pairs.push_back(q);
  }
  Sim3RansacParams p;
  p.min_inliers = 20;
  Sim3 E;
  std::vector<uint8_t> inl;
  const int n = estimate_sim3(pairs, Ta, Tb, K, p, &E, &inl);
  int true_in = 0, false_in = 0;  // 66 true pairs, 34 displaced
  for (size_t i = 0; i < pairs.size(); ++i) (i % 3 == 0 ? false_in : true_in) += inl[i];
  EXPECT_EQ(n, true_in + false_in);
  EXPECT_GE(true_in, 62);  // 0.5 px noise: nearly all inside the 99% gate
  EXPECT_LE(false_in, 3);  // a displaced point may fall inside the gate by chance
  EXPECT_NEAR(E.s, S.s, 0.02 * S.s);
  EXPECT_LT(Eigen::AngleAxisd(E.R.transpose() * S.R).angle(), 0.01);
  EXPECT_LT((E.t - S.t).norm(), 0.05);
  // Too few consistent pairs: no model.
  pairs.resize(12);
  EXPECT_EQ(estimate_sim3(pairs, Ta, Tb, K, p, &E, &inl), 0);
}

TEST(MapMerge, MergeShiftsIdsMovesGeometryAndFuses) {
  Map target, source;
  for (int k = 0; k < 3; ++k) {
    Keyframe& kf = target.keyframes[k];
    kf.id = k;
    kf.point_of.assign(4, -1);
  }
  target.keyframes[0].fixed = true;
  target.next_kf_id = 3;
  MapPoint tp;
  tp.id = 7;
  target.points[7] = tp;
  target.add_observation(7, 0, 0);
  target.next_point_id = 10;
  target.kf_seq = 3;

  for (int k = 0; k < 2; ++k) {
    Keyframe& kf = source.keyframes[k];
    kf.id = k;
    kf.fixed = k == 0;
    kf.T_cam_world = camera_at(Eigen::Vector3d(k, 0, 0));
    kf.point_of.assign(4, -1);
  }
  source.next_kf_id = 2;
  for (int64_t i = 0; i < 2; ++i) {
    MapPoint p;
    p.id = i;
    p.p_world = Eigen::Vector3d(double(i), 1.0, 3.0);
    p.min_dist = 1.f;
    p.max_dist = 2.f;
    source.points[i] = p;
    source.add_observation(i, 0, int(i));
    source.add_observation(i, 1, int(i));
  }
  source.next_point_id = 2;
  source.kf_seq = 2;
  const Sim3 S = example_sim3();
  const Pose T1 = source.keyframes[1].T_cam_world;
  const Eigen::Vector3d p0 = source.points[0].p_world;
  int kf_off = 0;
  int64_t pt_off = 0;
  // Source point 1 is the target's point 7.
  const int fused = merge_maps(target, std::move(source), S, {{1, 7}}, &kf_off, &pt_off);
  EXPECT_EQ(fused, 1);
  EXPECT_EQ(kf_off, 3);
  EXPECT_EQ(pt_off, 10);
  EXPECT_EQ(target.keyframes.size(), 5u);
  EXPECT_EQ(target.next_kf_id, 5);
  EXPECT_EQ(target.next_point_id, 12);
  EXPECT_TRUE(target.keyframes.at(0).fixed);
  EXPECT_FALSE(target.keyframes.at(3).fixed);  // the source's gauge is not one any more
  const MapPoint* moved = target.point(10);
  ASSERT_NE(moved, nullptr);
  EXPECT_LT((moved->p_world - S * p0).norm(), 1e-12);
  EXPECT_FLOAT_EQ(moved->max_dist, float(2.0 * S.s));
  EXPECT_EQ(target.point(11), nullptr);  // fused into 7
  const MapPoint* kept = target.point(7);
  ASSERT_NE(kept, nullptr);
  EXPECT_EQ(kept->obs.size(), 3u);  // its own and the two source keyframes'
  EXPECT_EQ(target.keyframes.at(4).point_of[1], 7);
  EXPECT_EQ(target.keyframes.at(4).point_of[0], 10);
  // Keyframe 1 of the source, now 4: same projections of the moved points.
  const PinholeIntrinsics K{500, 500, 320, 240};
  EXPECT_LT(
      (K.project(T1 * p0) - K.project(target.keyframes.at(4).T_cam_world * moved->p_world)).norm(),
      1e-9);
}

}  // namespace
}  // namespace rdslam
