// Rotation-only pose pieces (core/pose_refine.h; issue 23 item 3): Kabsch on bearings, the
// robust 2-point rotation and eq. (1) over the rotation, on map points seen from a held
// centre mixed with points at infinity (bearings), with outliers and pixel noise.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>
#include <vector>

#include "core/pose_refine.h"

namespace rdslam {
namespace {

double angle_deg(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(A * B.transpose()).angle() * 180.0 / M_PI;
}

Eigen::Matrix3d rot(double yaw_deg, double pitch_deg, double roll_deg) {
  const double k = M_PI / 180.0;
  return (Eigen::AngleAxisd(yaw_deg * k, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(pitch_deg * k, Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(roll_deg * k, Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

struct Scene {
  std::vector<Eigen::Vector3d> d;  // world directions from the centre (point - centre, or bearing)
  std::vector<Eigen::Vector2d> x;  // observed ideal pixels
  std::vector<float> sigma;
  std::vector<uint8_t> outlier;
};

// n directions in view of R (half of them map points at 1-8 m, half unit bearings), pixel noise
// `noise_px`, a fraction `outliers` moved by 20-80 px.
Scene make_scene(const PinholeIntrinsics& K, const Eigen::Matrix3d& R, int n, double noise_px,
                 double outliers, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, noise_px);
  Scene s;
  while (static_cast<int>(s.d.size()) < n) {
    const Eigen::Vector2d px(u(rng) * 640, u(rng) * 480);
    const Eigen::Vector3d ray_cam = K.unproject(px.x(), px.y()).normalized();
    const bool bearing = s.d.size() % 2 == 0;
    const double depth = bearing ? 1.0 : 1.0 + 7.0 * u(rng);
    s.d.push_back(R.transpose() * ray_cam * depth);
    Eigen::Vector2d obs = px + Eigen::Vector2d(g(rng), g(rng));
    const bool out = u(rng) < outliers;
    if (out) {
      const double a = 2 * M_PI * u(rng), r = 20 + 60 * u(rng);
      obs += r * Eigen::Vector2d(std::cos(a), std::sin(a));
    }
    s.x.push_back(obs);
    s.sigma.push_back(1.0f);
    s.outlier.push_back(out);
  }
  return s;
}

const PinholeIntrinsics kK{525, 525, 319.5, 239.5};

TEST(RotationOnly, KabschRecoversRotationFromBearings) {
  const Eigen::Matrix3d R = rot(40, -10, 5);
  std::vector<Eigen::Vector3d> a, b;
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0, 1);
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d w = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    b.push_back(w);
    a.push_back(R * w);
  }
  EXPECT_LT(angle_deg(kabsch_rotation(a.data(), b.data(), 20), R), 1e-6);
  // Two non-parallel pairs determine it too (the robust estimator's minimal sample).
  EXPECT_LT(angle_deg(kabsch_rotation(a.data(), b.data(), 2), R), 1e-6);
  // Never a reflection.
  EXPECT_GT(kabsch_rotation(a.data(), b.data(), 2).determinant(), 0.0);
}

TEST(RotationOnly, RefineConvergesFromSeveralDegrees) {
  const Eigen::Matrix3d R = rot(-75, 8, -3);
  const Scene s = make_scene(kK, R, 120, 0.5, 0.0, 7);
  Eigen::Matrix3d Re = rot(-72, 6, -1);  // 3.6 degrees off
  std::vector<uint8_t> inl(s.d.size());
  const int n =
      refine_rotation(kK, s.d.data(), s.x.data(), s.sigma.data(), 120, Re, inl.data(), 5.991);
  EXPECT_GE(n, 110);  // 0.5 px noise in a 2.45 px gate: nearly all
  EXPECT_LT(angle_deg(Re, R), 0.02);
}

TEST(RotationOnly, RobustEstimateWithOutliersAndNoPrediction) {
  const Eigen::Matrix3d R = rot(160, -5, 2);
  const Scene s = make_scene(kK, R, 200, 0.7, 0.35, 11);
  Eigen::Matrix3d Re = Eigen::Matrix3d::Identity();  // useless prediction: 160 degrees off
  std::vector<uint8_t> inl(s.d.size());
  const int n = estimate_rotation(kK, s.d.data(), s.x.data(), s.sigma.data(), 200, Re, inl.data(),
                                  5.991, 64, 1);
  EXPECT_LT(angle_deg(Re, R), 0.03);
  int good = 0, wrong = 0, outliers = 0;
  for (size_t i = 0; i < inl.size(); ++i) {
    outliers += s.outlier[i];
    if (inl[i] && !s.outlier[i]) ++good;
    if (inl[i] && s.outlier[i]) ++wrong;
  }
  EXPECT_EQ(wrong, 0);                      // 20+ px displacements never pass 2.45 px
  EXPECT_GE(good, 0.9 * (200 - outliers));  // the clean ones do (noise 0.7 px)
  EXPECT_EQ(n, good + wrong);
  // Deterministic for a seed.
  Eigen::Matrix3d Re2 = Eigen::Matrix3d::Identity();
  std::vector<uint8_t> inl2(s.d.size());
  EXPECT_EQ(estimate_rotation(kK, s.d.data(), s.x.data(), s.sigma.data(), 200, Re2, inl2.data(),
                              5.991, 64, 1),
            n);
  EXPECT_TRUE(Re2.isApprox(Re, 0.0));
}

TEST(RotationOnly, TooFewDirectionsIsNoModel) {
  const Scene s = make_scene(kK, Eigen::Matrix3d::Identity(), 1, 0.0, 0.0, 2);
  Eigen::Matrix3d Re = rot(10, 0, 0);
  const Eigen::Matrix3d before = Re;
  uint8_t inl[1];
  EXPECT_EQ(estimate_rotation(kK, s.d.data(), s.x.data(), s.sigma.data(), 1, Re, inl, 5.991, 64, 1),
            0);
  EXPECT_TRUE(Re.isApprox(before, 0.0));
}

}  // namespace
}  // namespace rdslam
