#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <random>

#include "core/change_detection.h"
#include "tests/support/appearance_reference.h"

using namespace rdslam;

namespace {

// A textured BGR image: smoothed uniform noise, deterministic.
cv::Mat textured(int w, int h, uint64_t seed) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  return img;
}

NeighbourPoint neighbour(double depth, Eigen::Vector2d y_p) {
  NeighbourPoint n;
  n.pixel = {0, 0};
  n.depth_current = depth;
  n.pixel_in_first_keyframe = y_p;
  n.in_first_keyframe = true;
  return n;
}

}  // namespace

TEST(ColorHistogram, ChannelsAreL2Normalised) {
  ColorHistogram h;
  compute_color_histogram(textured(160, 120, 1), 1, h);
  ASSERT_TRUE(h.valid);
  for (int c = 0; c < 3; ++c) {
    double ss = 0;
    for (int i = 0; i < 256; ++i) ss += double(h.bins[c * 256 + i]) * h.bins[c * 256 + i];
    EXPECT_NEAR(ss, 1.0, 1e-5);
  }
}

TEST(ColorHistogram, SameImageZeroChangedRegionAboveThreshold) {
  cv::Mat a = textured(320, 240, 2);
  cv::Mat b = a.clone();
  ColorHistogram ha, hb;
  compute_color_histogram(a, 2, ha);
  compute_color_histogram(b, 2, hb);
  EXPECT_NEAR(histogram_difference(ha, hb), 0.0, 1e-9);
  // A red object covering a third of the view changes all three channels' histograms.
  cv::rectangle(b, cv::Rect(0, 0, 160, 160), cv::Scalar(20, 30, 230), cv::FILLED);
  compute_color_histogram(b, 2, hb);
  EXPECT_GT(histogram_difference(ha, hb), 1.0);
}

TEST(SelectClosestKeyframes, FiltersByViewAngleThenRanksByDistance) {
  const Eigen::Vector3d z(0, 0, 1);
  const Eigen::Vector3d side = Eigen::Vector3d(1, 0, 1).normalized();  // 45 deg away
  Eigen::Vector3d axes[7] = {z, z, side, z, z, z, z};
  Eigen::Vector3d centres[7] = {{5, 0, 0}, {1, 0, 0}, {0.1, 0, 0}, {3, 0, 0},
                                {2, 0, 0}, {4, 0, 0}, {6, 0, 0}};
  int out[5];
  const int n =
      select_closest_keyframes(z, Eigen::Vector3d::Zero(), axes, centres, 7, 30.0, 5, out, 5);
  ASSERT_EQ(n, 5);
  const int expected[5] = {1, 4, 3, 5, 0};  // keyframe 2 is nearest but looks 45 deg away
  for (int i = 0; i < 5; ++i) EXPECT_EQ(out[i], expected[i]) << i;
}

TEST(AppearanceDifference, ZeroForSamePatchAndFindsShiftWithinSearch) {
  cv::Mat a = textured(200, 200, 3);
  const Eigen::Vector2d x(100, 100);
  EXPECT_NEAR(appearance_difference(a, x, a, x, 1.0, 11, 0), 0.0, 1e-9);
  // The current image is the keyframe shifted by (2, -1) px; the projection is off by that.
  cv::Mat shifted;
  const cv::Matx23d M(1, 0, 2, 0, 1, -1);
  cv::warpAffine(a, shifted, M, a.size());
  EXPECT_GT(appearance_difference(a, x, shifted, x, 1.0, 11, 0), 5.0);
  EXPECT_NEAR(appearance_difference(a, x, shifted, x, 1.0, 11, 2), 0.0, 1e-6);
}

TEST(AppearanceDifference, ScaleMapsTheWindowAtTheEstimatedDepth) {
  cv::Mat a = textured(200, 200, 4);
  cv::Mat big;
  cv::resize(a, big, cv::Size(), 2.0, 2.0, cv::INTER_LINEAR);
  const Eigen::Vector2d x(100, 100);
  // Pixel (u, v) of `a` sits at (2u + 0.5, 2v + 0.5) in `big` (pixel-centre convention).
  const Eigen::Vector2d xp(200.5, 200.5);
  const double same = appearance_difference(a, x, big, xp, 2.0, 11, 0);
  const double unscaled = appearance_difference(a, x, big, xp, 1.0, 11, 0);
  EXPECT_LT(same, 4.0);
  EXPECT_GT(unscaled, 2.0 * same);
}

