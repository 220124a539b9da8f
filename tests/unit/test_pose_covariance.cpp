// PoseInformation (core/pose_refine.h): the covariance rdslam.pose_t publishes, against the
// empirical covariance of Monte-Carlo pose estimates. Each trial draws fresh pixel noise on a
// fixed 2D-3D set, refines the pose with the tracker's eq. (1) (core/pose_estimation.h
// refine_pose, from a perturbed start) and computes the covariance over its inliers at the
// result; the errors of the estimates, in the published parameterisation [camera centre in
// world, rotation vector of camera -> world in the world frame], must scatter as predicted.
// Fixed seed; tolerances from the sampling error of 400 trials (a variance estimate from 400
// samples has a relative standard deviation of 7%).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "core/pose_estimation.h"
#include "core/pose_refine.h"

namespace rdslam {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

struct McResult {
  Mat6 empirical = Mat6::Zero();  // covariance of the estimates' errors
  Mat6 predicted = Mat6::Zero();  // mean of the per-trial PoseInformation covariances
  double mean_nees = 0.0;         // mean of e^T Sigma^-1 e (chi-square, 6 DoF, if consistent)
  int trials = 0;
};

// `noise_px`: the true per-axis pixel noise at pyramid level 0 (the model assumes 1 px); point
// i is at level i % 3 (scale 1.2^level for both the model and the drawn noise).
McResult monte_carlo(double noise_px, int trials, uint32_t seed) {
  const PinholeIntrinsics K{525.0, 525.0, 319.5, 239.5};
  // A rotated camera and an anisotropic point set (wide in x, shallow in y), so that the
  // covariance's axes differ and a wrong frame conversion shows in the diagonal.
  Pose T_true;
  T_true.R =
      (Eigen::AngleAxisd(1.2, Eigen::Vector3d(0.3, -0.5, 0.8).normalized())).toRotationMatrix();
  T_true.t = Eigen::Vector3d(0.4, -0.2, 1.5);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  const int n = 80;
  std::vector<Eigen::Vector3d> pw(n);
  std::vector<Eigen::Vector2d> clean(n), obs(n);
  std::vector<float> sigma(n);
  const Pose T_wc = T_true.inverse();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d pc(2.5 * U(rng), 0.5 * U(rng), 6.0 + 2.5 * U(rng));
    pw[i] = T_wc * pc;
    clean[i] = K.project(pc);
    sigma[i] = static_cast<float>(std::pow(1.2, i % 3));
  }
  McResult res;
  std::vector<Vec6> errors;
  std::vector<Mat6> sigmas;
  std::vector<uint8_t> inlier(n);
  for (int k = 0; k < trials; ++k) {
    for (int i = 0; i < n; ++i) {
      obs[i] = clean[i] + noise_px * sigma[i] * Eigen::Vector2d(N(rng), N(rng));
    }
    Pose T = T_true;
    T.R = exp_so3(Eigen::Vector3d(0.01 * U(rng), 0.01 * U(rng), 0.01 * U(rng))) * T.R;
    T.t += Eigen::Vector3d(0.02 * U(rng), 0.02 * U(rng), 0.02 * U(rng));
    refine_pose(K, pw.data(), obs.data(), sigma.data(), n, T, inlier.data());
    PoseInformation info(kInlierChi2);
    for (int i = 0; i < n; ++i) {
      if (inlier[i]) info.add(K, T, pw[i], obs[i], sigma[i]);
    }
    std::array<double, 36> cov;
    if (!info.covariance(T, &cov)) continue;
    const Mat6 S = Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(cov.data());
    // Published error: c_true = c + dc, R_true = exp(dtheta) R (camera -> world, world frame).
    const Pose Twc = T.inverse();
    Vec6 e;
    e.head<3>() = T_wc.t - Twc.t;
    e.tail<3>() = log_so3(T_wc.R * Twc.R.transpose());
    errors.push_back(e);
    sigmas.push_back(S);
    res.predicted += S;
    res.mean_nees += e.dot(S.ldlt().solve(e));
  }
  res.trials = static_cast<int>(errors.size());
  if (res.trials < 2) return res;
  res.predicted /= res.trials;
  res.mean_nees /= res.trials;
  Vec6 mean = Vec6::Zero();
  for (const Vec6& e : errors) mean += e;
  mean /= res.trials;
  for (const Vec6& e : errors) res.empirical += (e - mean) * (e - mean).transpose();
  res.empirical /= (res.trials - 1);
  return res;
}

