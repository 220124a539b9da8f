// ATE/RPE, association and Umeyama alignment against values computed by hand.
#include "core/trajectory_eval.h"

#include <gtest/gtest.h>

#include <cmath>

using rdslam::Alignment;
using rdslam::EvalParams;
using rdslam::EvalResult;
using rdslam::IndexPairs;
using rdslam::Sim3Transform;
using rdslam::StampedPose;
using rdslam::Trajectory;

namespace {

const int64_t kMs = 1000000;

StampedPose pose(int64_t stamp_ns, double x, double y, double z,
                 const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) {
  StampedPose p;
  p.stamp_ns = stamp_ns;
  p.p_world_cam = Eigen::Vector3d(x, y, z);
  p.q_world_cam = q;
  return p;
}

Eigen::Quaterniond rot_z_deg(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
}

// Ground truth moving 1 m along x per frame at 10 Hz, no rotation.
Trajectory straight_line(int n) {
  Trajectory t;
  for (int k = 0; k < n; ++k) t.push_back(pose(k * 100 * kMs, k, 0, 0));
  return t;
}

}  // namespace

TEST(TrajectoryEval, ParseAlignment) {
  Alignment a = Alignment::kNone;
  EXPECT_TRUE(rdslam::parse_alignment("sim3", a));
  EXPECT_EQ(a, Alignment::kSim3);
  EXPECT_TRUE(rdslam::parse_alignment("se3", a));
  EXPECT_EQ(a, Alignment::kSe3);
  EXPECT_TRUE(rdslam::parse_alignment("none", a));
  EXPECT_EQ(a, Alignment::kNone);
  EXPECT_FALSE(rdslam::parse_alignment("SIM3", a));
  EXPECT_FALSE(rdslam::parse_alignment("", a));
}

TEST(TrajectoryEval, AssociatesNearestStampWithinMaxDiff) {
  Trajectory gt;
  for (int64_t t : {0, 100, 200, 300, 400}) gt.push_back(pose(t * kMs, 0, 0, 0));
  Trajectory est;
  // 96 -> 100 (4 ms), 205 -> 200, 350 is 50 ms from anything, 409 -> 400 (9 ms).
  for (int64_t t : {96, 205, 350, 409}) est.push_back(pose(t * kMs, 0, 0, 0));
  const IndexPairs pairs = rdslam::associate_by_time(gt, est, 10 * kMs);
  const IndexPairs expected = {{1, 0}, {2, 1}, {4, 3}};
  EXPECT_EQ(pairs, expected);
  // A tighter limit drops the 9 ms match.
  const IndexPairs tight = rdslam::associate_by_time(gt, est, 5 * kMs);
  const IndexPairs expected_tight = {{1, 0}, {2, 1}};
  EXPECT_EQ(tight, expected_tight);
}

TEST(TrajectoryEval, AssociationTieGoesToEarlierStamp) {
  Trajectory gt = {pose(0, 0, 0, 0), pose(20 * kMs, 0, 0, 0), pose(40 * kMs, 0, 0, 0)};
  Trajectory est = {pose(10 * kMs, 0, 0, 0)};
  const IndexPairs pairs = rdslam::associate_by_time(gt, est, 10 * kMs);
  const IndexPairs expected = {{0, 0}};
  EXPECT_EQ(pairs, expected);
}

TEST(TrajectoryEval, AssociationIteratesTheShorterTrajectory) {
  // The estimate has more poses than the ground truth: every ground-truth pose finds its
  // nearest estimate (evo's rule), not the other way round.
  Trajectory gt = {pose(0, 0, 0, 0), pose(100 * kMs, 0, 0, 0)};
  Trajectory est;
  for (int64_t t = 0; t <= 100; t += 25) est.push_back(pose((t + 2) * kMs, 0, 0, 0));
  const IndexPairs pairs = rdslam::associate_by_time(gt, est, 10 * kMs);
  const IndexPairs expected = {{0, 0}, {1, 4}};
  EXPECT_EQ(pairs, expected);
}

TEST(TrajectoryEval, AssociatesUnsortedStampsLinearly) {
  Trajectory gt = {pose(300 * kMs, 0, 0, 0), pose(100 * kMs, 0, 0, 0), pose(200 * kMs, 0, 0, 0)};
  Trajectory est = {pose(101 * kMs, 0, 0, 0), pose(299 * kMs, 0, 0, 0)};
  const IndexPairs pairs = rdslam::associate_by_time(gt, est, 10 * kMs);
  const IndexPairs expected = {{1, 0}, {0, 1}};
  EXPECT_EQ(pairs, expected);
}

TEST(TrajectoryEval, AssociatesByIndexUpToTheShorterLength) {
  const IndexPairs pairs = rdslam::associate_by_index(straight_line(4), straight_line(3));
  const IndexPairs expected = {{0, 0}, {1, 1}, {2, 2}};
  EXPECT_EQ(pairs, expected);
}