TEST(AppearanceDifference, OutsideTheImageIsNotChecked) {
  cv::Mat a = textured(100, 100, 5);
  EXPECT_TRUE(std::isinf(appearance_difference(a, {2, 50}, a, {50, 50}, 1.0, 11, 2)));
  EXPECT_TRUE(std::isinf(appearance_difference(a, {50, 50}, a, {97, 50}, 1.0, 11, 2)));
}

// The paper's Algorithm 1 (temporal_check off: no evidence about what replaced X).
class Algorithm1 : public ::testing::Test {
 protected:
  Algorithm1() { p.temporal_check = false; }
  ChangeDetectionParams p;
  const Eigen::Vector3d n{0, 0, -1};
  const Eigen::Vector2d x_p{100, 100};
  const double depth_x = 4.0;
  const double changed = 100.0;  // D_c above tau_c
};

TEST_F(Algorithm1, LargeViewChangeKeepsThePoint) {
  const Eigen::Vector3d n2 = Eigen::Vector3d(std::sin(0.6), 0, -std::cos(0.6));  // 34 deg
  EXPECT_EQ(update_point_validity(p, n, n2, changed, depth_x, x_p, nullptr, 0),
            PointDecision::kKeepViewAngle);
  const Eigen::Vector3d n3 = Eigen::Vector3d(std::sin(0.4), 0, -std::cos(0.4));  // 23 deg
  EXPECT_EQ(update_point_validity(p, n, n3, changed, depth_x, x_p, nullptr, 0),
            PointDecision::kKeepOccludedMoving);
}

TEST_F(Algorithm1, SameAppearanceKeeps) {
  EXPECT_EQ(update_point_validity(p, n, n, p.tau_c - 1, depth_x, x_p, nullptr, 0),
            PointDecision::kKeepSameAppearance);
}

TEST_F(Algorithm1, NoTrackedNeighboursMeansAMovingOccluderAndKeeps) {
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, nullptr, 0),
            PointDecision::kKeepOccludedMoving);
}

TEST_F(Algorithm1, AllNeighboursBehindInvalidates) {
  NeighbourPoint ys[2] = {neighbour(4.0, {300, 300}), neighbour(6.0, {10, 10})};
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2),
            PointDecision::kInvalidNothingInFront);
}

TEST_F(Algorithm1, NearerNeighbourCloseInFirstKeyframeInvalidates) {
  NeighbourPoint ys[2] = {neighbour(6.0, {300, 300}), neighbour(2.0, {110, 105})};
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2),
            PointDecision::kInvalidSameObject);
}

TEST_F(Algorithm1, NearerNeighbourFarInFirstKeyframeIsAStaticOccluderAndKeeps) {
  NeighbourPoint ys[2] = {neighbour(6.0, {101, 101}), neighbour(2.0, {160, 100})};
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2),
            PointDecision::kKeepOccludedStatic);
}

TEST_F(Algorithm1, WithoutOcclusionHandlingAnyAppearanceChangeInvalidates) {
  p.occlusion_handling = false;
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, nullptr, 0),
            PointDecision::kInvalidNoOcclusionHandling);
  EXPECT_TRUE(is_invalidation(PointDecision::kInvalidNoOcclusionHandling));
  EXPECT_FALSE(is_invalidation(PointDecision::kKeepOccludedMoving));
}

// The temporal check's evidence (NewSurface) on top of Algorithm 1, default parameters.
TEST_F(Algorithm1, MovingNewAppearanceKeepsWhateverTheNeighboursSay) {
  p = ChangeDetectionParams();
  NeighbourPoint ys[2] = {neighbour(4.0, {300, 300}), neighbour(6.0, {10, 10})};
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2, NewSurface::kMoving),
            PointDecision::kKeepOccludedMoving);
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2, NewSurface::kInFront),
            PointDecision::kKeepOccludedStatic);
}

