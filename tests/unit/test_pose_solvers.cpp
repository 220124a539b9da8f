// Minimal solvers (DLT6 + K[R|T] decomposition, P3P), the quartic solver, eq. (1) refinement
// and the OpenCV MAGSAC++ reference: each checked against ground truth.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "core/pose_refine.h"
#include "core/pose_solvers.h"

using namespace rdslam;

namespace {

struct Scene {
  Intrinsics K;
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  std::vector<Eigen::Vector3d> X;
  std::vector<Eigen::Vector2d> x;
};

Scene random_scene(std::mt19937& rng, int n, double noise_px) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  Scene s;
  s.R = Eigen::AngleAxisd(0.5 * U(rng), Eigen::Vector3d(U(rng), U(rng), U(rng)).normalized())
            .toRotationMatrix();
  s.t = Eigen::Vector3d(U(rng), U(rng), 0.5 * U(rng));
  for (int i = 0; i < n; ++i) {
    // Points in front of the camera, in a 4 m deep volume, mapped back to the world.
    const Eigen::Vector3d Xc(2.0 * U(rng), 1.5 * U(rng), 5.0 + 2.0 * U(rng));
    const Eigen::Vector3d Xw = s.R.transpose() * (Xc - s.t);
    s.X.push_back(Xw);
    s.x.emplace_back(s.K.fx * Xc.x() / Xc.z() + s.K.cx + noise_px * N(rng),
                     s.K.fy * Xc.y() / Xc.z() + s.K.cy + noise_px * N(rng));
  }
  return s;
}

double rot_err_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(A * B.transpose()).angle() * 180.0 / M_PI;
}

}  // namespace

TEST(Quartic, FindsAllRealRoots) {
  // (x-1)(x-2)(x+3)(x-0.5) = x^4 - 0.5x^3 - 7x^2 + 9.5x - 3
  const double c[5] = {1.0, -0.5, -7.0, 9.5, -3.0};
  double r[4];
  const int n = solve_quartic(c, r);
  ASSERT_EQ(n, 4);
  std::vector<double> roots(r, r + n);
  std::sort(roots.begin(), roots.end());
  EXPECT_NEAR(roots[0], -3.0, 1e-9);
  EXPECT_NEAR(roots[1], 0.5, 1e-9);
  EXPECT_NEAR(roots[2], 1.0, 1e-9);
  EXPECT_NEAR(roots[3], 2.0, 1e-9);
}

TEST(Quartic, TwoRealRootsAndScaledLeadingCoefficient) {
  // 2 (x^2 + 1)(x - 3)(x + 0.25): the complex pair must not be reported.
  const double a = 2.0;
  // (x^2+1)(x^2 - 2.75x - 0.75) = x^4 - 2.75x^3 + 0.25x^2 - 2.75x - 0.75
  const double c[5] = {a, -2.75 * a, 0.25 * a, -2.75 * a, -0.75 * a};
  double r[4];
  const int n = solve_quartic(c, r);
  ASSERT_EQ(n, 2);
  std::vector<double> roots(r, r + n);
  std::sort(roots.begin(), roots.end());
  EXPECT_NEAR(roots[0], -0.25, 1e-9);
  EXPECT_NEAR(roots[1], 3.0, 1e-9);
}

TEST(P3P, OneSolutionIsTheTruePose) {
  std::mt19937 rng(7);
  int found = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Scene s = random_scene(rng, 3, 0.0);
    Eigen::Vector3d f[3], X[3];
    for (int i = 0; i < 3; ++i) {
      f[i] = (s.R * s.X[i] + s.t).normalized();
      X[i] = s.X[i];
    }
    Eigen::Matrix3d R[4];
    Eigen::Vector3d t[4];
    const int n = solve_p3p(f, X, R, t);
    ASSERT_LE(n, 4);
    for (int k = 0; k < n; ++k) {
      if (rot_err_deg(R[k], s.R) < 1e-4 && (t[k] - s.t).norm() < 1e-6) {
        ++found;
        break;
      }
    }
  }
  // Near-degenerate random triangles may lose a few digits; nearly all must be exact.
  EXPECT_GE(found, 198);
}

TEST(P3P, CollinearPointsGiveNoSolution) {
  Eigen::Vector3d X[3] = {{0, 0, 5}, {1, 0, 5}, {2, 0, 5}};
  Eigen::Vector3d f[3];
  for (int i = 0; i < 3; ++i) f[i] = X[i].normalized();
  Eigen::Matrix3d R[4];
  Eigen::Vector3d t[4];
  EXPECT_EQ(solve_p3p(f, X, R, t), 0);
}

TEST(Dlt, SixExactPointsRecoverKRT) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const Scene s = random_scene(rng, 6, 0.0);
    Eigen::Vector3d c(0, 0, 0);
    for (const auto& X : s.X) c += X;
    c /= 6;
    Mat34 P;
    ASSERT_TRUE(solve_dlt(s.x.data(), s.X.data(), nullptr, 6, s.K, c, 1.0, &P));
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    ASSERT_TRUE(decompose_projection(P, s.K, &R, &t));
    EXPECT_LT(rot_err_deg(R, s.R), 1e-5);
    EXPECT_LT((t - s.t).norm(), 1e-6);
  }
}

