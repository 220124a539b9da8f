// PARSAC (RDSLAM Sec. 5) and its baselines: bin sampling, the truncated prior, eq. (3)/(4)/(5),
// the termination criterion, determinism, no heap allocation in estimate(), and recovery of
// the camera motion (not the object's) on the paper's synthetic scene.
#include <gtest/gtest.h>

#include <atomic>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <set>
#include <vector>

#include "core/parsac.h"
#include "core/parsac_scene.h"

// ---- Counting global operator new: proves estimate() does not allocate. ----
// GCC sees malloc/free through the replaced operators after inlining and warns about a
// mismatch that is not one (both sides of every pair below use malloc/free).
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
}  // namespace

void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, std::align_val_t a) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  void* p = nullptr;
  if (posix_memalign(&p, static_cast<std::size_t>(a), n ? n : 1) == 0) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return operator new(n, a);
}
void operator delete(void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  std::free(p);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}

using namespace rdslam;

namespace {

ParsacParams params_for(const char* method, const char* solver, int iterations, int seed = 1) {
  ParsacParams p;
  p.method = method;
  p.solver = solver;
  p.max_iterations = iterations;
  p.seed = seed;
  return p;
}

const std::vector<ParsacFrame>& scene() {
  static const std::vector<ParsacFrame> frames = [] {
    ParsacSceneParams sp;
    sp.frames = 12;
    sp.seed = 3;
    return make_parsac_scene(sp);
  }();
  return frames;
}

struct SampleLog {
  const RobustPoseEstimator* est = nullptr;
  const std::vector<Eigen::Vector2d>* px = nullptr;
  long samples = 0;
  long violations = 0;
  std::vector<long> first_bin_counts;
};

void log_sample(void* ctx, const int* idx, int m) {
  auto* log = static_cast<SampleLog*>(ctx);
  ++log->samples;
  std::set<int> bins;
  for (int k = 0; k < m; ++k) {
    const Eigen::Vector2d& x = (*log->px)[idx[k]];
    bins.insert(log->est->bin_of(x.x(), x.y()));
  }
  if (static_cast<int>(bins.size()) != m) ++log->violations;
  const Eigen::Vector2d& x0 = (*log->px)[idx[0]];
  ++log->first_bin_counts[log->est->bin_of(x0.x(), x0.y())];
}

}  // namespace

TEST(Parsac, AtMostOnePointPerBinInEverySample) {
  const auto& f = scene()[0];
  for (const char* method : {"parsac", "arsac"}) {
    for (const char* solver : {"dlt6", "p3p"}) {
      RobustPoseEstimator est(params_for(method, solver, 300), parsac_scene_camera(), 2000);
      SampleLog log;
      log.est = &est;
      log.px = &f.pixels;
      log.first_bin_counts.assign(est.bin_count(), 0);
      est.set_sample_observer(log_sample, &log);
      PoseEstimate r;
      est.estimate(f.pixels.data(), f.p_world.data(), static_cast<int>(f.pixels.size()), nullptr,
                   nullptr, &r);
      EXPECT_GT(log.samples, 50) << method << " " << solver;
      EXPECT_EQ(log.violations, 0) << method << " " << solver;
    }
  }
}

TEST(Parsac, RansacSamplesAreDistinctPointsButMayShareBins) {
  const auto& f = scene()[0];
  RobustPoseEstimator est(params_for("ransac", "dlt6", 2000), parsac_scene_camera(), 2000);
  SampleLog log;
  log.est = &est;
  log.px = &f.pixels;
  log.first_bin_counts.assign(est.bin_count(), 0);
  est.set_sample_observer(log_sample, &log);
  PoseEstimate r;
  est.estimate(f.pixels.data(), f.p_world.data(), static_cast<int>(f.pixels.size()), nullptr,
               nullptr, &r);
  // With 6 of ~1000 points in 100 bins, shared bins happen in a sizeable share of samples:
  // this shows the bin test above is able to fail.
  EXPECT_GT(log.violations, log.samples / 20);
}