TEST_F(Algorithm1, StaticSurfaceBehindWithNothingTrackedInvalidates) {
  p = ChangeDetectionParams();
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, nullptr, 0, NewSurface::kBehind),
            PointDecision::kInvalidStaticChange);
  EXPECT_TRUE(is_invalidation(PointDecision::kInvalidStaticChange));
  // Without that evidence the paper's verdict stands: a moving occluder.
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, nullptr, 0, NewSurface::kUnknown),
            PointDecision::kKeepOccludedMoving);
}

TEST_F(Algorithm1, RequireStaticEvidenceGatesTheNeighbourVerdicts) {
  p = ChangeDetectionParams();
  ASSERT_TRUE(p.require_static_evidence);
  NeighbourPoint ys[2] = {neighbour(4.0, {300, 300}), neighbour(6.0, {10, 10})};
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2, NewSurface::kUnknown),
            PointDecision::kKeepUndecided);
  EXPECT_FALSE(is_invalidation(PointDecision::kKeepUndecided));
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2, NewSurface::kBehind),
            PointDecision::kInvalidNothingInFront);
  p.require_static_evidence = false;  // Alg. 1 decides where the check cannot
  EXPECT_EQ(update_point_validity(p, n, n, changed, depth_x, x_p, ys, 2, NewSurface::kUnknown),
            PointDecision::kInvalidNothingInFront);
}

TEST(LandmarkCounters, MissAndMovedThresholdsAsInTheSecondPaper) {
  LandmarkCounters c;
  for (int i = 0; i < 10; ++i)
    EXPECT_FALSE(update_landmark_counters(c, LandmarkEvent::kMissed, 10, 5));
  EXPECT_TRUE(update_landmark_counters(c, LandmarkEvent::kMissed, 10, 5));
  LandmarkCounters d;
  for (int i = 0; i < 5; ++i)
    EXPECT_FALSE(update_landmark_counters(d, LandmarkEvent::kMatchedMoved, 10, 5));
  EXPECT_FALSE(update_landmark_counters(d, LandmarkEvent::kMatchedStill, 10, 5));
  EXPECT_EQ(d.moved, 0);
  EXPECT_EQ(d.missed, 0);
}

TEST(Stationary, SmallMotionIsStationary) {
  ChangeDetectionParams p;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  EXPECT_TRUE(camera_is_stationary(p, I, {0, 0, 0}, I, {0.001, 0, 0}));
  EXPECT_FALSE(camera_is_stationary(p, I, {0, 0, 0}, I, {0.01, 0, 0}));
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.0 * M_PI / 180, Eigen::Vector3d::UnitY()).matrix();
  EXPECT_FALSE(camera_is_stationary(p, I, {0, 0, 0}, R, {0, 0, 0}));
}

TEST(FlowRejection, RejectsPointsOnAMovingBlockOnly) {
  // A textured block moves 3 px to the right over a static textured background.
  cv::Mat bg = textured(160, 120, 6), obj = textured(40, 40, 7);
  cv::Mat f0 = bg.clone(), f1 = bg.clone();
  obj.copyTo(f0(cv::Rect(50, 40, 40, 40)));
  obj.copyTo(f1(cv::Rect(53, 40, 40, 40)));
  cv::Mat g0, g1, flow;
  cv::cvtColor(f0, g0, cv::COLOR_BGR2GRAY);
  cv::cvtColor(f1, g1, cv::COLOR_BGR2GRAY);
  cv::calcOpticalFlowFarneback(g0, g1, flow, 0.5, 3, 15, 3, 5, 1.2, 0);
  const float xs[3] = {70, 20, 140}, ys[3] = {60, 20, 100};
  uint8_t keep[3] = {1, 1, 1};
  EXPECT_EQ(reject_by_flow(flow, xs, ys, 3, 1.0, keep), 1);
  EXPECT_EQ(keep[0], 0);
  EXPECT_EQ(keep[1], 1);
  EXPECT_EQ(keep[2], 1);
}

