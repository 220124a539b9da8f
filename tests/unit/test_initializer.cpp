// core/initializer: two-view initialization on synthetic correspondences. General and planar scenes
// initialize (essential matrix / homography chosen by the score) with the right motion and unit
// median depth; a static camera, a purely rotating camera and a fixed camera watching a moving
// object are refused, as is a pair above the motion gate whose parallax is below the pixel gate.
// The screening fit bounds the cost of a pair with mostly wrong matches without changing the result
// on a good pair. At large flow, the rotation consistency retry recovers a pair with many wrong
// matches, and the fast-motion check hands such pairs back to the owner (the tracker's deeper
// pyramid) before any fitting.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/initializer.h"

namespace rdslam {
namespace {

const PinholeIntrinsics kK{500, 500, 320, 240};

struct Scene {
  std::vector<Eigen::Vector3d> pts;
  std::vector<std::array<uint8_t, 32>> desc;
};

Scene make_scene(int n, bool planar, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-3, 3), z(4, 9);
  std::uniform_int_distribution<int> byte(0, 255);
  Scene s;
  for (int i = 0; i < n; ++i) {
    const double d = planar ? 6.0 : z(rng);
    s.pts.emplace_back(u(rng) * d / 6.0, u(rng) * d / 8.0, d);
    std::array<uint8_t, 32> b{};
    for (auto& c : b) c = static_cast<uint8_t>(byte(rng));
    s.desc.push_back(b);
  }
  return s;
}

// Features of the scene seen from T (T_cam_world); points in `moving` are shifted by `shift`.
Features observe(const Scene& s, const Pose& T, const std::vector<int>& moving = {},
                 const Eigen::Vector3d& shift = Eigen::Vector3d::Zero()) {
  Features f;
  const size_t n = s.pts.size();
  f.kps.resize(n);
  f.un.resize(n);
  f.scale.assign(n, 1.f);
  f.level.assign(n, 0);
  f.desc.create(static_cast<int>(n), 32, CV_8U);
  f.width = 640;
  f.height = 480;
  f.cell_px = 20;
  int k = 0;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d p = s.pts[i];
    if (std::find(moving.begin(), moving.end(), static_cast<int>(i)) != moving.end()) p += shift;
    const Eigen::Vector3d pc = T * p;
    if (pc.z() <= 0) continue;
    const Eigen::Vector2d x = kK.project(pc);
    if (x.x() < 0 || x.y() < 0 || x.x() >= 640 || x.y() >= 480) continue;
    f.kps[k].pt = cv::Point2f(float(x.x()), float(x.y()));
    f.un[k] = f.kps[k].pt;
    std::copy(s.desc[i].begin(), s.desc[i].end(), f.desc.ptr<uint8_t>(k));
    ++k;
  }
  f.count = k;
  f.build_grid();
  return f;
}

Pose pose_at(const Eigen::Vector3d& centre, double yaw) {
  Pose T;
  T.R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.t = -T.R * centre;
  return T;
}

InitStatus run(const Features& a, const Features& b, InitResult& out) {
  FeatureParams fp;
  Initializer init(InitializerParams{}, fp, kK, BundleAdjustmentParams{});
  init.add_frame(a, 0, out);
  return init.add_frame(b, 1, out);
}

TEST(Initializer, GeneralSceneUsesEssentialAndRecoversMotion) {
  const Scene s = make_scene(400, false, 1);
  const Pose T1 = pose_at({0.4, 0.02, 0.05}, 0.03);
  InitResult r;
  ASSERT_EQ(run(observe(s, Pose()), observe(s, T1), r), InitStatus::kOk);
  EXPECT_FALSE(r.homography);
  // Translation direction and rotation; scale is free (unit median depth).
  const Eigen::Vector3d dir = r.T1.centre().normalized();
  EXPECT_GT(dir.dot(T1.centre().normalized()), 0.995);
  EXPECT_LT(Eigen::AngleAxisd(r.T1.R * T1.R.transpose()).angle(), 0.003);
  std::vector<double> depth;
  for (const auto& p : r.points) depth.push_back(p.p_world.z());
  std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
  EXPECT_NEAR(depth[depth.size() / 2], 1.0, 1e-6);
  EXPECT_GE(r.points.size(), 200u);
}