TEST(Parsac, PriorIsTruncatedInlierRatioAndDrivesBinProbabilities) {
  const auto& frames = scene();
  ParsacParams many = params_for("parsac", "p3p", 20000);
  many.min_iterations = 20000;  // many samples for the goodness-of-fit test below
  RobustPoseEstimator est(many, parsac_scene_camera(), 2000);
  for (int b = 0; b < est.bin_count(); ++b) EXPECT_EQ(est.bin_prior()[b], 1.0);
  // Frame 0: the prior becomes each bin's inlier ratio truncated to [0.2, 1].
  const auto& f0 = frames[0];
  const int n0 = static_cast<int>(f0.pixels.size());
  std::vector<uint8_t> mask(n0);
  PoseEstimate r;
  ASSERT_EQ(est.estimate(f0.pixels.data(), f0.p_world.data(), n0, nullptr, mask.data(), &r),
            PoseStatus::kOk);
  std::vector<int> in(est.bin_count(), 0), all(est.bin_count(), 0);
  for (int i = 0; i < n0; ++i) {
    const int b = est.bin_of(f0.pixels[i].x(), f0.pixels[i].y());
    ++all[b];
    in[b] += mask[i];
  }
  int clamped_low = 0;
  for (int b = 0; b < est.bin_count(); ++b) {
    if (all[b] == 0) continue;
    const double ratio = static_cast<double>(in[b]) / all[b];
    EXPECT_NEAR(est.bin_prior()[b], std::min(1.0, std::max(0.2, ratio)), 1e-12) << "bin " << b;
    clamped_low += ratio < 0.2;
  }
  EXPECT_GT(clamped_low, 0);  // the truncation was exercised
  // Frame 1: p_i = eps*_i / sum_j eps*_j over occupied bins, and the sampler follows it (the
  // first point of each sample is an unconditioned draw from p).
  const std::vector<double> prior(est.bin_prior(), est.bin_prior() + est.bin_count());
  const auto& f1 = frames[1];
  SampleLog log;
  log.est = &est;
  log.px = &f1.pixels;
  log.first_bin_counts.assign(est.bin_count(), 0);
  est.set_sample_observer(log_sample, &log);
  est.estimate(f1.pixels.data(), f1.p_world.data(), static_cast<int>(f1.pixels.size()), nullptr,
               nullptr, &r);
  std::vector<uint8_t> occ(est.bin_count(), 0);
  for (const auto& x : f1.pixels) occ[est.bin_of(x.x(), x.y())] = 1;
  std::vector<double> expected(est.bin_count());
  truncated_prior_probabilities(prior.data(), occ.data(), est.bin_count(), 0.2, 1.0,
                                expected.data());
  ASSERT_GE(log.samples, 20000);
  double chi2 = 0.0, pmin = 1.0, pmax = 0.0;
  int dof = 0;
  for (int b = 0; b < est.bin_count(); ++b) {
    EXPECT_NEAR(est.last_bin_probabilities()[b], expected[b], 1e-12);
    if (expected[b] > 0) {
      const double e = expected[b] * log.samples;
      chi2 += (log.first_bin_counts[b] - e) * (log.first_bin_counts[b] - e) / e;
      ++dof;
      pmin = std::min(pmin, expected[b]);
      pmax = std::max(pmax, expected[b]);
    } else {
      EXPECT_EQ(log.first_bin_counts[b], 0);
    }
  }
  // Chi-square goodness of fit: mean dof, sd sqrt(2 dof); 5 sd is far beyond chance.
  EXPECT_LT(chi2, dof + 5.0 * std::sqrt(2.0 * dof)) << "dof " << dof;
  // The prior is far from uniform here, so the fit also tells PARSAC from ARSAC.
  EXPECT_GT(pmax, 2.0 * pmin);
}

TEST(Parsac, ResetPriorRestoresUniform) {
  const auto& f = scene()[0];
  RobustPoseEstimator est(params_for("parsac", "p3p", 300), parsac_scene_camera(), 2000);
  PoseEstimate r;
  est.estimate(f.pixels.data(), f.p_world.data(), static_cast<int>(f.pixels.size()), nullptr,
               nullptr, &r);
  bool changed = false;
  for (int b = 0; b < est.bin_count(); ++b) changed = changed || est.bin_prior()[b] != 1.0;
  EXPECT_TRUE(changed);
  est.reset_prior();
  for (int b = 0; b < est.bin_count(); ++b) EXPECT_EQ(est.bin_prior()[b], 1.0);
}