TEST(TrajectoryEval, UmeyamaRecoversKnownSim3) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(3, -1, 2);
  const double s = 2.5;
  std::vector<Eigen::Vector3d> src = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0},
                                      {0, 0, 3}, {1, 1, 1}, {-2, 0.5, 1}};
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.push_back(s * R * p + t);

  Sim3Transform T;
  ASSERT_TRUE(rdslam::umeyama_align(src, dst, Alignment::kSim3, T));
  EXPECT_NEAR(T.scale, s, 1e-12);
  EXPECT_LT((T.R - R).norm(), 1e-12);
  EXPECT_LT((T.t - t).norm(), 1e-12);

  // SE3 keeps the scale at 1; on unscaled data it recovers R, t exactly.
  std::vector<Eigen::Vector3d> dst_rigid;
  for (const auto& p : src) dst_rigid.push_back(R * p + t);
  ASSERT_TRUE(rdslam::umeyama_align(src, dst_rigid, Alignment::kSe3, T));
  EXPECT_EQ(T.scale, 1.0);
  EXPECT_LT((T.R - R).norm(), 1e-12);
  EXPECT_LT((T.t - t).norm(), 1e-12);
  EXPECT_NEAR(T.R.determinant(), 1.0, 1e-12);

  ASSERT_TRUE(rdslam::umeyama_align(src, dst, Alignment::kNone, T));
  EXPECT_EQ(T.scale, 1.0);
  EXPECT_TRUE(T.R.isIdentity());
  EXPECT_TRUE(T.t.isZero());
}

TEST(TrajectoryEval, UmeyamaReturnsAProperRotationForMirroredPoints) {
  // dst is src mirrored in z: the best rotation must still have det +1 (Umeyama's S).
  std::vector<Eigen::Vector3d> src = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::vector<Eigen::Vector3d> dst;
  for (const auto& p : src) dst.emplace_back(p.x(), p.y(), -p.z());
  Sim3Transform T;
  ASSERT_TRUE(rdslam::umeyama_align(src, dst, Alignment::kSe3, T));
  EXPECT_NEAR(T.R.determinant(), 1.0, 1e-12);
}

TEST(TrajectoryEval, UmeyamaRefusesDegenerateInput) {
  Sim3Transform T;
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_FALSE(rdslam::umeyama_align(two, two, Alignment::kSe3, T));
  const std::vector<Eigen::Vector3d> same = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  const std::vector<Eigen::Vector3d> spread = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  EXPECT_FALSE(rdslam::umeyama_align(same, spread, Alignment::kSim3, T));
  // Collinear points leave the rotation about the line undetermined.
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  EXPECT_FALSE(rdslam::umeyama_align(line, line, Alignment::kSe3, T));
  EXPECT_TRUE(T.R.isIdentity());
}

TEST(TrajectoryEval, StatsMatchHandComputedValues) {
  const rdslam::ErrorStats s = rdslam::compute_stats({3, 4, 0, 5});
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(12.5));  // (9 + 16 + 0 + 25) / 4
  EXPECT_DOUBLE_EQ(s.mean, 3.0);
  EXPECT_DOUBLE_EQ(s.median, 3.5);  // even count: mean of 3 and 4
  EXPECT_DOUBLE_EQ(s.max, 5.0);
  EXPECT_DOUBLE_EQ(s.min, 0.0);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(3.5));  // (0 + 1 + 9 + 4) / 4
  EXPECT_DOUBLE_EQ(rdslam::compute_stats({2, 9, 1}).median, 2.0);
  EXPECT_EQ(rdslam::compute_stats({}).count, 0u);
}

TEST(TrajectoryEval, AteWithoutAlignmentIsThePositionError) {
  const Trajectory gt = straight_line(4);
  Trajectory est = gt;
  est[0].p_world_cam.y() += 0.1;
  est[1].p_world_cam.y() -= 0.2;
  est[3].p_world_cam.z() += 0.2;
  EvalParams params;
  params.align = Alignment::kNone;
  const EvalResult r = rdslam::evaluate_trajectories(gt, est, params);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.pairs.size(), 4u);
  EXPECT_NEAR(r.ate_m.rmse, 0.15, 1e-12);  // sqrt((0.01 + 0.04 + 0 + 0.04) / 4)
  EXPECT_NEAR(r.ate_m.mean, 0.125, 1e-12);
  EXPECT_NEAR(r.ate_m.median, 0.15, 1e-12);
  EXPECT_NEAR(r.ate_m.max, 0.2, 1e-12);
  EXPECT_NEAR(r.gt_path_length_m, 3.0, 1e-12);
  EXPECT_NEAR(r.ate_pct_path.rmse, 5.0, 1e-10);  // 0.15 m of 3 m
  EXPECT_NEAR(r.ate_pct_path.max, 100.0 * 0.2 / 3.0, 1e-10);
}