TEST(Initializer, PlanarSceneUsesHomography) {
  const Scene s = make_scene(400, true, 2);
  const Pose T1 = pose_at({0.5, 0.0, 0.0}, 0.02);
  InitResult r;
  ASSERT_EQ(run(observe(s, Pose()), observe(s, T1), r), InitStatus::kOk);
  EXPECT_TRUE(r.homography);
  EXPECT_GT(r.T1.centre().normalized().dot(T1.centre().normalized()), 0.99);
}

// A camera that moves sideways while turning to keep the scene centre in view (an orbit, as
// the synthetic xyz scenes): little image flow, large parallax. It is below the motion gate,
// and initializes through the parallax bar of low-flow pairs; with that route off (the motion
// gate alone, as before) the same pair is refused, and a smaller step is refused on parallax.
TEST(Initializer, LookAtMotionWithLittleFlowInitializesOnParallax) {
  const Scene s = make_scene(400, false, 6);
  const auto look_at = [](double b) { return pose_at({b, 0.0, 0.0}, std::atan2(b, 6.5)); };
  const Features f0 = observe(s, Pose());
  const Pose T1 = look_at(0.3);
  FeatureParams fp;
  InitializerParams ip;
  InitResult r;
  Initializer init(ip, fp, kK, BundleAdjustmentParams{});
  init.add_frame(f0, 0, r);
  ASSERT_EQ(init.add_frame(observe(s, T1), 1, r), InitStatus::kOk);
  EXPECT_TRUE(init.last_attempt().low_flow);  // median flow below min_median_flow_frac
  EXPECT_LT(init.last_attempt().median_flow_px, ip.min_median_flow_frac * f0.width);
  EXPECT_GE(init.last_attempt().parallax_deg, ip.low_flow_parallax_deg);
  EXPECT_FALSE(r.homography);
  EXPECT_GT(r.T1.centre().normalized().dot(T1.centre().normalized()), 0.995);
  EXPECT_LT(Eigen::AngleAxisd(r.T1.R * T1.R.transpose()).angle(), 0.003);
  EXPECT_GE(r.points.size(), 200u);

  Initializer small(ip, fp, kK, BundleAdjustmentParams{});
  small.add_frame(f0, 0, r);
  EXPECT_NE(small.add_frame(observe(s, look_at(0.08)), 1, r), InitStatus::kOk);

  ip.low_flow_parallax_deg = 0.0;
  Initializer gated(ip, fp, kK, BundleAdjustmentParams{});
  gated.add_frame(f0, 0, r);
  EXPECT_EQ(gated.add_frame(observe(s, T1), 1, r), InitStatus::kLittleMotion);
}

// The parallax gate in pixels (min_parallax_px / fx radians; at this test's fx 500, the
// default 11 px is 1.26 deg): a sideways step above the motion gate whose median parallax is
// above min_parallax_deg (1 deg) but below 11 px is refused as low-parallax, and starts the
// map with the pixel gate off; a longer step passes both.
TEST(Initializer, PixelParallaxGateRefusesShortBaselineAboveTheMotionGate) {
  const Scene s = make_scene(400, false, 7);
  const Features f0 = observe(s, Pose());
  const Features short_step = observe(s, pose_at({0.13, 0.0, 0.0}, 0.0));
  FeatureParams fp;
  InitializerParams ip;
  ASSERT_GT(ip.min_parallax_px / kK.fx * 180.0 / M_PI, ip.min_parallax_deg);
  InitResult r;
  Initializer gated(ip, fp, kK, BundleAdjustmentParams{});
  gated.add_frame(f0, 0, r);
  EXPECT_EQ(gated.add_frame(short_step, 1, r), InitStatus::kLowParallax);
  EXPECT_FALSE(gated.last_attempt().low_flow);  // above the motion gate: the 1-degree bar
  const double p = gated.last_attempt().parallax_deg;
  EXPECT_GT(p, ip.min_parallax_deg);
  EXPECT_LT(p * M_PI / 180.0 * kK.fx, ip.min_parallax_px);

  ip.min_parallax_px = 0.0;
  Initializer degrees_only(ip, fp, kK, BundleAdjustmentParams{});
  degrees_only.add_frame(f0, 0, r);
  EXPECT_EQ(degrees_only.add_frame(short_step, 1, r), InitStatus::kOk);

  InitResult r2;
  EXPECT_EQ(run(f0, observe(s, pose_at({0.25, 0.0, 0.0}, 0.0)), r2), InitStatus::kOk);
  EXPECT_GE(r2.median_parallax_deg * M_PI / 180.0 * kK.fx, InitializerParams{}.min_parallax_px);
}