// The optimised appearance_difference() (precomputed weights, separable sampling, shifts
// scored together) against its definition, the plain loops kept verbatim in
// tests/support/appearance_reference.h: random grey and BGR images, plain and normalised
// scores, scale and general warps, sub-pixel x, every search_d 0..8 (and the invalid -1, 9),
// with and without `accept`, windows near the borders. The current image is mostly the
// keyframe warped by the same A and shifted by an integer d0 within the search (so the
// minimum and `accept` fall on every ring), else an unrelated texture, a lighting change or a
// flat image. Equal to float rounding (relative 1e-5, the same infinities); on x86-64 they
// are the same doubles.
TEST(AppearanceDifference, OptimisedMatchesTheReferenceDefinition) {
  std::mt19937 rng(20261204);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto pick = [&](int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  int finite = 0, identical = 0, accepted = 0, general = 0, coloured = 0;
  int finite_by_d[9] = {};
  for (int i = 0; i < 1500; ++i) {
    SCOPED_TRACE(i);
    const int ch = pick(0, 1) ? 3 : 1;
    const int cols = pick(50, 160), rows = pick(50, 130);
    cv::Mat kf(rows, cols, CV_8UC(ch));
    cv::randu(kf, 0, 256);
    const int blur = 2 * pick(0, 3) + 1;
    cv::GaussianBlur(kf, kf, cv::Size(blur, blur), 0);
    // Window: mostly the default 11, else any size up to the maximum (even ones too).
    const int window = pick(0, 2) ? 11 : pick(1, kMaxAppearanceWindow);
    const int D = pick(0, 40) == 0 ? (pick(0, 1) ? -1 : 9) : pick(0, 8);
    // Warp: scale I (most), a diagonal with two scales (some with a 180 deg turn), or general.
    Eigen::Matrix2d A;
    const int kind = pick(0, 9);
    if (kind < 5) {
      A = uni(0.5, 2.0) * Eigen::Matrix2d::Identity();
    } else if (kind < 7) {
      A << uni(0.6, 1.6), 0, 0, uni(0.6, 1.6);
      if (kind == 6 && pick(0, 1)) A = -A;
    } else {
      A = Eigen::Rotation2Dd(uni(-0.3, 0.3)).toRotationMatrix() * uni(0.7, 1.4);
      A(0, 1) += uni(-0.2, 0.2);
      A(1, 0) += uni(-0.2, 0.2);
    }
    const bool is_general = A(0, 1) != 0 || A(1, 0) != 0;
    // x, x': sub-pixel; one case in four anywhere (windows near and over the borders), else
    // where the window and the search fit more often than not.
    const int ccols = pick(50, 160), crows = pick(50, 130);
    auto point = [&](int w, int h) {
      const double m = pick(0, 3) ? window / 2 + std::max(D, 0) + 2.0 : -2.0;
      return Eigen::Vector2d(uni(m, w - 1 - m), uni(m, h - 1 - m));
    };
    const Eigen::Vector2d x = point(cols, rows), xp = point(ccols, crows);
    cv::Mat cur;
    const int content = pick(0, 9);
    if (content < 6) {
      // The keyframe seen through A, shifted by d0: cur(p') = kf(x + d0 + A^-1 (p' - x')).
      const Eigen::Matrix2d Ai = A.inverse();
      const Eigen::Vector2d d0(pick(-std::max(D, 0), std::max(D, 0)),
                               pick(-std::max(D, 0), std::max(D, 0)));
      const Eigen::Vector2d t = x + d0 - Ai * xp;
      const cv::Matx23d M(Ai(0, 0), Ai(0, 1), t.x(), Ai(1, 0), Ai(1, 1), t.y());
      cv::warpAffine(kf, cur, M, cv::Size(ccols, crows), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                     cv::BORDER_REFLECT);
      if (content >= 4) cur.convertTo(cur, -1, uni(0.5, 1.8), uni(-40, 40));  // lighting
      if (content == 5) {                                                     // noise on top
        cv::Mat noise(cur.size(), cur.type());
        cv::randn(noise, 0, 6);
        cv::add(cur, noise, cur);
      }
    } else if (content < 9) {
      cur.create(crows, ccols, CV_8UC(ch));
      cv::randu(cur, 0, 256);
      cv::GaussianBlur(cur, cur, cv::Size(5, 5), 0);
    } else {
      cur = cv::Mat(crows, ccols, CV_8UC(ch), cv::Scalar::all(pick(0, 255)));
    }
    if (pick(0, 19) == 0) kf = cv::Scalar::all(pick(0, 255));  // a flat keyframe window
    const bool normalise = pick(0, 1);
    double accept = -kInf;
    const int a = pick(0, 9);
    if (a >= 4) accept = normalise ? uni(0, 1.2) : uni(0, 40);
    if (a == 3) accept = kInf;
    if (a == 2) accept = 0;

    double ref, opt;
    if (!is_general && A(0, 0) == A(1, 1) && A(0, 0) > 0 && pick(0, 1)) {
      ref = test::reference_appearance_difference(kf, x, cur, xp, A(0, 0), window, D, normalise,
                                                  accept);
      opt = appearance_difference(kf, x, cur, xp, A(0, 0), window, D, normalise, accept);
    } else {
      ref = test::reference_appearance_difference(kf, x, cur, xp, A, window, D, normalise, accept);
      opt = appearance_difference(kf, x, cur, xp, A, window, D, normalise, accept);
    }
    ASSERT_EQ(std::isinf(ref), std::isinf(opt)) << ref << " " << opt;
    ASSERT_FALSE(std::isnan(opt));
    if (std::isinf(ref)) continue;
    ASSERT_NEAR(opt, ref, 1e-5 * std::fabs(ref) + 1e-12);
    ++finite;
    identical += std::memcmp(&ref, &opt, sizeof ref) == 0;
    accepted += ref <= accept;
    general += is_general;
    coloured += ch == 3;
    if (D >= 0 && D <= 8) ++finite_by_d[D];
  }
  // The comparison covers what it claims to: many finite scores, early exits, general warps
  // and colour, and every search radius.
  EXPECT_GT(finite, 600);
  EXPECT_GT(accepted, 150);
  EXPECT_GT(general, 100);
  EXPECT_GT(coloured, 250);
  for (int d = 0; d <= 8; ++d) EXPECT_GT(finite_by_d[d], 20) << "search_d " << d;
  std::printf("finite %d (identical doubles %d), accepted %d, general warp %d, colour %d\n", finite,
              identical, accepted, general, coloured);
}

TEST(AppearanceDifference, NormalisedScoreIgnoresGainAndBiasButSeesATextureChange) {
  cv::Mat kf(120, 160, CV_8UC3);
  cv::RNG rng(3);
  rng.fill(kf, cv::RNG::UNIFORM, 40, 200);
  cv::GaussianBlur(kf, kf, cv::Size(5, 5), 1.2);
  const Eigen::Vector2d x(80, 60);
  cv::Mat lit;
  kf.convertTo(lit, -1, 1.5, -30.0);  // gain 1.5, bias -30 (no clipping: 30..270 -> clipped)
  const double same = appearance_difference(kf, x, lit, x, 1.0, 11, 2, true);
  EXPECT_LT(same, 0.15);
  // The plain SAD sees the lighting change as a large difference.
  EXPECT_GT(appearance_difference(kf, x, lit, x, 1.0, 11, 2, false), 25.0);
  // A flat window where the texture was: about 1 (the texture is gone).
  cv::Mat flat(120, 160, CV_8UC3, cv::Scalar(128, 128, 128));
  const double gone = appearance_difference(kf, x, flat, x, 1.0, 11, 2, true);
  EXPECT_GT(gone, 0.9);
  EXPECT_LT(gone, 1.1);
  // An unrelated texture of the same contrast: well above the default threshold.
  cv::Mat other(120, 160, CV_8UC3);
  cv::RNG rng2(11);
  rng2.fill(other, cv::RNG::UNIFORM, 40, 200);
  cv::GaussianBlur(other, other, cv::Size(5, 5), 1.2);
  EXPECT_GT(appearance_difference(kf, x, other, x, 1.0, 11, 2, true),
            ChangeDetectionParams{}.tau_c_relative);
  // A window without texture cannot be compared.
  EXPECT_TRUE(std::isinf(appearance_difference(flat, x, kf, x, 1.0, 11, 2, true)));
}