void expect_consistent(const McResult& r, const char* what) {
  ASSERT_GE(r.trials, 390) << what;
  for (int d = 0; d < 6; ++d) {
    const double ratio = r.predicted(d, d) / r.empirical(d, d);
    std::printf("[ measured ] %s: axis %d predicted/empirical variance %.3f\n", what, d, ratio);
    // 400 samples: +-7% sampling error per variance; 0.75..1.33 is over 4 standard deviations.
    EXPECT_GT(ratio, 0.75) << what << " axis " << d;
    EXPECT_LT(ratio, 1.33) << what << " axis " << d;
  }
  const double tr = r.predicted.trace() / r.empirical.trace();
  std::printf("[ measured ] %s: trace ratio %.3f, mean NEES %.2f (6 if consistent)\n", what, tr,
              r.mean_nees);
  EXPECT_GT(tr, 0.8) << what;
  EXPECT_LT(tr, 1.25) << what;
  // Mean of 400 chi-square(6) draws: 6 +- 0.17; the estimated sigma0 adds a few percent.
  EXPECT_GT(r.mean_nees, 6.0 * 0.85) << what;
  EXPECT_LT(r.mean_nees, 6.0 * 1.2) << what;
}

TEST(PoseCovariance, MatchesMonteCarloScatterWithTheNoiseTheResidualsShow) {
  // True noise 0.6 px while the model says 1 px: the a-posteriori variance factor has to scale
  // the information; with the model's 1 px the variances would be 2.8x too large.
  expect_consistent(monte_carlo(0.6, 400, 7), "0.6 px");
}

TEST(PoseCovariance, MatchesMonteCarloScatterAtTheModelsNoise) {
  expect_consistent(monte_carlo(1.0, 400, 11), "1.0 px");
}

TEST(PoseCovariance, ScalesWithTheMapUnits) {
  // Monocular scale is arbitrary: a map twice as large (points and translation) gives the same
  // pixels, a centre covariance 4x as large and the same rotation covariance.
  const PinholeIntrinsics K{500.0, 500.0, 320.0, 240.0};
  Pose T;
  T.R = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.t = Eigen::Vector3d(0.1, 0.2, 0.3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  PoseInformation a, b;
  Pose T2 = T;
  T2.t *= 2.0;
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d pc(U(rng), U(rng), 4.0 + U(rng));
    const Eigen::Vector3d pw = T.inverse() * pc;
    const Eigen::Vector2d px = K.project(pc) + Eigen::Vector2d(0.5 * U(rng), 0.5 * U(rng));
    a.add(K, T, pw, px, 1.0);
    b.add(K, T2, 2.0 * pw, px, 1.0);
  }
  std::array<double, 36> ca, cb;
  ASSERT_TRUE(a.covariance(T, &ca));
  ASSERT_TRUE(b.covariance(T2, &cb));
  EXPECT_NEAR(a.chi2(), b.chi2(), 1e-9 * a.chi2());
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      const double s = (r < 3 ? 2.0 : 1.0) * (c < 3 ? 2.0 : 1.0);
      const double v = ca[size_t(6 * r + c)];
      EXPECT_NEAR(cb[size_t(6 * r + c)], s * v, 1e-7 * std::abs(ca[size_t(6 * r + r)]) + 1e-15)
          << r << "," << c;
    }
  }
}

TEST(PoseCovariance, FewerThanFourPointsOrNoConstraintGiveNone) {
  const PinholeIntrinsics K{500.0, 500.0, 320.0, 240.0};
  const Pose T;
  std::array<double, 36> out;
  out.fill(-1.0);
  PoseInformation three;
  for (int i = 0; i < 3; ++i) {
    three.add(K, T, Eigen::Vector3d(0.1 * i, -0.1 * i, 3.0), Eigen::Vector2d(330, 240), 1.0);
  }
  EXPECT_EQ(three.count(), 3);
  EXPECT_FALSE(three.covariance(T, &out));
  PoseInformation same;  // one point repeated: rank 2, no pose
  for (int i = 0; i < 10; ++i) {
    same.add(K, T, Eigen::Vector3d(0.2, 0.1, 3.0), Eigen::Vector2d(353.7, 256.4), 1.0);
  }
  EXPECT_FALSE(same.covariance(T, &out));
  PoseInformation behind;  // points behind the camera are not counted
  behind.add(K, T, Eigen::Vector3d(0.0, 0.0, -2.0), Eigen::Vector2d(320, 240), 1.0);
  EXPECT_EQ(behind.count(), 0);
  for (double v : out) EXPECT_EQ(v, -1.0);  // untouched
}

}  // namespace
}  // namespace rdslam