TEST(Initializer, RefusesStaticCamera) {
  const Scene s = make_scene(400, false, 3);
  InitResult r;
  EXPECT_EQ(run(observe(s, Pose()), observe(s, Pose()), r), InitStatus::kLittleMotion);
}

TEST(Initializer, RefusesPureRotation) {
  const Scene s = make_scene(400, false, 4);
  InitResult r;
  EXPECT_NE(run(observe(s, Pose()), observe(s, pose_at({0, 0, 0}, 0.06)), r), InitStatus::kOk);
}

TEST(Initializer, RefusesFixedCameraWithMovingObject) {
  const Scene s = make_scene(400, false, 5);
  std::vector<int> moving;
  for (int i = 0; i < 100; ++i) moving.push_back(i);  // a quarter of the points move rigidly
  InitResult r;
  EXPECT_NE(run(observe(s, Pose()), observe(s, Pose(), moving, {0.4, 0.1, 0.0}), r),
            InitStatus::kOk);
}

// The screening fit (ransac_screen_iterations) changes nothing on a good pair: the same
// motion to the bit as the full fit. A pair whose matches are mostly wrong (80% displaced by
// up to 60 px, as kitti06 `--every 3` after its first frame) is refused by the screen, before
// the full fit; without the screen the full fit refuses it too.
TEST(Initializer, ScreeningFitKeepsGoodPairsAndRefusesMostlyWrongMatches) {
  const Scene s = make_scene(400, false, 7);
  const Features f0 = observe(s, Pose());
  const Features f1 = observe(s, pose_at({0.4, 0.02, 0.05}, 0.03));
  FeatureParams fp;
  InitializerParams screened, full;
  full.ransac_screen_iterations = 0;
  ASSERT_GT(screened.ransac_screen_iterations, 0);
  ASSERT_LT(screened.ransac_screen_iterations, screened.ransac_max_iterations);
  const auto attempt = [&](const InitializerParams& ip, const Features& cur, InitResult& r,
                           InitAttempt& a) {
    Initializer init(ip, fp, kK, BundleAdjustmentParams{});
    init.add_frame(f0, 0, r);
    const InitStatus st = init.add_frame(cur, 1, r);
    a = init.last_attempt();
    return st;
  };
  InitResult rs, rf;
  InitAttempt as, af;
  ASSERT_EQ(attempt(screened, f1, rs, as), InitStatus::kOk);
  ASSERT_EQ(attempt(full, f1, rf, af), InitStatus::kOk);
  EXPECT_EQ(as.e_inliers, af.e_inliers);
  EXPECT_EQ(rs.points.size(), rf.points.size());
  EXPECT_TRUE(rs.T1.R == rf.T1.R);
  EXPECT_TRUE(rs.T1.t == rf.T1.t);

  Features bad = f1;
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> off(-60.f, 60.f);
  for (int i = 0; i < bad.count; ++i) {
    if (i % 5 == 0) continue;  // 20% stay right
    cv::Point2f& p = bad.kps[i].pt;
    p.x = std::clamp(p.x + off(rng), 0.f, 639.f);
    p.y = std::clamp(p.y + off(rng), 0.f, 479.f);
    bad.un[i] = p;
  }
  bad.build_grid();
  EXPECT_EQ(attempt(screened, bad, rs, as), InitStatus::kInconsistent);
  EXPECT_GT(as.matches, 300);
  EXPECT_LT(as.e_inliers, 0.5 * screened.min_inlier_fraction * as.matches);
  EXPECT_EQ(as.r_h, 0.0);  // refused before the homography was fitted
  EXPECT_NE(attempt(full, bad, rf, af), InitStatus::kOk);
  EXPECT_GT(af.e_inliers, 0);
}