TEST(TrajectoryEval, RpeMatchesHandComputedRelativeErrors) {
  // Estimate: the third pose is yawed by 10 deg, the last step is 1.5 m instead of 1 m.
  const Trajectory gt = straight_line(4);
  Trajectory est = gt;
  est[2].q_world_cam = rot_z_deg(10);
  est[3].q_world_cam = rot_z_deg(10);
  est[3].p_world_cam.x() = 3.5;
  EvalParams params;
  params.align = Alignment::kNone;
  const EvalResult r = rdslam::evaluate_trajectories(gt, est, params);
  ASSERT_TRUE(r.ok) << r.error;
  // Pairs (0,1): exact. (1,2): E = [Rz(10), 0]: 0 m, 10 deg. (2,3): the estimate's step
  // seen from the yawed camera is Rz(-10) * (1.5, 0, 0), against (1, 0, 0) in ground truth:
  // |t(E)| = sqrt(1.5^2 + 1 - 3 cos 10deg), 0 deg.
  const double e23 = std::sqrt(3.25 - 3.0 * std::cos(10.0 * M_PI / 180.0));
  ASSERT_EQ(r.rpe_trans_m.count, 3u);
  EXPECT_NEAR(r.rpe_trans_m.max, e23, 1e-12);
  EXPECT_NEAR(r.rpe_trans_m.rmse, e23 / std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(r.rpe_trans_m.median, 0.0, 1e-12);
  EXPECT_NEAR(r.rpe_rot_deg.max, 10.0, 1e-10);
  EXPECT_NEAR(r.rpe_rot_deg.mean, 10.0 / 3.0, 1e-10);
  EXPECT_NEAR(r.rpe_rot_deg.median, 0.0, 1e-10);
  // ATE: only the last position is off, by 0.5 m.
  EXPECT_NEAR(r.ate_m.rmse, 0.25, 1e-12);
  EXPECT_NEAR(r.ate_m.median, 0.0, 1e-12);

  // delta 2: the single pair (0, 2): translation exact, rotation 10 deg.
  params.rpe_delta = 2;
  const EvalResult r2 = rdslam::evaluate_trajectories(gt, est, params);
  ASSERT_TRUE(r2.ok);
  ASSERT_EQ(r2.rpe_trans_m.count, 1u);
  EXPECT_NEAR(r2.rpe_trans_m.max, 0.0, 1e-12);
  EXPECT_NEAR(r2.rpe_rot_deg.max, 10.0, 1e-10);
}

TEST(TrajectoryEval, Sim3AlignmentRemovesScaleRotationAndOffset) {
  // A monocular estimate: ground truth in another frame at 0.3 x scale.
  Trajectory gt;
  for (int k = 0; k < 30; ++k) {
    const double a = 0.2 * k;
    gt.push_back(pose(k * 50 * kMs, 4 * std::cos(a), 3 * std::sin(a), 0.1 * k, rot_z_deg(7 * k)));
  }
  const Eigen::Quaterniond q(Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, 1, -0.4).normalized()));
  const Eigen::Vector3d t(-5, 2, 7);
  Trajectory est;
  for (const auto& p : gt) {
    est.push_back(pose(p.stamp_ns + 3 * kMs, 0, 0, 0, q * p.q_world_cam));
    est.back().p_world_cam = 0.3 * (q * p.p_world_cam) + t;
  }
  EvalParams params;  // sim3 by default
  const EvalResult r = rdslam::evaluate_trajectories(gt, est, params);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.pairs.size(), 30u);
  EXPECT_NEAR(r.alignment.scale, 1.0 / 0.3, 1e-9);
  EXPECT_LT(r.ate_m.max, 1e-9);
  EXPECT_LT(r.rpe_trans_m.max, 1e-9);
  EXPECT_LT(r.rpe_rot_deg.max, 1e-6);

  // SE3 cannot undo the scale: the error is large.
  params.align = Alignment::kSe3;
  const EvalResult rigid = rdslam::evaluate_trajectories(gt, est, params);
  ASSERT_TRUE(rigid.ok);
  EXPECT_EQ(rigid.alignment.scale, 1.0);
  EXPECT_GT(rigid.ate_m.rmse, 1.0);
}

TEST(TrajectoryEval, ReportsWhyEvaluationIsImpossible) {
  const Trajectory gt = straight_line(5);
  Trajectory late = gt;
  for (auto& p : late) p.stamp_ns += 1000 * kMs;  // 1 s later: nothing within 10 ms
  EvalParams params;
  EvalResult r = rdslam::evaluate_trajectories(gt, late, params);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("no pose of the estimate"), std::string::npos) << r.error;

  r = rdslam::evaluate_trajectories(gt, Trajectory(gt.begin(), gt.begin() + 2), params);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error, "alignment sim3 needs at least 3 associated poses, found 2");

  r = rdslam::evaluate_trajectories(gt, gt, params);  // a straight line: rotation undetermined
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("degenerate"), std::string::npos) << r.error;

  params.align = Alignment::kNone;  // without alignment a line is fine
  r = rdslam::evaluate_trajectories(gt, gt, params);
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.ate_m.max, 0.0);

  params.rpe_delta = 0;
  r = rdslam::evaluate_trajectories(gt, gt, params);
  EXPECT_FALSE(r.ok);
}
