// core/geometry + core/pose_estimation: triangulation, multi-view point refinement, epipolar
// geometry and the eq. (1) pose refinement with outliers.
#include <gtest/gtest.h>

#include <random>

#include "core/geometry.h"
#include "core/pose_estimation.h"

namespace rdslam {
namespace {

const PinholeIntrinsics kK{500, 500, 320, 240};

Pose make_pose(double yaw, const Eigen::Vector3d& centre) {
  Pose T;
  T.R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.t = -T.R * centre;
  return T;
}

TEST(Geometry, TriangulationRecoversPoint) {
  const Pose T0 = make_pose(0.0, {0, 0, 0});
  const Pose T1 = make_pose(0.1, {0.5, 0.05, 0});
  const Eigen::Vector3d p(0.3, -0.2, 4.0);
  const Eigen::Vector3d b0 = T0 * p / (T0 * p).z(), b1 = T1 * p / (T1 * p).z();
  Eigen::Vector3d q;
  ASSERT_TRUE(triangulate_dlt(T0, b0, T1, b1, q));
  EXPECT_LT((q - p).norm(), 1e-9);
  EXPECT_LT(parallax_cos(p, T0.centre(), T1.centre()), 0.999);
}

TEST(Geometry, PointsSatisfyEpipolarConstraint) {
  const Pose T0 = make_pose(0.05, {0, 0, 0});
  const Pose T1 = make_pose(-0.1, {0.4, 0.1, 0.2});
  const Eigen::Matrix3d F = fundamental_from_poses(kK, T0, T1);
  const Eigen::Vector3d p(1.0, 0.5, 5.0);
  const Eigen::Vector2d x0 = kK.project(T0 * p), x1 = kK.project(T1 * p);
  EXPECT_LT(epipolar_dist2(F, x0, x1), 1e-12);
  EXPECT_GT(epipolar_dist2(F, x0, x1 + Eigen::Vector2d(0, 5)), 1.0);
}

TEST(Geometry, MultiViewRefinementReducesError) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.5);
  const Eigen::Vector3d p(0.2, 0.1, 6.0);
  Pose poses[4] = {make_pose(0, {0, 0, 0}), make_pose(0.05, {0.3, 0, 0}),
                   make_pose(-0.05, {-0.3, 0.1, 0}), make_pose(0.1, {0.6, 0, 0.2})};
  Eigen::Vector2d obs[4];
  double sig[4] = {1, 1, 1, 1};
  for (int i = 0; i < 4; ++i)
    obs[i] = kK.project(poses[i] * p) + Eigen::Vector2d(noise(rng), noise(rng));
  Eigen::Vector3d x = p + Eigen::Vector3d(0.3, -0.2, 0.8);
  const double rms = refine_point(kK, poses, obs, sig, 4, x, 10);
  ASSERT_GE(rms, 0.0);
  EXPECT_LT(rms, 1.0);
  EXPECT_LT((x - p).norm(), 0.1);
}

TEST(PoseRefine, ConvergesAndFlagsOutliers) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2, 2), z(3, 8), px(0, 640);
  std::normal_distribution<double> noise(0.0, 0.5);
  const Pose truth = make_pose(0.2, {0.3, -0.1, 0.5});
  const int n = 200;
  std::vector<Eigen::Vector3d> pw(n);
  std::vector<Eigen::Vector2d> obs(n);
  std::vector<float> sig(n, 1.0f);
  std::vector<uint8_t> inl(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pc(u(rng), u(rng), z(rng));
    pw[i] = truth.inverse() * pc;
    obs[i] = kK.project(pc) + Eigen::Vector2d(noise(rng), noise(rng));
    if (i % 5 == 0) obs[i] = Eigen::Vector2d(px(rng), px(rng) * 0.75);  // 20% outliers
  }
  Pose T = truth;
  T.t += Eigen::Vector3d(0.05, -0.03, 0.08);
  T.R = exp_so3(Eigen::Vector3d(0.02, -0.01, 0.03)) * T.R;
  const PoseRefineStats st = refine_pose(kK, pw.data(), obs.data(), sig.data(), n, T, inl.data());
  EXPECT_LT((T.centre() - truth.centre()).norm(), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(T.R * truth.R.transpose()).angle(), 0.002);
  int flagged_outliers = 0;
  for (int i = 0; i < n; i += 5) flagged_outliers += inl[i] == 0;
  EXPECT_GE(flagged_outliers, 38);  // of 40 gross outliers
  EXPECT_GE(st.inliers, 150);
}

// A rigid group of near points displaced coherently (a moving object, RDSLAM Figure 8): eq. (1)
// started from the robust estimator's inliers stays at the camera pose; started from all
// correspondences, the Huber kernel lets the group pull the pose before re-classification.
TEST(PoseRefine, KeepsInitialInliersAgainstACoherentGroup) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2, 2), z(4, 8), un(-0.3, 0.3), zn(1.0, 1.3);
  std::normal_distribution<double> noise(0.0, 0.5);
  const Pose truth = make_pose(0.1, {0.2, 0.0, 0.3});
  const int n = 300;
  std::vector<Eigen::Vector3d> pw(n);
  std::vector<Eigen::Vector2d> obs(n);
  std::vector<float> sig(n, 1.0f);
  std::vector<uint8_t> inl(n);
  for (int i = 0; i < n; ++i) {
    const bool object = i % 3 == 0;  // 100 near points, seen 6 px to the right
    const Eigen::Vector3d pc = object ? Eigen::Vector3d(un(rng), un(rng), zn(rng))
                                      : Eigen::Vector3d(u(rng), u(rng), z(rng));
    pw[i] = truth.inverse() * pc;
    obs[i] = kK.project(pc) + Eigen::Vector2d(noise(rng), noise(rng));
    if (object) obs[i].x() += 6.0;
  }
  auto refine = [&](bool keep) {
    for (int i = 0; i < n; ++i) inl[i] = i % 3 != 0;  // the robust estimator's consensus set
    Pose T = truth;
    refine_pose(kK, pw.data(), obs.data(), sig.data(), n, T, inl.data(), 4, 10, keep);
    return (T.centre() - truth.centre()).norm();
  };
  const double kept = refine(true);
  int object_inliers = 0;
  for (int i = 0; i < n; i += 3) object_inliers += inl[i];
  EXPECT_LT(kept, 0.01);
  EXPECT_EQ(object_inliers, 0);
  EXPECT_GT(refine(false), 2.0 * kept);  // the old behaviour: pulled towards the group
}

TEST(PoseEstimator, RecoversPoseWithoutPrior) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2, 2), z(3, 8), px(0, 640);
  const Pose truth = make_pose(-0.3, {0.2, 0.1, -0.4});
  const int n = 120;
  std::vector<Eigen::Vector3d> pw(n);
  std::vector<Eigen::Vector2d> obs(n);
  std::vector<float> sig(n, 1.0f);
  std::vector<uint8_t> inl(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pc(u(rng), u(rng), z(rng));
    pw[i] = truth.inverse() * pc;
    obs[i] = kK.project(pc);
    if (i % 3 == 0) obs[i] = Eigen::Vector2d(px(rng), px(rng) * 0.75);
  }
  CameraModel cam;
  cam.fx = cam.fy = 500;
  cam.cx = 320;
  cam.cy = 240;
  PoseEstimator est(ParsacParams{}, cam, n);
  Pose T;
  const int inliers = est.estimate(pw.data(), obs.data(), sig.data(), n, T, inl.data());
  EXPECT_GE(inliers, 75);
  EXPECT_LT((T.centre() - truth.centre()).norm(), 1e-3);
}

}  // namespace
}  // namespace rdslam