// Rotation consistency (InitializerParams::rotation_bins): a pair at large flow with 50% wrong
// matches (displaced by up to 60 px, keypoint angles turned at random; the right matches keep
// their angle, a camera without roll) is refused as inconsistent without the retry; the retry
// keeps the matches in the fullest bins of the angle-change histogram and initializes with the
// true motion. Below `rotation_min_flow_frac` the retry does not run.
TEST(Initializer, RotationConsistencyRetryRecoversLargeFlowPairWithWrongMatches) {
  const Scene s = make_scene(400, false, 9);
  const Features f0 = observe(s, Pose());
  const Pose T1 = pose_at({0.4, 0.02, 0.05}, 0.03);
  Features f1 = observe(s, T1);
  std::mt19937 rng(10);
  std::uniform_real_distribution<float> off(-60.f, 60.f), turn(20.f, 340.f);
  for (int i = 0; i < f1.count; ++i) {
    if (i % 20 >= 10) continue;  // 50% stay right
    cv::Point2f& p = f1.kps[i].pt;
    p.x = std::clamp(p.x + off(rng), 0.f, 639.f);
    p.y = std::clamp(p.y + off(rng), 0.f, 479.f);
    f1.un[i] = p;
    f1.kps[i].angle = std::fmod(f0.kps[i].angle + turn(rng) + 360.f, 360.f);
  }
  f1.build_grid();
  FeatureParams fp;
  const auto attempt = [&](const InitializerParams& ip, InitResult& r, InitAttempt& a) {
    Initializer init(ip, fp, kK, BundleAdjustmentParams{});
    init.add_frame(f0, 0, r);
    const InitStatus st = init.add_frame(f1, 1, r);
    a = init.last_attempt();
    return st;
  };
  InitializerParams off_params;
  off_params.rotation_bins = 0;
  InitResult r;
  InitAttempt a;
  ASSERT_EQ(attempt(off_params, r, a), InitStatus::kInconsistent);
  EXPECT_GE(a.median_flow_px, InitializerParams{}.rotation_min_flow_frac * f0.width);
  EXPECT_EQ(a.rotation_removed, 0);

  ASSERT_EQ(attempt(InitializerParams{}, r, a), InitStatus::kOk);
  EXPECT_GT(a.rotation_removed, 100);
  EXPECT_GT(r.T1.centre().normalized().dot(T1.centre().normalized()), 0.995);
  EXPECT_LT(Eigen::AngleAxisd(r.T1.R * T1.R.transpose()).angle(), 0.003);

  InitializerParams high;
  high.rotation_min_flow_frac = 0.5;  // the pair's flow is below it: no retry
  EXPECT_EQ(attempt(high, r, a), InitStatus::kInconsistent);
  EXPECT_EQ(a.rotation_removed, 0);
}

// Fast motion (InitializerParams::fast_flow_frac): with the check on, a pair at that median
// flow or more is answered kFastMotion without any model fitting; the owner then repeats the
// attempt (the reference described anew, same age) with the check off, which gives the same
// result as a plain attempt. A pair below that flow is fitted as usual with the check on.
TEST(Initializer, FastMotionCheckDefersLargeFlowPairsToTheOwner) {
  const Scene s = make_scene(400, false, 11);
  const Features f0 = observe(s, Pose());
  const Features f1 = observe(s, pose_at({0.8, 0.02, 0.05}, 0.03));
  FeatureParams fp;
  const InitializerParams ip;
  InitResult r, plain;
  Initializer init(ip, fp, kK, BundleAdjustmentParams{});
  init.set_fast_motion_check(true);
  init.add_frame(f0, 0, r);
  ASSERT_EQ(init.add_frame(f1, 1, r), InitStatus::kFastMotion);
  EXPECT_GE(init.last_attempt().median_flow_px, ip.fast_flow_frac * f0.width);
  EXPECT_EQ(init.last_attempt().e_inliers, 0);  // not fitted
  init.set_fast_motion_check(false);
  ASSERT_EQ(init.retry_with_reference(f0, f1, 1, r), InitStatus::kOk);
  EXPECT_EQ(init.reference_age(), 1);
  ASSERT_EQ(run(f0, f1, plain), InitStatus::kOk);
  EXPECT_EQ(r.points.size(), plain.points.size());
  EXPECT_TRUE(r.T1.R == plain.T1.R);
  EXPECT_TRUE(r.T1.t == plain.T1.t);

  const Features slow = observe(s, pose_at({0.15, 0.01, 0.02}, 0.01));
  Initializer checked(ip, fp, kK, BundleAdjustmentParams{});
  checked.set_fast_motion_check(true);
  checked.add_frame(f0, 0, r);
  const InitStatus st = checked.add_frame(slow, 1, r);
  EXPECT_NE(st, InitStatus::kFastMotion);
  EXPECT_LT(checked.last_attempt().median_flow_px, ip.fast_flow_frac * f0.width);
  EXPECT_GT(checked.last_attempt().e_inliers, 0);  // fitted
}

}  // namespace
}  // namespace rdslam