TEST(Dlt, NoisyPointsAreCloseAndIndexSelectionWorks) {
  std::mt19937 rng(4);
  const Scene s = random_scene(rng, 200, 1.0);
  std::vector<int> idx;
  for (int i = 0; i < 200; i += 2) idx.push_back(i);
  Mat34 P;
  ASSERT_TRUE(solve_dlt(s.x.data(), s.X.data(), idx.data(), static_cast<int>(idx.size()), s.K,
                        Eigen::Vector3d(0, 0, 0), 5.0, &P));
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  ASSERT_TRUE(decompose_projection(P, s.K, &R, &t));
  EXPECT_LT(rot_err_deg(R, s.R), 1.0);
  EXPECT_LT((t - s.t).norm(), 0.1);
}

TEST(Dlt, DegenerateInputIsRejected) {
  Intrinsics K;
  std::vector<Eigen::Vector3d> X(6, Eigen::Vector3d(1, 2, 5));  // all the same point
  std::vector<Eigen::Vector2d> x(6, Eigen::Vector2d(400, 300));
  Mat34 P;
  EXPECT_FALSE(solve_dlt(x.data(), X.data(), nullptr, 6, K, Eigen::Vector3d(0, 0, 0), 1.0, &P));
  EXPECT_FALSE(solve_dlt(x.data(), X.data(), nullptr, 5, K, Eigen::Vector3d(0, 0, 0), 1.0, &P));
}

TEST(Decompose, InvertsComposeUpToScaleAndSign) {
  Intrinsics K;
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.1, -0.2, 0.7);
  const Mat34 P = compose_projection(K, R, t);
  for (double scale : {1.0, 3.5, -0.01}) {
    Eigen::Matrix3d R2;
    Eigen::Vector3d t2;
    ASSERT_TRUE(decompose_projection(scale * P, K, &R2, &t2));
    EXPECT_LT(rot_err_deg(R2, R), 1e-9);
    EXPECT_LT((t2 - t).norm(), 1e-9);
  }
}

TEST(RefinePose, ConvergesToTruthAndLowersCost) {
  std::mt19937 rng(5);
  const Scene s = random_scene(rng, 100, 0.0);
  Eigen::Matrix3d R = Eigen::AngleAxisd(0.05, Eigen::Vector3d(0, 1, 0)).toRotationMatrix() * s.R;
  Eigen::Vector3d t = s.t + Eigen::Vector3d(0.05, -0.03, 0.1);
  const RefineResult r = refine_pose(s.x.data(), s.X.data(), nullptr, 100, s.K, 20, &R, &t);
  EXPECT_GT(r.initial_cost, 1.0);
  EXPECT_LT(r.final_cost, 1e-12);
  EXPECT_EQ(r.used_points, 100);
  EXPECT_LT(rot_err_deg(R, s.R), 1e-6);
  EXPECT_LT((t - s.t).norm(), 1e-8);
}

TEST(RefinePose, MaskSelectsPointsAndOutliersOutsideMaskAreIgnored) {
  std::mt19937 rng(6);
  Scene s = random_scene(rng, 60, 0.0);
  std::vector<uint8_t> mask(60, 1);
  for (int i = 0; i < 60; i += 3) {
    s.x[i] += Eigen::Vector2d(80, -50);  // gross outliers, masked out
    mask[i] = 0;
  }
  Eigen::Matrix3d R = s.R;
  Eigen::Vector3d t = s.t + Eigen::Vector3d(0.02, 0.02, -0.05);
  const RefineResult r = refine_pose(s.x.data(), s.X.data(), mask.data(), 60, s.K, 20, &R, &t);
  EXPECT_EQ(r.used_points, 40);
  EXPECT_LT((t - s.t).norm(), 1e-8);
}

TEST(RefinePose, TooFewPointsLeavesPoseUnchanged) {
  std::mt19937 rng(8);
  const Scene s = random_scene(rng, 2, 0.0);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t(1, 2, 3);
  const RefineResult r = refine_pose(s.x.data(), s.X.data(), nullptr, 2, s.K, 10, &R, &t);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(t, Eigen::Vector3d(1, 2, 3));
}

TEST(MagsacReference, RecoversPoseWithOutliers) {
  std::mt19937 rng(9);
  Scene s = random_scene(rng, 200, 0.5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int i = 0; i < 200; i += 4) s.x[i] = Eigen::Vector2d(640 * U(rng), 480 * U(rng));
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  std::vector<uint8_t> mask(200);
  ASSERT_TRUE(
      opencv_magsac_pnp(s.x.data(), s.X.data(), 200, s.K, 1000, 2.0, 0.99, 1, &R, &t, mask.data()));
  EXPECT_LT(rot_err_deg(R, s.R), 0.5);
  EXPECT_LT((t - s.t).norm(), 0.05);
  int inl = 0;
  for (auto m : mask) inl += m;
  EXPECT_GT(inl, 120);
}