TEST(Parsac, Eq4EqualsEq3ForEqualWeights) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.0, 640.0);
  for (int n : {2, 3, 10, 57}) {
    std::vector<Eigen::Vector2d> x(n);
    for (auto& p : x) p = Eigen::Vector2d(U(rng), 0.75 * U(rng));
    const Eigen::Matrix2d C3 = sample_covariance(x.data(), n);
    for (double w : {1.0 / n, 0.37, 1.0}) {  // eq. (4) is invariant to a common scale
      std::vector<double> eps(n, w);
      Eigen::Matrix2d C4;
      ASSERT_TRUE(weighted_covariance(x.data(), eps.data(), n, &C4));
      EXPECT_LT((C4 - C3).norm(), 1e-9 * C3.norm()) << "n=" << n << " w=" << w;
    }
  }
}

TEST(Parsac, Eq4WeightsMatterAndZeroWeightsAreIgnored) {
  std::vector<Eigen::Vector2d> x = {{0, 0}, {100, 0}, {0, 100}, {500, 400}};
  std::vector<double> w = {1.0, 1.0, 1.0, 0.0};
  Eigen::Matrix2d C4;
  ASSERT_TRUE(weighted_covariance(x.data(), w.data(), 4, &C4));
  const Eigen::Matrix2d C3 = sample_covariance(x.data(), 3);
  EXPECT_LT((C4 - C3).norm(), 1e-9);
  w[3] = 0.5;
  ASSERT_TRUE(weighted_covariance(x.data(), w.data(), 4, &C4));
  EXPECT_GT((C4 - C3).norm(), 1.0);
  // A single weighted bin has no covariance.
  std::vector<double> one = {0.0, 0.7, 0.0, 0.0};
  EXPECT_FALSE(weighted_covariance(x.data(), one.data(), 4, &C4));
}

TEST(Parsac, ScoreIsEq5) {
  Eigen::Matrix2d C;
  C << 640.0 * 640.0 / 12.0, 0.0, 0.0, 480.0 * 480.0 / 12.0;  // uniform over the image
  EXPECT_NEAR(parsac_score(24.0, C, 640.0 * 480.0), 24.0 * M_PI / 12.0, 1e-12);
}

TEST(Parsac, TerminationCountMatchesFormula) {
  for (double q : {0.05, 0.2, 0.31, 0.5, 0.9}) {
    for (int m : {4, 6}) {
      for (double eta : {0.01, 0.05}) {
        const int K = required_iterations(q, m, eta);
        const double fail = 1.0 - std::pow(q, m);
        EXPECT_LT(std::pow(fail, K), eta) << q << " " << m << " " << eta;
        if (K > 1) {
          EXPECT_GE(std::pow(fail, K - 1), eta) << q << " " << m << " " << eta;
        }
        EXPECT_NEAR(K, std::ceil(std::log(eta) / std::log(fail)), 1.0);
      }
    }
  }
  EXPECT_EQ(required_iterations(1.0, 6, 0.01), 1);
  EXPECT_EQ(required_iterations(0.0, 6, 0.01), INT_MAX);
}

TEST(Parsac, EstimatorStopsAtTheFormulasCount) {
  // A clean scene with 60% inliers spread everywhere: adaptive termination ends the loop.
  const auto& f = scene()[2];
  std::vector<Eigen::Vector2d> px;
  std::vector<Eigen::Vector3d> pw;
  for (size_t i = 0; i < f.pixels.size(); ++i) {
    if (f.label[i] == 0 || (f.label[i] == 2 && i % 4 == 0)) {
      px.push_back(f.pixels[i]);
      pw.push_back(f.p_world[i]);
    }
  }
  const int n = static_cast<int>(px.size());
  for (const char* method : {"parsac", "arsac", "ransac"}) {
    RobustPoseEstimator est(params_for(method, "p3p", 100000), parsac_scene_camera(), 2000);
    PoseEstimate r;
    ASSERT_EQ(est.estimate(px.data(), pw.data(), n, nullptr, nullptr, &r), PoseStatus::kOk);
    // q recomputed from the exposed p_i and eps^_i (bin samplers) or the inlier count.
    ASSERT_LT(r.iterations, 100000);
    EXPECT_EQ(r.iterations, std::max(r.best_iteration, r.required_iterations)) << method;
    if (std::string(method) != "ransac") {
      double q = 0.0;
      for (int b = 0; b < est.bin_count(); ++b) {
        q += est.last_bin_probabilities()[b] * est.last_best_bin_inlier_ratio()[b];
      }
      EXPECT_EQ(r.required_iterations, required_iterations(q, 4, 0.01)) << method;
    }
  }
}

