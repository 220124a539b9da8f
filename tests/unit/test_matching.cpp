// core/matching: the one acceptance rule of every matcher, its per-purpose parameters and their
// validation, the one-to-one assignment, the pyramid-level prediction (issue 21); the epipolar
// candidate bins of the mapper's new-point search (issue 23 item 7).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/epipolar_bins.h"
#include "core/matching.h"
#include "firmware_app/config.h"

namespace rdslam {
namespace {

BestTwo best(double d1, double d2) {
  BestTwo b;
  b.offer(d1, 0);
  b.offer(d2, 1);
  return b;
}

TEST(Matching, RuleTestsDistanceAndRatioInclusive) {
  const MatchRule r{50, 0.8};
  EXPECT_TRUE(r.accepts(best(40, 50)));    // 40 <= 0.8 * 50, the boundary is accepted
  EXPECT_FALSE(r.accepts(best(41, 50)));   // ratio
  EXPECT_FALSE(r.accepts(best(51, 200)));  // distance
  EXPECT_TRUE(r.accepts(best(50, 200)));
  BestTwo one;
  one.offer(10, 3);  // a single candidate has no second nearest: the ratio test passes
  EXPECT_TRUE(r.accepts(one));
  EXPECT_FALSE(r.accepts(BestTwo{}));  // no candidate
  const MatchRule nearest_only{50, 1.0};
  EXPECT_TRUE(nearest_only.accepts(best(30, 30)));  // ratio 1: any nearest within the limit
}

TEST(Matching, BestTwoKeepsFirstOfEqualAndSkips) {
  Features f;
  f.desc = cv::Mat::zeros(4, 32, CV_8U);
  f.desc.at<uint8_t>(1, 0) = 0x01;  // distance 1 from zero
  f.desc.at<uint8_t>(2, 0) = 0x01;  // also 1: the first offered stays nearest
  f.desc.at<uint8_t>(3, 0) = 0x07;  // 3
  const uint8_t zero[32] = {};
  const int cand[] = {3, 1, 2};
  BestTwo b = best_of(zero, f, cand, 3, true);
  EXPECT_EQ(b.index, 1);
  EXPECT_EQ(b.d1, 1.0);
  EXPECT_EQ(b.d2, 1.0);
  b = best_of(zero, f, cand, 3, true, [](int j) { return j == 1; });
  EXPECT_EQ(b.index, 2);
  EXPECT_EQ(b.d2, 3.0);
  const BestTwo rows = best_of_rows(zero, f.desc, 4, true);
  EXPECT_EQ(rows.index, 0);
  EXPECT_EQ(rows.d1, 0.0);
  EXPECT_EQ(rows.d2, 1.0);
}

TEST(Matching, ClaimTableGivesEachTargetToItsClosestQuery) {
  ClaimTable t;
  t.reset(3, 2);
  t.offer(0, 1, 20.0);
  t.offer(1, 1, 10.0);  // closer: query 0 loses target 1
  t.offer(2, 1, 10.0);  // equal: the holder keeps it
  t.offer(2, 0, 5.0);
  EXPECT_EQ(t.target_of(0), -1);
  EXPECT_EQ(t.target_of(1), 1);
  EXPECT_EQ(t.target_of(2), 0);
  EXPECT_EQ(t.matched(), 2);
  t.reset(2, 2);
  EXPECT_EQ(t.matched(), 0);
}

TEST(Matching, PredictedLevelIsClampedScalePrediction) {
  const double log_sf = std::log(1.2);
  // A point first seen at level 0 from 1 m: max_dist = 1.2 m * 1.2^0; from 1 m it is at level 0.
  EXPECT_EQ(predict_level(1.2, 1.0, log_sf, 4), 0);
  // From 1/1.3 m it appears 1.3x larger: between levels 1 and 2, rounded up to 2.
  EXPECT_EQ(predict_level(1.2, 1.0 / 1.3, log_sf, 4), 2);
  EXPECT_EQ(predict_level(1.2, 1.0 / 1.1, log_sf, 4), 1);
  EXPECT_EQ(predict_level(1.2, 1e-3, log_sf, 4), 3);  // clamped to the top level
  EXPECT_EQ(predict_level(1.2, 100.0, log_sf, 4), 0);
}

TEST(Matching, RulePerPurposeAndModeAndDefaults) {
  const MatchingParams p;
  EXPECT_EQ(p.rule(MatchPurpose::kMotion, true).max_distance, 64);
  EXPECT_EQ(p.rule(MatchPurpose::kMotion, true).ratio, 0.9);
  EXPECT_EQ(p.rule(MatchPurpose::kLocalMap, true).ratio, 0.9);
  EXPECT_EQ(p.rule(MatchPurpose::kInit, true).max_distance, 50);
  EXPECT_EQ(p.rule(MatchPurpose::kTriangulate, true).ratio, 0.8);
  EXPECT_EQ(p.rule(MatchPurpose::kFuse, true).ratio, 1.0);
  EXPECT_EQ(p.rule(MatchPurpose::kRelocalize, true).ratio, 0.75);
  for (int k = 0; k < kMatchPurposes; ++k) {
    const MatchRule& s = p.rule(MatchPurpose(k), false);
    EXPECT_EQ(s.max_distance, 250);
    EXPECT_EQ(s.ratio, MatchPurpose(k) == MatchPurpose::kFuse ? 1.0 : 0.6);  // paper: c < 0.6
  }
}

TEST(Matching, ConfigKeysSetAndValidateEachRule) {
  AppConfig cfg =
      load_config("", {"matching.orb_local_ratio=0.7", "matching.sift_reloc_max_distance=300"});
  EXPECT_EQ(cfg.slam.features.matching.rule(MatchPurpose::kLocalMap, true).ratio, 0.7);
  EXPECT_EQ(cfg.slam.features.matching.rule(MatchPurpose::kRelocalize, false).max_distance, 300);
  EXPECT_EQ(cfg.slam.features.matching.rule(MatchPurpose::kMotion, true).ratio, 0.9);  // untouched
  try {
    load_config("", {"matching.orb_init_max_distance=300"});
    FAIL() << "accepted a Hamming distance above 256";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "config: matching.orb_init_max_distance: value '300' is out of range; allowed [1, "
              "256]");
  }
  EXPECT_THROW(load_config("", {"matching.sift_fuse_ratio=1.5"}), ConfigError);
  EXPECT_THROW(load_config("", {"features.match_ratio=0.8"}), ConfigError);  // moved to matching
}

// EpipolarBins must return, for any line through the epipole, every feature within its band of
// the line (a superset), in the order the features were given, so that the mapper's best-of
// search finds what a scan of all features finds. Epipoles inside the image, outside it, far
// away (near-parallel lines) and at infinity; bands from 0 to 10 px.
TEST(EpipolarBins, EveryFeatureWithinItsBandIsACandidateInGivenOrder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0, 640), uy(0, 480), uband(0, 10), uang(0, 2 * M_PI);
  const std::vector<Eigen::Vector3d> epipoles = {{320, 240, 1},  {10, 470, 1},
                                                 {-200, 100, 1}, {900, -300, 1},
                                                 {5e4, 2e3, 1},  {320 * 0.5, 240 * 0.5, 0.5},
                                                 {-1e7, 3e6, 1}, {1, 0.3, 1e-14}};
  EpipolarBins bins;
  long checked = 0, candidates = 0, all_features = 0, brute = 0;
  for (const auto& e : epipoles) {
    for (int trial = 0; trial < 5; ++trial) {
      const int n = 40 + trial * 300;
      std::vector<int> idx(n);
      std::vector<double> x(n), y(n), band(n);
      for (int k = 0; k < n; ++k) {
        idx[k] = 3 * k + 1;  // any increasing ids
        x[k] = ux(rng);
        y[k] = uy(rng);
        band[k] = uband(rng);
      }
      bins.build(e, idx.data(), x.data(), y.data(), band.data(), n);
      const bool finite = std::abs(e.z()) > 1e-12 * e.norm();
      if (!finite) {
        EXPECT_EQ(bins.bins(), 0) << "epipole at infinity: bins off";
      }
      const Eigen::Vector2d ep =
          finite ? Eigen::Vector2d(e.head<2>() / e.z()) : Eigen::Vector2d(0, 0);
      for (int q = 0; q < 400; ++q) {
        // A line through the epipole: towards a random feature half the time (lines that hit
        // features), at a random angle otherwise.
        const double a =
            q % 2 ? uang(rng)
                  : std::atan2(y[q % n] - ep.y(), x[q % n] - ep.x()) + 1e-3 * (uband(rng) - 5);
        const Eigen::Vector2d d(std::cos(a), std::sin(a));
        Eigen::Vector3d l(-d.y(), d.x(), 0.0);
        l.z() = -(l.x() * ep.x() + l.y() * ep.y());
        l *= 0.37;  // lines come unnormalised from F^T x
        int nc = 0;
        const int* c = bins.candidates(l, &nc);
        std::vector<int> got(c, c + nc);
        EXPECT_TRUE(std::is_sorted(got.begin(), got.end()));
        EXPECT_TRUE(std::adjacent_find(got.begin(), got.end()) == got.end()) << "no duplicates";
        const double ln = std::hypot(l.x(), l.y());
        for (int k = 0; k < n; ++k) {
          const double dist = std::abs(l.x() * x[k] + l.y() * y[k] + l.z()) / ln;
          if (finite && dist > band[k]) continue;
          ++brute;
          ASSERT_TRUE(std::binary_search(got.begin(), got.end(), idx[k]))
              << "feature " << k << " at " << dist << " px of the line (band " << band[k]
              << ") missing; epipole " << e.transpose() << ", n " << n;
        }
        if (finite && n >= 640) {
          candidates += nc;
          all_features += n;
        }
        ++checked;
      }
    }
  }
  // The point of the bins: far fewer candidates than features (finite epipoles, n >= 640).
  std::printf("%ld lines, %ld features within their band; candidates %.1f%% of the features\n",
              checked, brute, 100.0 * candidates / all_features);
  EXPECT_LT(candidates, all_features / 5);
}

}  // namespace
}  // namespace rdslam