TEST(Parsac, DeterministicForASeed) {
  const auto& frames = scene();
  for (const char* method : {"parsac", "arsac", "ransac", "lo-ransac"}) {
    RobustPoseEstimator a(params_for(method, "dlt6", 400, 42), parsac_scene_camera(), 2000);
    RobustPoseEstimator b(params_for(method, "dlt6", 400, 42), parsac_scene_camera(), 2000);
    for (int t = 0; t < 4; ++t) {
      const auto& f = frames[t];
      const int n = static_cast<int>(f.pixels.size());
      std::vector<uint8_t> ma(n), mb(n);
      PoseEstimate ra, rb;
      a.estimate(f.pixels.data(), f.p_world.data(), n, nullptr, ma.data(), &ra);
      b.estimate(f.pixels.data(), f.p_world.data(), n, nullptr, mb.data(), &rb);
      EXPECT_EQ(ra.status, rb.status);
      EXPECT_EQ(ra.iterations, rb.iterations);
      EXPECT_EQ(ra.best_iteration, rb.best_iteration);
      EXPECT_EQ(ra.inlier_count, rb.inlier_count);
      EXPECT_TRUE(ra.T_cam_world.matrix() == rb.T_cam_world.matrix()) << method << " frame " << t;
      EXPECT_EQ(ma, mb);
    }
  }
}

TEST(Parsac, NoHeapAllocationInEstimate) {
  const auto& frames = scene();
  for (const char* method : {"parsac", "arsac", "ransac", "lo-ransac"}) {
    for (const char* solver : {"dlt6", "p3p"}) {
      RobustPoseEstimator est(params_for(method, solver, 300), parsac_scene_camera(), 2000);
      std::vector<uint8_t> mask(2000);
      const Eigen::Isometry3d guess = frames[0].T_cam_world;
      PoseEstimate r;
      long allocs = 0;
      for (int t = 0; t < 3; ++t) {
        const auto& f = frames[t];
        const int n = static_cast<int>(f.pixels.size());
        g_allocations = 0;
        g_counting = true;
        est.estimate(f.pixels.data(), f.p_world.data(), n, t == 1 ? &guess : nullptr, mask.data(),
                     &r);
        g_counting = false;
        allocs += g_allocations.load();
      }
      EXPECT_EQ(allocs, 0) << method << " " << solver;
    }
  }
  // The counter works: a vector allocation is seen.
  g_allocations = 0;
  g_counting = true;
  std::vector<int>* v = new std::vector<int>(10);
  g_counting = false;
  delete v;
  EXPECT_GE(g_allocations.load(), 2);
}

TEST(Parsac, FindsTheCameraMotionNotTheObject) {
  // 20% camera inliers, 30% on one rigid object: RANSAC prefers the object, PARSAC's
  // distribution-aware score keeps the camera (Sec. 5).
  const auto& frames = scene();
  const CameraModel cam = parsac_scene_camera();
  RobustPoseEstimator parsac(params_for("parsac", "p3p", 500), cam, 2000);
  RobustPoseEstimator ransac(params_for("ransac", "p3p", 5000), cam, 2000);
  int ok_parsac = 0, object_ransac = 0;
  for (const auto& f : frames) {
    const int n = static_cast<int>(f.pixels.size());
    PoseEstimate r;
    parsac.estimate(f.pixels.data(), f.p_world.data(), n, nullptr, nullptr, &r);
    ok_parsac += r.status == PoseStatus::kOk &&
                 pose_matches(r.T_cam_world, f.T_cam_world, f.mean_static_depth_m);
    ransac.estimate(f.pixels.data(), f.p_world.data(), n, nullptr, nullptr, &r);
    object_ransac += r.status == PoseStatus::kOk &&
                     pose_matches(r.T_cam_world, f.T_object, f.mean_static_depth_m);
  }
  EXPECT_GE(ok_parsac, static_cast<int>(frames.size()) - 1);
  EXPECT_GE(object_ransac, static_cast<int>(frames.size()) / 2);
}

TEST(Parsac, InitialGuessIsScoredAndCanWinAlone) {
  const auto& f = scene()[5];
  const int n = static_cast<int>(f.pixels.size());
  ParsacParams p = params_for("parsac", "p3p", 1);
  RobustPoseEstimator est(p, parsac_scene_camera(), 2000);
  est.reseed(12345);
  PoseEstimate r;
  ASSERT_EQ(est.estimate(f.pixels.data(), f.p_world.data(), n, &f.T_cam_world, nullptr, &r),
            PoseStatus::kOk);
  EXPECT_TRUE(pose_matches(r.T_cam_world, f.T_cam_world, f.mean_static_depth_m));
  EXPECT_GE(r.inlier_count, 150);
}

TEST(Parsac, StatusesForBadInput) {
  const CameraModel cam = parsac_scene_camera();
  RobustPoseEstimator est(params_for("parsac", "dlt6", 100), cam, 10);
  std::vector<Eigen::Vector2d> px(20, Eigen::Vector2d(100, 100));
  std::vector<Eigen::Vector3d> pw(20, Eigen::Vector3d(0, 0, 5));
  PoseEstimate r;
  EXPECT_EQ(est.estimate(px.data(), pw.data(), 20, nullptr, nullptr, &r), PoseStatus::kBadInput);
  EXPECT_EQ(est.estimate(nullptr, pw.data(), 5, nullptr, nullptr, &r), PoseStatus::kBadInput);
  EXPECT_EQ(est.estimate(px.data(), pw.data(), 5, nullptr, nullptr, &r), PoseStatus::kTooFewPoints);
  // 10 points in one bin: a bin sampler cannot draw 6 distinct bins.
  EXPECT_EQ(est.estimate(px.data(), pw.data(), 10, nullptr, nullptr, &r),
            PoseStatus::kTooFewPoints);
  // Non-finite points are skipped rather than crashing; all-garbage input finds no model.
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int i = 0; i < 10; ++i) {
    px[i] = Eigen::Vector2d(640 * U(rng), 480 * U(rng));
    pw[i] = Eigen::Vector3d(U(rng), U(rng), 3 + U(rng));
  }
  px[3].x() = NAN;
  pw[4].z() = INFINITY;
  const PoseStatus s = est.estimate(px.data(), pw.data(), 10, nullptr, nullptr, &r);
  EXPECT_TRUE(s == PoseStatus::kNoModel || s == PoseStatus::kTooFewPoints) << to_string(s);
  EXPECT_EQ(est.estimate(px.data(), pw.data(), 0, nullptr, nullptr, &r), PoseStatus::kTooFewPoints);
}

TEST(Parsac, ParamsValidateAndConstructorRejectsBadValues) {
  ParsacParams p;
  EXPECT_EQ(p.validate(), "");
  p.prior_min = 0.5;
  p.prior_max = 0.4;
  EXPECT_NE(p.validate().find("parsac.prior_min"), std::string::npos);
  EXPECT_THROW(RobustPoseEstimator(p, parsac_scene_camera(), 10), std::invalid_argument);
  p = ParsacParams();
  p.method = "prosac";
  EXPECT_NE(p.validate().find("parsac.method"), std::string::npos);
  p = ParsacParams();
  p.min_iterations = p.max_iterations + 1;
  EXPECT_NE(p.validate().find("parsac.min_iterations"), std::string::npos);
  p = ParsacParams();
  p.bins_x = 1;
  p.bins_y = 3;  // 3 bins < m = 4 of p3p
  EXPECT_NE(p.validate().find("bins"), std::string::npos);
}
